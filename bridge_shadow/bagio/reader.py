"""Read rosbag2 bags (sqlite3 or MCAP) into ``MonitoringData``; raw iteration and summaries.

``read_monitoring`` gets each topic's CDR blobs as one buffer (``RawBlock``): plain sqlite3 bags
through one SQL query per topic (``sqlite_direct``), MCAP bags through their message indexes
(``mcap_direct``), anything else through rosbags. It then decodes each buffer vectorized
(``cdr.decode_buffer``). Every storage failure becomes a one-line ``BagError`` naming the bag.
"""

from __future__ import annotations

import sqlite3
import struct
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager
from datetime import datetime, timezone
from operator import attrgetter, itemgetter
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import N_FLOATS, CdrFormatError, RawBlock, decode_buffer
from bridge_shadow.bagio.errors import (
    BagError,
    BagNotFoundError,
    CorruptBagError,
    MissingTopicError,
    NotABagError,
    UnexpectedTypeError,
)
from bridge_shadow.bagio.mcap_direct import read_mcap_topics
from bridge_shadow.bagio.mcap_format import McapLayoutError, mcap_files
from bridge_shadow.bagio.sqlite_direct import plain_sqlite_files, read_sqlite_topics
from bridge_shadow.contract import (
    CHANNELS,
    FORCE_TOPICS,
    FORCE_TYPE,
    INPUT_TOPICS,
    RECORD_FILE_SUFFIXES,
    TEMPERATURE_TOPIC,
    TEMPERATURE_TYPE,
)
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = ["bag_summary", "iter_raw", "open_bag", "read_blocks", "read_monitoring", "read_raw_topics"]

#: Storage failures that mean a damaged file (apsw errors are added at import time below).
_STORAGE_ERRORS: tuple[type[BaseException], ...] = (
    OSError,
    EOFError,
    ValueError,
    KeyError,
    IndexError,
    TypeError,
    AttributeError,
    AssertionError,
    struct.error,
    sqlite3.Error,
)
try:  # the sqlite3 back end of rosbags
    import apsw

    _STORAGE_ERRORS = (*_STORAGE_ERRORS, apsw.Error)
except ImportError:  # pragma: no cover
    pass
try:  # a damaged zstd chunk of an MCAP file (rosbags decompresses with it too)
    from backports.zstd import ZstdError

    _STORAGE_ERRORS = (*_STORAGE_ERRORS, ZstdError)
except ImportError:  # pragma: no cover
    pass


def _reader_error() -> type[BaseException]:
    from rosbags.rosbag2 import ReaderError

    return ReaderError


@contextmanager
def _translated(path: Path, doing: str) -> Iterator[None]:
    """Turn any storage failure inside the block into a one-line ``BagError`` naming the bag."""
    reader_error = _reader_error()
    try:
        yield
    except BagError:
        raise
    except PermissionError as err:
        raise BagError(f"{path}: permission denied ({err.filename or path})") from err
    except FileNotFoundError as err:
        if not path.exists():
            raise BagNotFoundError(f"{path}: no such bag") from err
        raise NotABagError(f"{path}: not a rosbag2 bag (no metadata.yaml, .db3 or .mcap)") from err
    except reader_error as err:
        text = str(err).splitlines()[0] if str(err) else type(err).__name__
        if "Unrecognized storage format" in text:
            raise NotABagError(f"{path}: not a rosbag2 bag ({text})") from err
        if text.startswith(("Invalid bag metadata", "A metadata key is missing")):
            # rosbags' own words carry Python's ("string indices must be integers"): say what it is
            raise CorruptBagError(
                f"{path}: metadata.yaml is not rosbag2 metadata (a mapping under rosbag2_bagfile_information "
                f"with the bag's files, topics and counts); rosbags: {text}"
            ) from err
        raise CorruptBagError(f"{path}: corrupt or truncated bag while {doing}: {text}") from err
    except _STORAGE_ERRORS as err:
        text = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise CorruptBagError(f"{path}: corrupt or truncated bag while {doing}: {text}") from err


def not_a_bag(path: Path, why: str) -> NotABagError:
    """Return the error for a path that is no bag (for CSV records, with the command that converts them)."""
    csv = path.is_file() and path.suffix.lower() in RECORD_FILE_SUFFIXES
    given = "FILE..."
    if path.is_dir():
        try:
            csv = any(p.suffix.lower() in RECORD_FILE_SUFFIXES for p in path.iterdir() if p.is_file())
        except OSError:  # an unreadable folder: no hint
            csv = False
        given = str(path)  # import-csv reads a folder's records as they are
    hint = f"; CSV records: make a bag of them with `bridge-shadow import-csv {given} --out BAG`"
    hint = hint if csv else ""
    return NotABagError(f"{path}: not a rosbag2 bag ({why}){hint}")


