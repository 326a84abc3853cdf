"""Vectorized CDR codec for the fixed-layout contract messages (no ROS import).

``geometry_msgs/msg/WrenchStamped`` and ``sensor_msgs/msg/Temperature`` share one layout in
ROS 2 CDR (XCDR1, as rosbag2 stores it)::

    offset  0  encapsulation  4 bytes: 0x00, 0x01 (little endian) or 0x00 (big), options 0x0000
    offset  4  header.stamp.sec       int32
    offset  8  header.stamp.nanosec   uint32
    offset 12  frame_id length        uint32, counts the bytes plus the terminating NUL
    offset 16  frame_id bytes + NUL
    offset f   k float64              f = 4 + align8(12 + length): alignment counts from offset 4

with k = 6 for WrenchStamped (force x y z, torque x y z) and k = 2 for Temperature (temperature,
variance). Messages of one total length share one offset table, so a bag decodes as a few numpy
blocks, one per (length, frame_id length): no Python work per message beyond ``len``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "N_FLOATS",
    "CdrFormatError",
    "RawBlock",
    "decode_buffer",
    "decode_stamped_floats",
    "encode_stamped_floats",
]

#: Float64 payload fields after the header, by message type.
N_FLOATS: dict[str, int] = {
    "geometry_msgs/msg/WrenchStamped": 6,
    "sensor_msgs/msg/Temperature": 2,
}

_HEADER_BYTES = 16  # encapsulation + sec + nanosec + string length
_NS = 1_000_000_000


class CdrFormatError(ValueError):
    """A raw message does not have the fixed layout it claims (reported per topic by the reader)."""


@dataclass
class RawBlock:
    """Messages of one topic lying in one buffer.

    Attributes:
        log_ns: (n,) int64 log times, ascending.
        buf: (N,) uint8 buffer.
        starts: (n,) int64 offset of each CDR message in ``buf``.
        lengths: (n,) int64 size of each CDR message.

    """

    log_ns: np.ndarray
    buf: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray

    def raws(self) -> list[bytes]:
        """Return the messages as separate ``bytes`` (slow path for callers that need them)."""
        data = self.buf.tobytes()
        return [data[s : s + n] for s, n in zip(self.starts.tolist(), self.lengths.tolist(), strict=True)]

    @staticmethod
    def from_raws(log_ns: Sequence[int] | np.ndarray, raws: Sequence[bytes]) -> RawBlock:
        """Pack separate messages into one buffer."""
        lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
        buf = np.frombuffer(b"".join(raws), dtype=np.uint8)
        return RawBlock(np.asarray(log_ns, dtype=np.int64), buf, np.cumsum(lengths) - lengths, lengths)


def _align8(n: np.ndarray) -> np.ndarray:
    return (n + 7) // 8 * 8


def _field(block: np.ndarray, start: int, dtype: str) -> np.ndarray:
    """Read one fixed-offset scalar column from a ``(n, L) uint8`` block."""
    width = np.dtype(dtype).itemsize
    return np.ascontiguousarray(block[:, start : start + width]).view(dtype).ravel()


def _decode_frames(chars: np.ndarray) -> np.ndarray:
    """Decode ``(n, w) uint8`` NUL-padded strings into an object array, one decode per distinct value."""
    n, width = chars.shape
    if width == 0:
        return np.full(n, "", dtype=object)
    if np.array_equal(chars, np.broadcast_to(chars[0], chars.shape)):  # one frame_id: the usual case
        return np.full(n, bytes(chars[0]).rstrip(b"\0").decode("utf-8", errors="replace"), dtype=object)
    fixed = np.ascontiguousarray(chars).view(f"S{width}").ravel()  # numpy strips trailing NULs
    uniq, inverse = np.unique(fixed, return_inverse=True)
    text = np.array([u.decode("utf-8", errors="replace") for u in uniq], dtype=object)
    return text[inverse.ravel()]


def decode_stamped_floats(raws: Sequence[bytes], n_floats: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decode header stamp, frame_id and trailing float64s of many CDR messages at once.

    Args:
        raws: n raw CDR messages (with the 4-byte encapsulation header), any mix of lengths.
        n_floats: number of float64 fields after the header (see ``N_FLOATS``).

    Returns:
        ``stamp_ns`` (n,) int64, ``frame_id`` (n,) object array of str, ``values`` (n, n_floats)
        float64.

    Raises:
        CdrFormatError: a message is too short, has an unknown encapsulation or an
            inconsistent string length.

    """
    lengths = np.fromiter(map(len, raws), dtype=np.int64, count=len(raws))
    starts = np.cumsum(lengths) - lengths
    buf = np.frombuffer(b"".join(raws), dtype=np.uint8)
    return decode_buffer(buf, starts, lengths, n_floats)


def _gather(buf: np.ndarray, starts: np.ndarray, length: int) -> np.ndarray:
    """Return the ``(m, length) uint8`` block of messages at ``starts`` (a view when they are packed)."""
    m = len(starts)
    if m and int(starts[-1]) - int(starts[0]) == (m - 1) * length and np.all(np.diff(starts) == length):
        return buf[int(starts[0]) : int(starts[0]) + m * length].reshape(m, length)
    block = np.empty((m, length), dtype=np.uint8)
    for j in range(length):  # one vectorized gather per byte column: no Python work per message
        block[:, j] = buf[starts + j]
    return block


