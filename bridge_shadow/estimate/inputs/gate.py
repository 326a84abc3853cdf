"""Message gate per input topic (robot_localization style): drop and count, never propagate.

Reasons counted at message level:

- ``nonfinite``: NaN or inf value.
- ``out_of_range``: force outside ``[force_min_n, force_max_n]`` (non-positive or absurd),
  temperature outside ``[temp_min_c, temp_max_c]``.
- ``frame_id``: wrong ``header.frame_id`` (an empty one is accepted as unknown).
- ``duplicate``: same stamp as the last accepted on the topic; ``out_of_order``: older.
- ``clock_jump``: more than ``clock_jump_s`` away from the topic's last stamp (or from the data
  clock, for a topic's first message). A forward jump is held, not rejected: once
  ``clock_jump_confirm`` consecutive messages agree (each within ``clock_jump_s`` of the one
  before) it is the new time base and the held messages are taken (a data outage longer than
  ``clock_jump_s`` loses nothing); if the stream falls back to the old time base first, the held
  messages were wild and are counted here. Also a single wild stamp ahead of the stream (see
  below).
- ``late``: force stamp in a window already closed (counted by the shadow).
- ``frozen`` (force topics): the same value repeated more than ``FROZEN_REPEATS`` times and for
  longer than ``FROZEN_S`` since the run of it began: a channel that stopped while its logger
  holds the last reading (a data logger's sample-and-hold when a load cell drops out), not a
  load. The run's first ``FROZEN_S`` are taken (nothing tells it apart yet), every later repeat
  is rejected.

A single wild stamp costs that one message only. A stamp that steps forward more than
``GAP_FACTOR`` times the topic's previous step (a gap in the data, or one glitched stamp, say
25 min ahead) is held back until the topic's next message decides: if that one comes after it,
the gap was real and the held message is taken (``pop_released`` hands it to the caller, before
the messages of the current chunk); if it comes between the last accepted stamp and the held
one, the held stamp was wild and only it is rejected (``clock_jump``). Accepting the wild stamp
at once would make every good message after it ``out_of_order`` until the stream caught up with
it, and move the data clock so that windows close with a topic missing. The price is a delay of
one message after each real gap (``release_held`` takes a held message at the end of the data).

The common case (finite, in range, strictly increasing, no jump, no gap) is decided in vectorized
numpy passes over runs of regular messages; an irregular message is decided by an exact
sequential step, so the result never depends on how messages are chunked.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

__all__ = ["FROZEN_REPEATS", "FROZEN_S", "GAP_FACTOR", "MESSAGE_REASONS", "REASONS", "TopicGate"]

#: The rejection reasons of single messages (the gate's and the late-arrival check), in report order.
MESSAGE_REASONS: tuple[str, ...] = (
    "nonfinite",
    "out_of_range",
    "frame_id",
    "duplicate",
    "out_of_order",
    "clock_jump",
    "late",
    "frozen",
)
#: A force value repeated unchanged for longer than this is a stopped channel [s]. The public
#: records repeat a value for at most 4 samples (40 ms at 100 Hz; 0.7-0.8 % of their samples repeat
#: the one before: a slower channel's sample-and-hold); a load cell's noise (60-80 N per sample)
#: makes a run of identical readings over seconds a logger holding its last value. Ten seconds
#: keep any sample-and-hold of a live channel (a 1 Hz logger's ten readings) and cost a stopped
#: one its first ten seconds.
FROZEN_S = 10.0
#: ... and more often than this: a few repeats across a jump of the stamps are no run of seconds.
FROZEN_REPEATS = 10
#: A forward step larger than this many times the topic's previous one is held until the next
#: message shows whether it was a real gap or a wild stamp (the bundled and real records step
#: evenly: the largest ratio of two consecutive steps outside gaps is below 2).
GAP_FACTOR = 4
#: Up to this many messages ``TopicGate._regular`` tests them in Python numbers (``_regular_few``),
#: more in numpy: a node's drain brings a few dozen per topic, where numpy's per-call cost dominates.
REGULAR_FEW = 64
#: Messages ``TopicGate._decide`` first looks ahead at for a run of regular ones (doubled while the
#: run goes on): a short block, not the rest of the batch, after each irregular message.
LOOKAHEAD = 64
#: Every rejection reason the shadow counts (message and window level), in report order.
REASONS: tuple[str, ...] = (
    *MESSAGE_REASONS,
    "stale_temperature",
    "missing_topic",
    "sparse_window",
    "traffic",
    "step_window",
    "outlier",
)


class TopicGate:
    """Gate state of one topic.

    Attributes:
        frame_id: expected frame id (None: not checked).
        lo, hi: accepted value range (inclusive).
        jump_ns: clock-jump threshold in ns; confirm: messages needed to accept a new time base.
        last_ns: last accepted stamp (None before the first); last_step_ns: the step before it
            (0: unknown).
        pending: messages held after a forward jump beyond ``jump_ns``, waiting for confirmation
            (stamp, value, index in the current call's arrays or -1).
        held_ns, held_value: a message held after a large forward step (None: none held).
        frozen_ns: how long one value may repeat before it is ``frozen`` (None: not checked);
            run_value, run_since_ns, run_count: the current run of one value, its first stamp, its
            length (carried across calls).

    """

    def __init__(
        self,
        frame_id: str | None,
        lo: float,
        hi: float,
        jump_ns: int,
        confirm: int,
        frozen_ns: int | None = None,
    ) -> None:
        self.frame_id = frame_id
        self.frozen_ns = frozen_ns
        self.run_value = float("nan")  # the value of the current run of repeats, since when, how many
        self.run_since_ns = 0
        self.run_count = 0
        self.lo, self.hi = float(lo), float(hi)
        self.jump_ns = int(jump_ns)
        self.confirm = int(confirm)
        self.last_ns: int | None = None
        self.last_step_ns = 0
        self.pending: list[tuple[int, float, int]] = []
        self.held_ns: int | None = None
        self.held_value = float("nan")
        self._held_index = -1  # index of the held message in the current call's arrays, or -1
        self._released: list[tuple[int, float]] = []
        #: runs found frozen in the last call: (first stamp of the run, its first frozen stamp);
        #: the head before it was taken (``pop_frozen_heads``)
        self._frozen_heads: list[tuple[int, int]] = []

    def __call__(
        self,
        stamp_ns: np.ndarray,
        value: np.ndarray,
        frame_id: np.ndarray | str | None,
        clock_ns: tuple[int, int] | None,
        counts: Counter,
        try_regular: bool = True,
    ) -> np.ndarray:
        """Return the boolean mask of accepted messages and add rejections to ``counts``.

        ``clock_ns`` is the span (first, latest) of accepted stamps over all topics, or None; a
        topic's first message must lie within ``clock_jump_s`` of it. A message held in an earlier
        call and accepted in this one is not in the mask: take it with ``pop_released`` (or use
        ``with_released``), it comes before the messages accepted here. ``try_regular`` False:
        the caller has just found the batch not regular (``take_regular``), not tested again.
        """
        stamps = np.asarray(stamp_ns, dtype=np.int64)
        vals = np.asarray(value, dtype=float)
        if try_regular and self.take_regular(stamps, vals, frame_id):
            return np.ones(len(vals), dtype=bool)
        ok = np.isfinite(vals)
        bad = int(np.count_nonzero(~ok))
        if bad:
            counts["nonfinite"] += bad
        in_range = (vals >= self.lo) & (vals <= self.hi)
        bad = int(np.count_nonzero(ok & ~in_range))
        if bad:
            counts["out_of_range"] += bad
        ok &= in_range
        if self.frame_id is not None and frame_id is not None:
            good_frame = self._good_frames(frame_id, len(stamps))
            bad = int(np.count_nonzero(ok & ~good_frame))
            if bad:
                counts["frame_id"] += bad
            ok &= good_frame
        if self.frozen_ns is not None:
            idx = np.flatnonzero(ok)
            if len(idx):
                frozen = self._frozen(stamps[idx], vals[idx], self.frozen_ns)
                bad = int(np.count_nonzero(frozen))
                if bad:
                    counts["frozen"] += bad
                    ok[idx[frozen]] = False
        idx = np.flatnonzero(ok)
        if not len(idx):
            return ok
        keep = self._decide(stamps[idx], vals[idx], clock_ns, counts)
        ok[idx[~keep]] = False
        return ok

    def take_regular(self, stamps: np.ndarray, vals: np.ndarray, frame_id: np.ndarray | str | None) -> bool:
        """Accept every message of a batch of regular ones (``_regular``); False: nothing done.

        What ``__call__`` does with such a batch, without its mask: every message is taken, none is
        held, released or counted (none held, waiting or released before: none is released now).
        """
        if (
            self.last_ns is None
            or self.held_ns is not None
            or self.pending
            or self._released
            or not len(vals)
        ):
            return False
        return self._regular(stamps, vals, frame_id)

    def _regular(self, s: np.ndarray, v: np.ndarray, frame_id: np.ndarray | str | None) -> bool:
        """Take a batch of only regular messages at once; return False (nothing done) otherwise.

        Regular: finite and in range, of the expected frame, no value repeating the one before
        (no run that could grow ``frozen``), stamps strictly increasing by steps within
        ``jump_ns`` and within ``GAP_FACTOR`` of the step before. Every message of such a batch is
        accepted by the general path too, which leaves the same state (the common case of a live
        stream, decided in a handful of numpy calls instead of the general path's few dozen).
        """
        if len(v) <= REGULAR_FEW:
            return self._regular_few(s.tolist(), v.tolist(), frame_id)
        lo, hi = float(v.min()), float(v.max())  # NaN if any is NaN
        if not (math.isfinite(lo) and math.isfinite(hi) and self.lo <= lo and hi <= self.hi):
            return False
        if (
            self.frame_id is not None
            and frame_id is not None
            and not self._good_frames(frame_id, len(v)).all()
        ):
            return False
        if self.frozen_ns is not None and (v[0] == self.run_value or bool(np.any(v[1:] == v[:-1]))):
            return False
        assert self.last_ns is not None
        ds = np.empty(len(s), dtype=np.int64)
        ds[0] = s[0] - self.last_ns
        np.subtract(s[1:], s[:-1], out=ds[1:])
        if int(ds.min()) <= 0 or int(ds.max()) > self.jump_ns:
            return False
        if self.last_step_ns > 0 and int(ds[0]) > GAP_FACTOR * self.last_step_ns:
            return False
        if bool(np.any(ds[1:] > GAP_FACTOR * ds[:-1])):
            return False
        if self.frozen_ns is not None:  # every value starts a run of its own (``_frozen``)
            self.run_value, self.run_since_ns, self.run_count = float(v[-1]), int(s[-1]), 1
        self.last_ns, self.last_step_ns = int(s[-1]), int(ds[-1])
        return True

    def _regular_few(self, s: list[int], v: list[float], frame_id: np.ndarray | str | None) -> bool:
        """``_regular`` of a few messages in one pass over Python numbers: the same tests, the same state.

        A node's drain brings a few dozen messages per topic; numpy's per-call cost made the
        vectorized tests most of the gate's time there.
        """
        lo, hi = self.lo, self.hi
        if math.isinf(lo) or math.isinf(hi):
            for x in v:
                if not lo <= x <= hi or math.isinf(x):  # (NaN fails the range)
                    return False
        else:
            for x in v:
                if not lo <= x <= hi:  # (NaN and inf fail a finite range)
                    return False
        if self.frame_id is not None and frame_id is not None:
            if isinstance(frame_id, str):
                if frame_id not in (self.frame_id, ""):
                    return False
            else:
                expected = self.frame_id
                frames = frame_id.tolist() if isinstance(frame_id, np.ndarray) else list(frame_id)
                for f in frames:
                    if not (f == expected or f == ""):
                        return False
        if self.frozen_ns is not None:
            before = self.run_value
            for x in v:
                if x == before:
                    return False
                before = x
        assert self.last_ns is not None
        prev, step, jump = self.last_ns, self.last_step_ns, self.jump_ns
        for t in s:
            d = t - prev
            if d <= 0 or d > jump or (step > 0 and d > GAP_FACTOR * step):
                return False
            prev, step = t, d
        if self.frozen_ns is not None:  # every value starts a run of its own (``_frozen``)
            self.run_value, self.run_since_ns, self.run_count = v[-1], s[-1], 1
        self.last_ns, self.last_step_ns = s[-1], step
        return True

    def _good_frames(self, frame_id: np.ndarray | str, n: int) -> np.ndarray:
        """Mask of the ``n`` messages whose frame_id is the expected one or empty (unknown)."""
        if isinstance(frame_id, str):
            return np.full(n, frame_id in (self.frame_id, ""))
        frames = np.asarray(frame_id, dtype=object)
        good = frames == self.frame_id
        if not good.all():  # one comparison per message in the common case, two where any differs
            good |= frames == ""
        return good

    def _frozen(self, s: np.ndarray, v: np.ndarray, frozen_ns: int) -> np.ndarray:
        """Mark the messages that repeat their run's value longer than ``frozen_ns`` after its start.

        Runs are read in arrival order and carried across calls (``run_value``, ``run_since_ns``,
        ``run_count``), so the result does not depend on the chunking.
        """
        new = np.empty(len(v), bool)
        new[0] = not v[0] == self.run_value  # NaN never repeats
        new[1:] = v[1:] != v[:-1]
        starts = np.flatnonzero(new)
        run = np.cumsum(new) - 1  # -1: the run carried from the last call
        first = starts[np.maximum(run, 0)] if len(starts) else np.zeros(len(v), np.int64)
        carried = run < 0
        since = np.where(carried, self.run_since_ns, s[first])
        count = np.where(carried, self.run_count + np.arange(1, len(v) + 1), np.arange(len(v)) - first + 1)
        self.run_since_ns, self.run_count = int(since[-1]), int(count[-1])
        self.run_value = float(v[-1])
        frozen = ((s - since) > frozen_ns) & (count > FROZEN_REPEATS)
        if frozen.any():  # each run's first frozen message (arrival order) bounds the head it took
            runs, first = np.unique(since[frozen], return_index=True)
            self._frozen_heads.extend(zip(runs.tolist(), s[frozen][first].tolist(), strict=True))
        return frozen

    def pop_frozen_heads(self) -> list[tuple[int, int]]:
        """Return and forget the runs found frozen since the last call: ``(run start, first frozen)`` ns.

        The gate took each run's first ``frozen_ns`` (nothing told it apart yet); a run that
        turned out frozen is a channel that stopped, its head too (``Shadow._gate`` takes it back
        from the windows still open: a cell stuck at its old value through a record read its first
        seconds as the state beside the other cell's new one, a change 6 mm off at probability 1).
        The same run found again later in its length is reported again; taking it back is then
        nothing.
        """
        heads, self._frozen_heads = self._frozen_heads, []
        return heads

    def _decide(
        self, s: np.ndarray, v: np.ndarray, clock_ns: tuple[int, int] | None, counts: Counter
    ) -> np.ndarray:
        """Accept or reject the (finite, in-range, right-frame) messages ``s`` in order."""
        n = len(s)
        keep = np.zeros(n, dtype=bool)
        i = 0
        look = LOOKAHEAD
        while i < n:
            if self.last_ns is not None and self.held_ns is None and not self.pending:
                # a run of regular messages, decided at once; looked at a block at a time, doubled
                # while the run goes on, so that a stretch of irregular messages (a record given
                # twice: every other message a duplicate) costs each of them a short block, not
                # the rest of the batch (which made the gate quadratic in such a stretch)
                ds = np.diff(s[i : i + look], prepend=np.int64(self.last_ns))
                prev = np.empty_like(ds)
                prev[0] = self.last_step_ns
                prev[1:] = ds[:-1]
                irregular = (ds <= 0) | (ds > self.jump_ns) | ((prev > 0) & (ds > GAP_FACTOR * prev))
                bad = np.flatnonzero(irregular)
                j = int(bad[0]) if len(bad) else len(ds)
                if j:
                    keep[i : i + j] = True
                    self.last_ns = int(s[i + j - 1])
                    self.last_step_ns = int(ds[j - 1])
                    i += j
                    if i == n:
                        break
                    if not len(bad):
                        look = min(2 * look, n)  # the block was regular to its end: a longer one
                        continue
                look = LOOKAHEAD
            self._step(i, int(s[i]), float(v[i]), keep, clock_ns, counts)
            i += 1
        if self.held_ns is not None and self._held_index >= 0:
            self._held_index = -1  # still held after this call: released later by value
        self.pending = [(t, x, -1) for t, x, _ in self.pending]  # likewise
        return keep

    def _accept(self, stamp: int) -> None:
        if self.last_ns is not None:
            self.last_step_ns = stamp - self.last_ns
        self.last_ns = stamp

    def _take_held(self, keep: np.ndarray) -> None:
        assert self.held_ns is not None
        if self._held_index >= 0:
            keep[self._held_index] = True
        else:
            self._released.append((self.held_ns, self.held_value))
        self._accept(self.held_ns)
        self.held_ns, self._held_index = None, -1

    def _near_clock(self, stamp: int, clock_ns: tuple[int, int] | None) -> bool:
        return clock_ns is None or clock_ns[0] - self.jump_ns <= stamp <= clock_ns[1] + self.jump_ns

    def _step(
        self,
        i: int,
        stamp: int,
        value: float,
        keep: np.ndarray,
        clock_ns: tuple[int, int] | None,
        counts: Counter,
    ) -> None:
        """Decide one message exactly (the sequential definition the vectorized runs follow)."""
        if self.held_ns is not None:
            if stamp >= self.held_ns:  # the stream goes on after the held message: a real gap
                self._take_held(keep)
            elif self.last_ns is None or stamp > self.last_ns:  # it falls back: the held stamp was wild
                counts["clock_jump"] += 1
                self.held_ns, self._held_index = None, -1
        last = self.last_ns
        if last is None:
            if self._near_clock(stamp, clock_ns):
                keep[i] = True
                self._accept(stamp)
                return
            jumped = True
        elif stamp == last:
            counts["duplicate"] += 1
            return
        elif stamp < last:
            if last - stamp > self.jump_ns:
                counts["clock_jump"] += 1
            else:
                counts["out_of_order"] += 1
            return
        else:
            step = stamp - last
            jumped = step > self.jump_ns
            if not jumped and self.last_step_ns > 0 and step > GAP_FACTOR * self.last_step_ns:
                self.held_ns, self.held_value, self._held_index = stamp, value, i
                return
        if not jumped:
            self._drop_pending(counts)  # the stream went on in the old time base
            keep[i] = True
            self._accept(stamp)
            return
        if self.pending and not 0 < stamp - self.pending[-1][0] <= self.jump_ns:
            self._drop_pending(counts)  # not the same new time base: the earlier ones were wild
        self.pending.append((stamp, value, i))
        if len(self.pending) >= self.confirm:
            self._take_pending(keep)

    def _drop_pending(self, counts: Counter) -> None:
        if self.pending:
            counts["clock_jump"] += len(self.pending)
            self.pending = []

    def _take_pending(self, keep: np.ndarray) -> None:
        """Take the held jumped messages, in order: they are the new time base."""
        for stamp, value, index in self.pending:
            if index >= 0:
                keep[index] = True
            else:
                self._released.append((stamp, value))
        stamps = [t for t, _, _ in self.pending]
        self.last_ns = stamps[-1]
        self.last_step_ns = stamps[-1] - stamps[-2] if len(stamps) > 1 else 0
        self.pending = []

    def release_held(self) -> bool:
        """End of the data: take held messages (``pop_released`` returns them); True if there were any."""
        if self.pending:
            self._take_pending(np.zeros(0, dtype=bool))
            return True
        if self.held_ns is None:
            return False
        self._released.append((self.held_ns, self.held_value))
        self._accept(self.held_ns)
        self.held_ns, self._held_index = None, -1
        return True

    def pop_released(self) -> tuple[np.ndarray, np.ndarray]:
        """Messages held earlier and accepted since: (stamps ns int64, values), oldest first."""
        out = self._released
        self._released = []
        return np.array([t for t, _ in out], dtype=np.int64), np.array([x for _, x in out], dtype=float)

    def with_released(self, stamps: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Prepend ``pop_released()`` to the messages accepted in the last call."""
        if not self._released:
            return stamps, values
        rs, rv = self.pop_released()
        return np.concatenate([rs, stamps]), np.concatenate([rv, values])

    def state_dict(self) -> dict[str, object]:
        """Plain-data state (a held message included; nothing is waiting in ``pop_released``)."""
        return {
            "last_ns": -1 if self.last_ns is None else self.last_ns,
            "has_last": self.last_ns is not None,
            "last_step_ns": self.last_step_ns,
            "pending_ns": np.array([t for t, _, _ in self.pending], dtype=np.int64),
            "pending_values": np.array([x for _, x, _ in self.pending], dtype=float),
            "has_held": self.held_ns is not None,
            "held_ns": -1 if self.held_ns is None else self.held_ns,
            # the last held value stays in the attribute once taken; it is state only while held
            "held_value": self.held_value if self.held_ns is not None else float("nan"),
            "run_value": self.run_value,
            "run_since_ns": self.run_since_ns,
            "run_count": self.run_count,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the state (a checkpoint written before the hold existed has no held message)."""
        self.last_ns = int(state["last_ns"]) if bool(state["has_last"]) else None  # type: ignore[call-overload]
        self.last_step_ns = int(state.get("last_step_ns", 0))  # type: ignore[call-overload]
        stamps = np.asarray(state.get("pending_ns", []), dtype=np.int64).reshape(-1)
        values = np.asarray(state.get("pending_values", []), dtype=float).reshape(-1)
        self.pending = [(int(t), float(x), -1) for t, x in zip(stamps, values, strict=True)]
        held = bool(state.get("has_held", False))
        self.held_ns = int(state["held_ns"]) if held else None  # type: ignore[call-overload]
        self.held_value = float(state["held_value"]) if held else float("nan")  # type: ignore[arg-type]
        self._held_index = -1
        self._released = []
        self.run_value = float(state.get("run_value", float("nan")))  # type: ignore[arg-type]
        self.run_since_ns = int(state.get("run_since_ns", 0))  # type: ignore[call-overload]
        self.run_count = int(state.get("run_count", 0))  # type: ignore[call-overload]
