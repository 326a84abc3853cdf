"""A live replay's checkpoint chain: the air past a bag's last force held, as the offline chain holds it.

A bag of one record often carries the whole day's air temperature (``import-csv`` of a record with
the day's temperature file). Played to a node with ``replay --live --checkpoint``, that air, hours
past the record's last force, moved the node's data clock on, and the next bag's forces, earlier
than the air's end, were all ``late``: a chain of live replays lost every later record (exit 1),
where the offline chain (``replay --checkpoint``, ``replay.air_tail``) gives what one replay of
all the bags merged by log time gives.

The player holds what the offline chain holds, on the raw pieces it publishes:

- ``prepare``: the node resumes from a private copy of the named checkpoint without its held air
  (a node ingests a checkpoint's held air first, before any live data: right for a node going
  live after an offline chain, too early for the next bag of a replay); the held air is
  published merged with the bag by log time, before the bag's messages of equal log time, as
  ``bagio.merged.MergedStream(held=...)`` reads it (``merge_held``);
- ``RawAirTail``: the air after the last force seen is held until forces follow (``AirTail``'s
  rule on raw pieces); what is held at the bag's end is the tail;
- after the last force the player asks the node's checkpoint service for the state then (the
  offline chain's checkpoint, taken before the tail is fed), plays the tail for this bag's own
  result, and flushes;
- ``finish``: once the run is complete, the named checkpoint becomes that state with the tail as
  its held air (written atomically). An interrupted run leaves it as it was: its rerun replays the
  bag whole from there.

No ROS import: the player (``live_replay``) publishes what these yield.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.bagio.cdr import decode_stamped_floats_kept, encode_stamped_floats
from bridge_shadow.contract import CHANNELS
from bridge_shadow.estimate.state.checkpoint import load_state, save_state
from bridge_shadow.estimate.state.persistence import held_air_arrays, held_air_series
from bridge_shadow.replay.air_tail import HELD_AIR_LIMIT
from bridge_shadow.replay.taken import forces_used, older_data, recorded
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = [
    "AIR",
    "LiveChain",
    "RawAirTail",
    "RawPiece",
    "decode_air",
    "encode_air",
    "encode_forces",
    "merge_held",
    "merge_log_order",
    "prepare",
    "raw_piece",
]

#: A player's piece: (topic index per message, position in that topic's raws, raws per topic, log times).
RawPiece = tuple[np.ndarray, np.ndarray, Sequence[Sequence[bytes]], np.ndarray]
#: Topic index of the air temperature (frc_01, frc_02, air temperature).
AIR = 2
#: Float64 fields of a ``sensor_msgs/Temperature`` after its header: temperature, variance.
_AIR_FLOATS = 2


@dataclass
class LiveChain:
    """The named checkpoint of a live replay, the node's private copy of it, the air it held.

    Attributes:
        checkpoint: the checkpoint named (``--checkpoint``): read before, written once at the end.
        private: the node's copy (resumed from and written by the node; removed with the run's
            temporary directory).
        held: the air the named checkpoint held unfed (None: none), published merged with the bag.
        notes: what opening the named checkpoint did (set aside as unusable, stale writers' files).
        config: the parameters the offline chain's checkpoint records (this one's path, its
            period), written in place of the node's (its private path, written rarely).

    """

    checkpoint: Path
    private: Path
    held: TemperatureSeries | None = None
    notes: list[str] = field(default_factory=list)
    config: Any = None
    used_before: int = 0
    clock_before: int | None = None

    def finish(
        self,
        state: dict[str, Any],
        tail: TemperatureSeries | None,
        taken: Sequence[dict[str, Any]] = (),
        forces_fed: int = 0,
    ) -> Path | None:
        """Write ``state`` (the node's, after the bag's last force) with ``tail`` held, to ``checkpoint``.

        The parameters recorded are the offline chain's: the node's named its private copy, gone
        after the run, as the path a shadow resumed from this file without parameters writes to.
        ``taken``: the signatures of the bags played (``replay.taken``), recorded as taken.
        ``forces_fed``: the load-cell messages played; when there were some, the node used none and
        its data clock did not move (data older than the checkpoint's), a checkpoint resumed from is
        left as it was (None), as the offline chain leaves it (``replay_bag``). A newer bag whose
        load cells all failed moved the clock with its air: written, as offline.
        """
        used, clock = (self.used_before, _forces_used(state)), (self.clock_before, _clock(state))
        if older_data(forces_fed, used, clock, tail, self.held) and self.checkpoint.is_file():
            return None
        state = dict(state)
        before = json.loads(str(state["taken_bags"])) if "taken_bags" in state else []
        state["taken_bags"] = json.dumps(recorded(before, taken))
        if self.config is not None:
            state["config"] = json.dumps(self.config.to_params())
        state.pop("held_air", None)
        if tail is not None and len(tail):
            state["held_air"] = held_air_arrays(tail)
        return save_state(state, self.checkpoint)


def _forces_used(state: dict[str, Any]) -> int:
    """Load-cell messages a checkpoint's state has used (its ``used`` counts)."""
    return forces_used(json.loads(str(state["used"])) if "used" in state else {})


def _clock(state: dict[str, Any]) -> int | None:
    """Return a checkpoint state's data clock: its latest accepted stamp (``Shadow.clock_ns``)."""
    stamps = [int(g["last_ns"]) for g in state.get("gates", []) if bool(g["has_last"])]
    return max(stamps) if stamps else None


def prepare(config: Any, surrogate: Any, checkpoint: str | Path, private: Path) -> LiveChain:
    """Open ``checkpoint`` as the node would, and write the node's copy of it without held air to ``private``.

    Raises:
        CheckpointError: it cannot be written, or it is unusable and ``checkpoint_unusable`` is
            ``stop`` (``fresh``: set aside, and the node starts from the prior).

    """
    from bridge_shadow.estimate.startup import open_shadow

    file = Path(checkpoint)
    config = config.replace(checkpoint_path=str(checkpoint))  # as given, as the offline chain records it
    _, notes = open_shadow(config, surrogate)
    # what a user must hear of (a file set aside, a killed writer's left), not "resumed" or "none yet";
    # told by the whole opening (a note of a file set aside opens with its name, "resumed.npz: ...")
    usual = (f"resumed from {file}: ", f"checkpoint {file}: none yet")
    chain = LiveChain(file, private, config=config, notes=[n for n in notes if not n.startswith(usual)])
    if file.is_file():  # resumable (an unusable one is set aside by now)
        state = load_state(file)
        chain.used_before, chain.clock_before = _forces_used(state), _clock(state)
        held = state.pop("held_air", None)
        chain.held = held_air_series(held) if held is not None else None
        save_state(state, private)
    return chain


def merge_log_order(log_ns: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge per-topic log times into one arrival order (stable: ties keep topic order).

    Returns:
        ``topic`` (n,) int index into ``log_ns``, ``pos`` (n,) index within that topic, and the
        merged ``log_ns`` (n,) int64.

    """
    sizes = [len(x) for x in log_ns]
    topic = np.concatenate([np.full(n, i, dtype=np.int64) for i, n in enumerate(sizes)])
    pos = np.concatenate([np.arange(n, dtype=np.int64) for n in sizes])
    merged = np.concatenate([np.asarray(x, np.int64) for x in log_ns])
    order = np.argsort(merged, kind="stable")
    return topic[order], pos[order], merged[order]


def encode_air(t: TemperatureSeries) -> list[bytes]:
    """Serialize decoded air messages again: stamp (as decoded: ``carry``), frame, temperature, variance."""
    values = np.column_stack([t.temp_c, np.asarray(t.variance, float)])
    return encode_stamped_floats(t.stamp_ns, np.asarray(t.frame_id, dtype=object), values, carry=True)


def encode_forces(f: ForceSeries) -> list[bytes]:
    """Serialize decoded force messages again: a wrench's ``force.z`` (the shadow reads no other)."""
    values = np.zeros((len(f), 6))
    values[:, 2] = f.force_n
    return encode_stamped_floats(f.stamp_ns, np.asarray(f.frame_id, dtype=object), values, carry=True)


def raw_piece(piece: MonitoringData) -> RawPiece:
    """Return a decoded piece serialized again, as a player publishes it: in log order, ties by topic."""
    raws = [*(encode_forces(piece.forces[ch]) for ch in CHANNELS), encode_air(piece.temperature)]
    logs = [*(piece.forces[ch].log_ns for ch in CHANNELS), piece.temperature.log_ns]
    topic, pos, merged = merge_log_order(logs)
    return topic, pos, raws, merged


def merge_held(pieces: Iterable[RawPiece], held: TemperatureSeries | None) -> Iterator[RawPiece]:
    """Yield ``pieces`` with ``held``'s air merged in by log time, before the pieces' own at equal log time.

    A held message goes into the first piece whose last log time is not before its own; what is
    left after the last piece follows as a piece of its own.
    """
    if held is None or not len(held):
        yield from pieces
        return
    logs = np.asarray(held.log_ns, np.int64)
    raws = encode_air(held)
    i, n = 0, len(logs)
    for topic, pos, piece_raws, piece_logs in pieces:
        if not len(topic):
            continue
        j = int(np.searchsorted(logs, piece_logs[-1], side="right")) if i < n else n
        if j == i:
            yield topic, pos, piece_raws, piece_logs
            continue
        base = len(piece_raws[AIR])
        air = [*piece_raws[AIR], *raws[i:j]]
        t = np.concatenate([np.full(j - i, AIR, np.int64), topic])
        p = np.concatenate([base + np.arange(j - i, dtype=np.int64), pos])
        lg = np.concatenate([logs[i:j], piece_logs])
        order = np.argsort(lg, kind="stable")  # the held air first at equal log time
        yield t[order], p[order], [piece_raws[0], piece_raws[1], air], lg[order]
        i = j
    if i < n:
        yield np.full(n - i, AIR, np.int64), np.arange(n - i, dtype=np.int64), [[], [], raws[i:]], logs[i:]


def _take(piece: RawPiece, keep: np.ndarray) -> RawPiece:
    topic, pos, raws, logs = piece
    return topic[keep], pos[keep], raws, logs[keep]


class RawAirTail:
    """A player's pieces in order, the air after the last force held until forces follow (``AirTail``).

    The rule of ``replay.air_tail.AirTail``, on raw pieces: in a piece with forces, the air whose
    log time is at or after the piece's last force is held (it goes on just before the next piece
    with forces); a piece of air alone is held whole; past ``limit`` messages held, they go on.

    Attributes:
        tail: once iterated to the end, the pieces held then (the air past the bag's last force).
        released: air messages that went on past ``limit`` with no force after them yet.

    """

    def __init__(self, pieces: Iterable[RawPiece], limit: int = HELD_AIR_LIMIT) -> None:
        self._pieces = pieces
        self.limit = int(limit)
        self.tail: list[RawPiece] = []
        self.released = 0

    def __iter__(self) -> Iterator[RawPiece]:
        held: list[RawPiece] = []
        n_held = 0
        for piece in self._pieces:
            topic, _, _, logs = piece
            forces = np.flatnonzero(topic != AIR)
            if not len(forces):
                if len(topic):
                    held.append(piece)
                    n_held += len(topic)
                    if n_held > self.limit:
                        self.released += n_held
                        yield from held
                        held, n_held = [], 0
                continue
            yield from held
            held, n_held = [], 0
            after = (topic == AIR) & (logs >= logs[forces[-1]])
            yield _take(piece, ~after)
            if after.any():
                held.append(_take(piece, after))
                n_held += int(np.count_nonzero(after))
        self.tail = held

    @property
    def n_tail(self) -> int:
        """Messages held at the end (0 before the iteration ends)."""
        return sum(len(p[0]) for p in self.tail)


def decode_air(pieces: Sequence[RawPiece]) -> tuple[TemperatureSeries | None, int]:
    """Return the air messages of ``pieces`` decoded (None: none), and how many could not be.

    A message that cannot be decoded is left out, as the node drops it (``malformed``).
    """
    raws: list[bytes] = []
    logs: list[np.ndarray] = []
    for topic, pos, piece_raws, piece_logs in pieces:
        air = topic == AIR
        raws += [piece_raws[AIR][k] for k in pos[air].tolist()]
        logs.append(piece_logs[air])
    if not raws:
        return None, 0
    stamp, frame, values, kept = decode_stamped_floats_kept(raws, _AIR_FLOATS)
    dropped = len(raws) - len(kept)
    if not len(kept):
        return None, dropped
    return TemperatureSeries(stamp, values[:, 0], values[:, 1], frame, np.concatenate(logs)[kept]), dropped
