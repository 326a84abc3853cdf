"""Online estimation: gate, windows, event detector, joint compensation, noise model, settlement, Shadow.

No ROS import here: the rclpy node (``bridge_shadow.ros``) and offline replay drive the same
``Shadow`` object (``shadow``), which composes the subpackages: ``inputs`` (gate, ledger, window
buffer), ``events`` (change detector), ``compensation`` (temperature curve, noise model),
``settlement`` (segment posterior, prior, the paper's Kalman filter and batch method), ``state``
(plain-data state, checkpoints) and ``parameters`` (``config/shadow.yaml`` and its specs).
Outside them: ``result`` and ``report`` (what the shadow reports), ``plots``, ``startup`` (a shadow
fresh or resumed from its checkpoint) and ``small`` (2x2 algebra).
"""

from bridge_shadow.estimate.inputs.gate import REASONS
from bridge_shadow.estimate.parameters.config import ShadowConfig, load_config
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
