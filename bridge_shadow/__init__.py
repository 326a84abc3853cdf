"""Digital shadow of the UniBw Munich two-span steel-concrete composite test bridge.

The functional core (``fe``, ``model``, ``estimate``, ``twin``, ``gap``, ``bagio``, ``importers``)
imports no ROS code; ``ros`` is the only package that touches rclpy.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
