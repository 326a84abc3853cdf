"""Bags a checkpoint chain has taken, known again when one is replayed after its own run's checkpoint.

A replay with ``--checkpoint`` records every bag it took whole (``bag_signature``) in the
checkpoint it writes once the run is complete (``Shadow.taken_bags``; an interrupted run records
nothing). Replayed again from that checkpoint (the same command run twice, a script's retry),
every message of such a bag lies at or before the checkpoint's data: each was rejected
(``clock_jump``, ``out_of_order``), the run exited 1 as after a bag of older data, and the checkpoint
was written again with the rejects counted. Known by its signature, the rerun says so, changes
nothing and prints the checkpoint's answer.

The signature is the bag's metadata (every topic with its type and message count, the log
times of its first and last message) and its storage files as they are on disk (name, size,
modification and change time, inode: ``bagio.identity.stat_signature``; a bag named by its
directory or by its one bare ``.db3`` / ``.mcap`` file is the same bag). Reading it reads no message. The
metadata alone is not enough: the bags of a load-test day's records, each imported with the day's
air temperature, have the same topics, counts and span (the air's). A copy of a bag, or one
written again, is not known: replayed after the checkpoint, it is refused as data older than the
checkpoint's is (every message rejected, exit 1, the checkpoint left as it was: ``replay_bag``).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from bridge_shadow.contract import CHANNELS
from bridge_shadow.replay.air_tail import new_air

__all__ = ["TAKEN_LIMIT", "bag_signature", "find_taken", "forces_used", "older_data", "recorded"]

#: Most bags a checkpoint remembers (the latest kept): over a year of hourly bags. An older bag
#: replayed again is refused as older data is, with every message rejected and exit 1.
TAKEN_LIMIT = 10_000


def bag_signature(path: str | Path) -> dict[str, Any]:
    """Return the bag's signature entry: ``bag``, ``signature`` (hex), ``messages``, ``start``, ``end``.

    Raises:
        BagError: the bag cannot be opened or its metadata read.

    """
    from bridge_shadow.bagio.identity import bag_files, stat_signature
    from bridge_shadow.bagio.reader import bag_summary

    s = bag_summary(path)
    topics = {name: [t["type"], t["count"]] for name, t in sorted(s["topics"].items())}
    # the storage files alone: a bag named as its directory or as its one bare .db3 / .mcap file is
    # one bag (its metadata.yaml is of the directory only; what it says is in the summary above)
    files = stat_signature([p for p in bag_files(Path(path)) if p.name != "metadata.yaml"])
    text = json.dumps(
        {"topics": topics, "start_ns": s["start_ns"], "end_ns": s["end_ns"], "files": files}, sort_keys=True
    )
    return {
        "bag": str(path),
        "signature": hashlib.blake2b(text.encode(), digest_size=16).hexdigest(),
        "messages": s["message_count"],
        "start": s["start_iso"],
        "end": s["end_iso"],
    }


def recorded(taken: Sequence[dict[str, Any]], new: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Return ``taken`` with the ``new`` entries (``taken_at`` now, UTC) last, at most ``TAKEN_LIMIT``.

    An entry of the same signature taken before is replaced (the latest run that took it is named);
    a bag named twice in ``new`` (``replay a a``) is one entry.
    """
    now = datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    fresh = list({e["signature"]: {**e, "taken_at": now} for e in new}.values())
    again = {e["signature"] for e in fresh}
    kept = [e for e in taken if e.get("signature") not in again]
    return [*kept, *fresh][-TAKEN_LIMIT:]


def find_taken(
    taken: Sequence[dict[str, Any]], bags: Sequence[dict[str, Any]]
) -> list[dict[str, Any]] | None:
    """Return the recorded entry of each of ``bags`` (signature entries); None unless all were taken."""
    by_signature = {e.get("signature"): e for e in taken}
    found = [by_signature.get(b["signature"]) for b in bags]
    if not bags or any(e is None for e in found):
        return None
    return [e for e in found if e is not None]


def forces_used(used: Mapping[str, int]) -> int:
    """Load-cell messages among a shadow's ``used`` counts (per topic: frc_01, frc_02, the air)."""
    return sum(int(used.get(ch, 0)) for ch in CHANNELS)


def older_data(
    forces_fed: int,
    used: tuple[int, int],
    clock_ns: tuple[int | None, int | None],
    tail: Any,
    held: Any,
) -> bool:
    """Whether a chain's run took nothing of its bag: data older than the checkpoint's.

    Its checkpoint is then left as it was and the bag is not taken (``replay_bag``, and the live
    chain's ``LiveChain.finish``). ``forces_fed``: the bag's load-cell messages; ``used``: the
    load-cell messages used before and after the run (``forces_used``); ``clock_ns``: the data
    clock before and after; ``tail``: the bag's air past its last force; ``held``: the air the
    checkpoint held. Older means load-cell messages fed and none used, the clock where it was (a
    newer bag whose load cells all failed moves it with its air), and no air in the tail that the
    checkpoint lacks (a bag run again after a run stopped past a periodic write that took all its
    forces has its tail: ``air_tail.new_air``).
    """
    return (
        bool(forces_fed)
        and used[0] == used[1]
        and clock_ns[0] == clock_ns[1]
        and not new_air(tail, held, clock_ns[0])
    )