@contextmanager
def open_bag(path: str | Path) -> Iterator[Any]:
    """Open a bag directory (or a bare ``.db3``/``.mcap`` file) with rosbags, errors typed.

    Yields:
        an open ``rosbags.rosbag2.Reader``.

    Raises:
        BagNotFoundError, NotABagError, CorruptBagError.

    """
    from rosbags.rosbag2 import Reader

    path = Path(path)
    if not path.exists():
        raise BagNotFoundError(f"{path}: no such bag")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        raise not_a_bag(path, "directory without metadata.yaml")
    if path.is_file() and path.suffix not in (".db3", ".mcap"):
        raise not_a_bag(path, "expected a directory, .db3 or .mcap")
    with _translated(path, "opening"):
        reader = Reader(path)
        reader.open()
    try:
        yield reader
    finally:
        with _translated(path, "closing"):
            reader.close()


def _storage_name(reader: Any) -> str:
    storage = reader.storage
    inner = getattr(storage, "storages", None) or [storage]
    name = type(inner[0]).__name__.lower()
    return "mcap" if "mcap" in name else "sqlite3" if "sqlite" in name else name


def _iso(ns: int) -> str:
    stamp = datetime.fromtimestamp(ns // 1_000_000_000, tz=timezone.utc)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns % 1_000_000_000:09d}Z"


def bag_summary(path: str | Path) -> dict[str, Any]:
    """Describe a bag: storage, topics with type and count, time span.

    Returns:
        ``{"path", "storage", "message_count", "topics": {topic: {"type", "count"}},
        "start_ns", "end_ns", "duration_s", "start_iso", "end_iso"}`` (times from the log
        time, ``None`` for an empty bag).

    """
    path = Path(path)
    with open_bag(path) as reader, _translated(path, "reading metadata"):
        topics = {
            name: {"type": info.msgtype, "count": int(info.msgcount)} for name, info in reader.topics.items()
        }
        count = int(reader.message_count)
        start = int(reader.start_time) if count else None
        end = int(reader.end_time) - 1 if count else None
        storage = _storage_name(reader)
        compression = reader.compression_mode or None
    return {
        "path": str(path),
        "storage": storage,
        "compression": compression,
        "message_count": count,
        "topics": topics,
        "start_ns": start,
        "end_ns": end,
        "duration_s": (end - start) / 1e9 if count else 0.0,
        "start_iso": _iso(start) if start is not None else None,
        "end_iso": _iso(end) if end is not None else None,
    }


def iter_raw(
    path: str | Path, topics: Collection[str] | None = None
) -> Iterator[tuple[str, str, int, bytes]]:
    """Yield ``(topic, msgtype, log_ns, raw_cdr)`` in log-time order (all topics when None).

    Topics in ``topics`` that the bag lacks are ignored here; check with ``bag_summary``.
    """
    path = Path(path)
    with open_bag(path) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        if not conns:
            return
        messages = reader.messages(connections=conns)
        while True:
            with _translated(path, "reading messages"):
                item = next(messages, None)
            if item is None:
                return
            conn, log_ns, raw = item
            yield conn.topic, conn.msgtype, log_ns, raw


def _read_generic(reader: Any, conns: list[Any]) -> dict[str, RawBlock]:
    """Read the messages of the given connections through rosbags' iterator (any storage)."""
    out: dict[str, RawBlock] = {c.topic: RawBlock.from_raws([], []) for c in conns}
    items = list(reader.messages(connections=conns))
    if not items:
        return out
    cs, ts, rs = zip(*items, strict=True)
    topic_of = np.array(list(map(attrgetter("topic"), cs)), dtype=object)
    for topic in out:
        idx = np.flatnonzero(topic_of == topic).tolist()
        if idx:
            pick = itemgetter(*idx) if len(idx) > 1 else (lambda seq, i=idx[0]: (seq[i],))
            out[topic] = RawBlock.from_raws(list(pick(ts)), list(pick(rs)))
    return out


def _check_types(path: Path, found: dict[str, str], topics: dict[str, str]) -> None:
    for topic, msgtype in found.items():
        if topic in topics and msgtype != topics[topic]:
            raise UnexpectedTypeError(f"{path}: topic {topic} has type {msgtype}, expected {topics[topic]}")


def read_blocks(path: str | Path, topics: dict[str, str]) -> dict[str, RawBlock]:
    """Read the messages of the given ``{topic: expected_type}`` as one buffer per topic.

    Plain sqlite3 bags are read with one SQL query per topic (``sqlite_direct``), MCAP bags
    through their message indexes (``mcap_direct``); anything else, or an MCAP file that the
    fast path does not handle, through rosbags.

    Returns:
        ``{topic: RawBlock}`` for each topic the bag holds, messages in log-time order.

    Raises:
        UnexpectedTypeError: a topic is present with another message type; other ``BagError``s.

    """
    path = Path(path)
    if path.exists():
        if (files := plain_sqlite_files(path)) is not None:
            with _translated(path, "reading messages"):
                out, found = read_sqlite_topics(files, set(topics))
            _check_types(path, found, topics)
            return out
        if (files := mcap_files(path)) is not None:
            try:
                out, found = read_mcap_topics(files, set(topics))
            except McapLayoutError:
                pass  # rosbags decides: a damaged file becomes a CorruptBagError below
            else:
                _check_types(path, found, topics)
                return out
    with open_bag(path) as reader:
        conns = [c for c in reader.connections if c.topic in topics]
        _check_types(path, {c.topic: c.msgtype for c in conns}, topics)
        with _translated(path, "reading messages"):
            return _read_generic(reader, conns)


def read_raw_topics(path: str | Path, topics: dict[str, str]) -> dict[str, tuple[np.ndarray, list[bytes]]]:
    """Like ``read_blocks``, as ``{topic: (log_ns (n,) int64, [raw bytes, ...])}``."""
    return {t: (b.log_ns, b.raws()) for t, b in read_blocks(path, topics).items()}


def _required_topics(required: bool | Collection[str]) -> set[str]:
    if required is True:
        return set(INPUT_TOPICS)
    if required is False:
        return set()
    unknown = set(required) - set(INPUT_TOPICS)
    if unknown:
        raise ValueError(f"not contract input topics: {sorted(unknown)}")
    return set(required)


def read_monitoring(
    path: str | Path,
    *,
    required: bool | Collection[str] = True,
    topics: Sequence[str] | None = None,
) -> MonitoringData:
    """Read the three contract input topics, decoding their CDR vectorized.

    Args:
        path: bag directory (sqlite3 or MCAP) or a bare ``.db3``/``.mcap`` file.
        required: True (all three topics must be present), False (none), or the contract topic
            names that must be present. An absent optional topic gives an empty series.
        topics: the names the bag uses for frc_01, frc_02 and the air temperature (default: the
            contract's); the message types stay the contract's.

    Returns:
        ``MonitoringData`` with stamps from ``header.stamp``, ``log_ns`` from the bag's log time
        and ``frame_id`` per message; messages in log-time order per topic.

    Raises:
        BagNotFoundError, NotABagError, MissingTopicError, UnexpectedTypeError, CorruptBagError.

    """
    path = Path(path)
    names = dict(zip(INPUT_TOPICS, INPUT_TOPICS if topics is None else topics, strict=True))
    must = {names[t] for t in _required_topics(required)}
    raw = read_blocks(path, {names[t]: msgtype for t, msgtype in INPUT_TOPICS.items()})
    missing = sorted(must - set(raw))
    if missing:
        has = ", ".join(sorted(raw)) or "none of the input topics"
        raise MissingTopicError(f"{path}: missing topic(s) {', '.join(missing)} (bag has {has})")

    def decode(topic: str, msgtype: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        block = raw.get(topic) or RawBlock.from_raws([], [])
        try:
            stamp_ns, frames, values = decode_buffer(
                block.buf, block.starts, block.lengths, N_FLOATS[msgtype]
            )
        except CdrFormatError as err:
            raise CorruptBagError(f"{path}: topic {topic} does not decode as {msgtype}: {err}") from err
        return stamp_ns, frames, values, block.log_ns

    forces = {}
    for ch in CHANNELS:
        stamp_ns, frames, values, log_ns = decode(names[FORCE_TOPICS[ch]], FORCE_TYPE)
        forces[ch] = ForceSeries(stamp_ns, values[:, 2], frames, log_ns)
    stamp_ns, frames, values, log_ns = decode(names[TEMPERATURE_TOPIC], TEMPERATURE_TYPE)
    temperature = TemperatureSeries(stamp_ns, values[:, 0], values[:, 1], frames, log_ns)
    return MonitoringData(forces, temperature)
