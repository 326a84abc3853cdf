"""Declarations of the node's parameters: one ParameterDescriptor per ``config/shadow.yaml`` entry.

The parameters are every entry of ``config/shadow.yaml`` (its values are the declared defaults), overridable
with ``--ros-args -p name:=value`` or ``--params-file FILE``. Each is declared with a
ParameterDescriptor built from ``estimate.parameters.specs`` (type, description with unit, constraint,
range), and checked as strictly as ``replay --params`` checks it: an unknown name, a wrong type or
an out-of-range value stops the node at start with one line and exit code 2. Only
``diagnostics_period_s`` may change at run time (the set-parameters callback refuses a bad value
with the reason); every other parameter is read-only once the node runs. ``qos_depth`` is the input history
depth (RELIABLE, KEEP_LAST; 0 means KEEP_ALL). Note that a full reliable reader drops samples for
the writer to resend at its next heartbeat (seconds later, in Fast DDS), so a fast replay keeps
fewer than ``qos_depth`` messages in flight using the status service instead.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.node import Node

from bridge_shadow.estimate import ShadowConfig, load_config
from bridge_shadow.estimate.parameters.specs import SPECS, constraint_text, describe, kind_of

__all__ = ["declare_parameters", "is_ros_own", "parameter_descriptor", "plain_value"]


#: Parameters rclpy itself reads (not the shadow's, and not unknown either).
_ROS_OWN = ("use_sim_time", "start_type_description_service", "qos_overrides.")
#: ROS parameter type of each value kind of ``estimate.parameters.specs``.
_ROS_TYPES = {
    "bool": ParameterType.PARAMETER_BOOL,
    "int": ParameterType.PARAMETER_INTEGER,
    "float": ParameterType.PARAMETER_DOUBLE,
    "str": ParameterType.PARAMETER_STRING,
    "float_pair": ParameterType.PARAMETER_DOUBLE_ARRAY,
}


def is_ros_own(name: str) -> bool:
    """Tell whether ``name`` is a parameter rclpy itself reads (``use_sim_time``, ``qos_overrides.*``)."""
    return any(name == own or (own.endswith(".") and name.startswith(own)) for own in _ROS_OWN)


def plain_value(value: Any) -> Any:
    """Return a ROS parameter value as plain Python (arrays as lists)."""
    if value is None or isinstance(value, (str, bool, int, float)):
        return value
    return list(value)


def parameter_descriptor(name: str, kind: str) -> ParameterDescriptor:
    """Build the ParameterDescriptor of a shadow parameter from ``estimate.parameters.specs`` (one table).

    Type, description (the comment of config/shadow.yaml, unit, constraint, role), the constraint
    in words, and the range where both ends are finite. Parameters that cannot change while the
    node runs are read-only; the live ones take an integer for a real (dynamic typing) and carry
    no range: the set-parameters callback checks the value and says why it refuses one (rclpy's
    own range check would answer first, without the reason).
    """
    spec = SPECS.get(name)
    live = spec is not None and spec.live
    descriptor = ParameterDescriptor(
        name=name,
        type=_ROS_TYPES[kind],
        description=describe(name, kind),
        additional_constraints=constraint_text(name, kind),
        read_only=not live,
        dynamic_typing=live,
    )
    if spec is not None and not live and spec.low is not None and spec.high is not None:
        if kind == "float":
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(spec.low), to_value=float(spec.high), step=0.0)
            ]
        elif kind == "int":
            descriptor.integer_range = [
                IntegerRange(from_value=int(spec.low), to_value=int(spec.high), step=1)
            ]
    return descriptor


def declare_parameters(node: Node) -> ShadowConfig:
    """Check the start-up parameters, declare each with its descriptor, and return them read back.

    Defaults are config/shadow.yaml. The overrides (``--params-file``, ``-p``) are checked by the
    same strict rules as ``replay --params`` (``estimate.parameters.specs``): an unknown name, a wrong
    type or an out-of-range value raises ConfigError, one line.
    """
    overrides = {
        name: plain_value(p.value)
        for name, p in getattr(node, "_parameter_overrides", {}).items()
        if not is_ros_own(name)
    }
    config = ShadowConfig.from_params({**load_config().to_params(), **overrides})
    for f in dataclasses.fields(ShadowConfig):
        value = getattr(config, f.name)
        descriptor = parameter_descriptor(f.name, kind_of(f))
        node.declare_parameter(f.name, value, descriptor, ignore_override=True)
    return config
