"""Contract messages <-> numpy: the node's only knowledge of message layouts.

Inputs arrive as raw CDR bytes (``raw=True`` subscriptions: no Python message object per sample)
and are decoded in blocks by ``bridge_shadow.bagio.decode_stamped_floats``, the same vectorized
codec the offline replay uses. Outputs are built as typed rclpy messages (``*_msg``: bags, tests)
or serialized directly (``*_raw``: what the node publishes, below). Units are SI: forces in N,
settlements in m, covariances in m^2, stamps in integer ns.

The node publishes its outputs serialized (``*_raw``: ``Publisher.publish`` takes CDR bytes):
each is a template serialized once by rclpy with the varying fields packed in place: what rclpy
reads back is the typed message, field for field, at the length of rclpy's own serialization
(``test_ros_messages.py``; only CDR's alignment padding, which rclpy leaves unset, may differ),
without building a Python message per window (about a quarter of a millisecond off every
posterior's way out).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from functools import cache

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import WrenchStamped
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from bridge_shadow.bagio.cdr import decode_stamped_floats_kept
from bridge_shadow.contract import COVARIANCE_LAYOUT_LABELS, MEAN_LAYOUT_LABEL

__all__ = [
    "Decoded",
    "array_from_msg",
    "covariance_msg",
    "covariance_raw",
    "decode_forces",
    "decode_temperatures",
    "mean_msg",
    "mean_raw",
    "stamp_msg",
    "wrench_msg",
    "wrench_raw",
]

_NS = 1_000_000_000
#: ``Decoded``: stamp_ns (n,) int64, value (n,) float64, frame_id (n,) object, malformed count.
Decoded = tuple[np.ndarray, np.ndarray, np.ndarray, int]


def _decode(raws: Sequence[bytes], n_floats: int, column: int) -> Decoded:
    """Decode a block; on a malformed message decode one by one and drop (count) the bad ones."""
    stamp, frame, values, kept = decode_stamped_floats_kept(raws, n_floats)
    return stamp, values[:, column], frame, len(raws) - len(kept)


def decode_forces(raws: Sequence[bytes]) -> Decoded:
    """Decode raw ``WrenchStamped`` CDR: header stamp (ns), ``wrench.force.z`` (N), frame_id."""
    return _decode(raws, 6, 2)


def decode_temperatures(raws: Sequence[bytes]) -> Decoded:
    """Decode raw ``sensor_msgs/Temperature`` CDR: header stamp (ns), temperature (C), frame_id."""
    return _decode(raws, 2, 0)


def stamp_msg(stamp_ns: int) -> Time:
    """``builtin_interfaces/Time`` from integer ns since the epoch."""
    sec, nanosec = divmod(int(stamp_ns), _NS)
    return Time(sec=sec, nanosec=nanosec)


def _array_msg(values: np.ndarray, labels: Sequence[str]) -> Float64MultiArray:
    """Row-major ``Float64MultiArray`` with one layout dim per label (size, stride per REP/std_msgs)."""
    values = np.asarray(values, dtype=float)
    if values.ndim != len(labels):
        raise ValueError(f"array of shape {values.shape} needs {values.ndim} labels, got {list(labels)}")
    msg = Float64MultiArray()
    strides = np.cumprod(values.shape[::-1])[::-1]
    msg.layout.dim = [
        MultiArrayDimension(label=label, size=int(size), stride=int(stride))
        for label, size, stride in zip(labels, values.shape, strides, strict=True)
    ]
    msg.layout.data_offset = 0
    msg.data = values.ravel().tolist()
    return msg


def mean_msg(mean_m: np.ndarray) -> Float64MultiArray:
    """Posterior mean ``[south, north]`` in m; layout dim label ``support``."""
    return _array_msg(np.asarray(mean_m, float).reshape(2), [MEAN_LAYOUT_LABEL])


def covariance_msg(covariance_m2: np.ndarray) -> Float64MultiArray:
    """Posterior covariance, 2x2 row-major in m^2; layout dims ``row``, ``col``."""
    return _array_msg(np.asarray(covariance_m2, float).reshape(2, 2), COVARIANCE_LAYOUT_LABELS)


def array_from_msg(msg: Float64MultiArray) -> tuple[np.ndarray, tuple[str, ...]]:
    """Inverse of ``mean_msg``/``covariance_msg``: the array shaped by its layout, and its labels."""
    dims = list(msg.layout.dim)
    shape = tuple(int(d.size) for d in dims)
    data = np.asarray(msg.data, dtype=float)[int(msg.layout.data_offset) :]
    return data[: int(np.prod(shape))].reshape(shape), tuple(d.label for d in dims)


def wrench_msg(stamp_ns: int, frame_id: str, force_n: float) -> WrenchStamped:
    """``WrenchStamped`` with the force (N) in ``wrench.force.z``, as the input contract."""
    msg = WrenchStamped()
    msg.header.stamp = stamp_msg(stamp_ns)
    msg.header.frame_id = frame_id
    msg.wrench.force.z = float(force_n)
    return msg


# -- serialized outputs ---------------------------------------------------------------------------
_STAMP = struct.Struct("<iI")  # builtin_interfaces/Time right after the 4-byte CDR encapsulation
_FLOAT = struct.Struct("<d")


@cache
def _array_prefix(shape: tuple[int, ...], labels: tuple[str, ...]) -> bytes:
    """CDR of a ``Float64MultiArray`` of ``shape`` up to its data (the data are its last bytes)."""
    raw = serialize_message(_array_msg(np.zeros(shape), labels))
    return bytes(raw[: len(raw) - 8 * int(np.prod(shape))])


def mean_raw(mean_m: np.ndarray) -> bytes:
    """``mean_msg`` serialized."""
    x = np.asarray(mean_m, dtype="<f8").reshape(2)
    return _array_prefix(x.shape, (MEAN_LAYOUT_LABEL,)) + x.tobytes()


def covariance_raw(covariance_m2: np.ndarray) -> bytes:
    """``covariance_msg`` serialized."""
    x = np.asarray(covariance_m2, dtype="<f8").reshape(2, 2)
    return _array_prefix(x.shape, tuple(COVARIANCE_LAYOUT_LABELS)) + x.tobytes()


@cache
def _wrench_template(frame_id: str) -> bytes:
    return bytes(serialize_message(wrench_msg(0, frame_id, 0.0)))


def wrench_raw(stamp_ns: int, frame_id: str, force_n: float) -> bytes:
    """``wrench_msg`` serialized."""
    raw = bytearray(_wrench_template(frame_id))
    sec, nanosec = divmod(int(stamp_ns), _NS)
    _STAMP.pack_into(raw, 4, sec, nanosec)
    _FLOAT.pack_into(raw, len(raw) - 32, float(force_n))  # force.z: then torque x, y, z
    return bytes(raw)
