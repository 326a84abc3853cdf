"""The ROS 2 shell: the only package in bridge_shadow that imports rclpy."""
