"""Fast path for plain sqlite3 rosbag2 directories: read message blobs with one query per topic.

rosbags opens a sqlite3 bag by counting every topic's messages (a full join) and yields messages
one by one through Python; for the contract topics we only need ``(timestamp, data)`` per topic,
which ``sqlite3`` hands back from C in one ``fetchall``. Anything unusual (compression, another
storage, unreadable metadata) returns None and the caller falls back to rosbags.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Collection
from operator import itemgetter
from pathlib import Path

import numpy as np

from bridge_shadow.bagio.cdr import RawBlock
from bridge_shadow.bagio.metadata import METADATA_ERRORS, plain_bag_files

__all__ = ["plain_sqlite_files", "read_sqlite_topics"]


def plain_sqlite_files(path: Path) -> list[Path] | None:
    """Return the ``.db3`` files of an uncompressed sqlite3 bag directory, or None for anything else."""
    if not path.is_dir():
        return None
    found = plain_bag_files(path, "sqlite3")
    if found is None:
        return None
    files, meta = found
    try:
        formats = {t["topic_metadata"].get("serialization_format") for t in meta["topics_with_message_count"]}
    except METADATA_ERRORS:
        return None
    return files if formats <= {"cdr"} else None


def read_sqlite_topics(
    files: list[Path], topics: Collection[str]
) -> tuple[dict[str, RawBlock], dict[str, str]]:
    """Read the messages of the given topics, in log-time order.

    Returns:
        ``{topic: RawBlock}`` for each topic present, and ``{topic: type}`` of every topic in the
        files.

    Raises:
        sqlite3.Error: unreadable or corrupt database (the caller turns it into a ``BagError``).

    """
    stamps: dict[str, list[int]] = {}
    raws: dict[str, list[bytes]] = {}
    types: dict[str, str] = {}
    for file in files:
        db = sqlite3.connect(f"file:{file}?immutable=1", uri=True)
        try:
            rows = db.execute("SELECT id, name, type FROM topics").fetchall()
            types.update({name: msgtype for _, name, msgtype in rows})
            for topic_id, name, _ in rows:
                if name not in topics:
                    continue
                found = db.execute(
                    "SELECT timestamp, data FROM messages WHERE topic_id = ?", (topic_id,)
                ).fetchall()
                stamps.setdefault(name, [])
                raws.setdefault(name, [])
                stamps[name].extend(map(itemgetter(0), found))
                raws[name].extend(map(itemgetter(1), found))
        finally:
            db.close()
    out: dict[str, RawBlock] = {}
    for name, t in stamps.items():
        log_ns = np.asarray(t, dtype=np.int64)
        data = raws[name]
        if len(log_ns) > 1 and np.any(np.diff(log_ns) < 0):  # rowid order is write order: sort if needed
            order = np.argsort(log_ns, kind="stable")
            log_ns = log_ns[order]
            data = list(itemgetter(*order.tolist())(data))
        out[name] = RawBlock.from_raws(log_ns, data)
    return out, types
