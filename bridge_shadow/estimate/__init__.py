"""Online estimation: gate, align/aggregate, P-spline compensation, noise model, Kalman, Shadow.

No ROS import here: the rclpy node (``bridge_shadow.ros``) and offline replay drive the same
``Shadow`` object.
"""

from bridge_shadow.estimate.config import ShadowConfig, load_config
from bridge_shadow.estimate.gate import REASONS
from bridge_shadow.estimate.shadow import TOPIC_KEYS, ReplayResult, Shadow, WindowOutput

__all__ = ["REASONS", "TOPIC_KEYS", "ReplayResult", "Shadow", "ShadowConfig", "WindowOutput", "load_config"]