def decode_buffer(
    buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray, n_floats: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decode n messages lying in one byte buffer at ``starts`` with ``lengths`` (see above).

    Args:
        buf: (N,) uint8 buffer holding the messages (e.g. joined blobs or MCAP chunk records).
        starts, lengths: (n,) int64 offset and size of each message in ``buf``.
        n_floats: number of float64 fields after the header.

    """
    n = len(starts)
    stamp_ns = np.empty(n, dtype=np.int64)
    frames = np.empty(n, dtype=object)
    values = np.empty((n, n_floats), dtype=np.float64)
    if n == 0:
        return stamp_ns, frames, values
    starts = np.asarray(starts, dtype=np.int64)
    lengths = np.asarray(lengths, dtype=np.int64)
    if int((starts + lengths).max()) > len(buf) or int(starts.min()) < 0:
        raise CdrFormatError("message extends beyond its buffer")
    same = lengths.min() == lengths.max()
    for length in [int(lengths[0])] if same else np.unique(lengths).tolist():
        rows = np.arange(n) if same else np.flatnonzero(lengths == length)
        if length < _HEADER_BYTES + 8 * n_floats:
            raise CdrFormatError(f"message {int(rows[0])} is {length} bytes, too short for the layout")
        block = _gather(buf, starts[rows], length)
        if np.any(block[:, 0] != 0) or np.any(block[:, 1] > 1):
            bad = int(rows[np.flatnonzero((block[:, 0] != 0) | (block[:, 1] > 1))[0]])
            raise CdrFormatError(f"message {bad} has an unknown CDR encapsulation")
        little = block[:, 1] == 1
        if np.all(little):
            _decode_block(block, rows, n_floats, "<", stamp_ns, frames, values)
            continue
        for mask, order in ((little, "<"), (~little, ">")):
            if np.any(mask):
                _decode_block(block[mask], rows[mask], n_floats, order, stamp_ns, frames, values)
    return stamp_ns, frames, values


def _decode_block(
    block: np.ndarray,
    rows: np.ndarray,
    n_floats: int,
    order: str,
    stamp_ns: np.ndarray,
    frames: np.ndarray,
    values: np.ndarray,
) -> None:
    """Decode a ``(m, L)`` block of one length and byte order into the output rows."""
    length = block.shape[1]
    slen = _field(block, 12, order + "u4").astype(np.int64)
    offset = 4 + _align8(12 + slen)  # first float64; trailing padding up to L is tolerated
    bad = (slen < 1) | (offset + 8 * n_floats > length)
    if np.any(bad):
        raise CdrFormatError(f"message {int(rows[np.flatnonzero(bad)[0]])} has an inconsistent string length")
    sec = _field(block, 4, order + "i4").astype(np.int64)
    nsec = _field(block, 8, order + "u4").astype(np.int64)
    stamp_ns[rows] = sec * _NS + nsec
    same = offset.min() == offset.max()
    for off in [int(offset[0])] if same else np.unique(offset).tolist():
        sub = slice(None) if same else np.flatnonzero(offset == off)
        part = block[sub]
        floats = np.ascontiguousarray(part[:, off : off + 8 * n_floats]).view(order + "f8")
        values[rows[sub]] = floats.reshape(len(part), n_floats)
        frames[rows[sub]] = _decode_frames(part[:, _HEADER_BYTES:off])


def encode_stamped_floats(
    stamp_ns: np.ndarray, frame_id: np.ndarray | Sequence[str] | str, values: np.ndarray
) -> list[bytes]:
    """Serialize messages of the fixed layout to little-endian CDR, one numpy block per frame_id.

    Args:
        stamp_ns: (n,) int64 header stamps, ns since epoch.
        frame_id: a str for all messages or (n,) str per message.
        values: (n, k) float64 fields after the header.

    Returns:
        n raw CDR messages, byte-identical to rosbags' ``serialize_cdr``.

    """
    stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
    values = np.asarray(values, dtype="<f8")
    n, n_floats = values.shape
    if len(stamp_ns) != n:
        raise ValueError("stamp_ns and values must have the same number of rows")
    frames = np.full(n, frame_id, dtype=object) if isinstance(frame_id, str) else np.asarray(frame_id, object)
    sec = stamp_ns // _NS
    if n and (sec.min() < np.iinfo(np.int32).min or sec.max() > np.iinfo(np.int32).max):
        raise ValueError("stamp out of the int32 seconds range of builtin_interfaces/Time")
    nsec = stamp_ns - sec * _NS
    out: list[bytes] = [b""] * n
    uniq, inverse = np.unique(frames.astype(str), return_inverse=True) if n else ([], np.empty(0, int))
    for k, frame in enumerate(uniq):
        rows = np.flatnonzero(inverse.ravel() == k)
        text = str(frame).encode("utf-8") + b"\0"
        offset = 4 + int(_align8(np.int64(12 + len(text))))
        length = offset + 8 * n_floats
        block = np.zeros((len(rows), length), dtype=np.uint8)
        block[:, 1] = 1
        block[:, 4:8] = sec[rows].astype("<i4").view(np.uint8).reshape(-1, 4)
        block[:, 8:12] = nsec[rows].astype("<u4").view(np.uint8).reshape(-1, 4)
        block[:, 12:16] = np.frombuffer(np.uint32(len(text)).astype("<u4").tobytes(), np.uint8)
        block[:, 16 : 16 + len(text)] = np.frombuffer(text, np.uint8)
        block[:, offset:] = values[rows].view(np.uint8).reshape(len(rows), 8 * n_floats)
        blob = block.tobytes()
        for j, row in enumerate(rows.tolist()):
            out[row] = blob[j * length : (j + 1) * length]
    return out
