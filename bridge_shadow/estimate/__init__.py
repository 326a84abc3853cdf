"""Online estimation: gate, windows, event detector, joint compensation, noise model, settlement, Shadow.

No ROS import here: the rclpy node (``bridge_shadow.ros``) and offline replay drive the same
``Shadow`` object.
"""

from bridge_shadow.estimate.config import ShadowConfig, load_config
from bridge_shadow.estimate.gate import REASONS
from bridge_shadow.estimate.result import EventRecord, ReplayResult, WindowOutput
from bridge_shadow.estimate.shadow import TOPIC_KEYS, Shadow

__all__ = [
    "REASONS",
    "TOPIC_KEYS",
    "EventRecord",
    "ReplayResult",
    "Shadow",
    "ShadowConfig",
    "WindowOutput",
    "load_config",
]
