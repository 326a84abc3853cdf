"""Message gate per input topic (robot_localization style): drop and count, never propagate.

Reasons counted at message level:

- ``nonfinite``: NaN or inf value.
- ``out_of_range``: force outside ``[force_min_n, force_max_n]`` (non-positive or absurd),
  temperature outside ``[temp_min_c, temp_max_c]``.
- ``frame_id``: wrong ``header.frame_id`` (an empty one is accepted as unknown).
- ``duplicate``: same stamp as the last accepted on the topic; ``out_of_order``: older.
- ``clock_jump``: more than ``clock_jump_s`` away from the topic's last stamp (or from the data
  clock, for a topic's first message); a forward jump becomes the new time base once
  ``clock_jump_confirm`` consecutive messages agree.
- ``late``: force stamp in a window already closed (counted by the shadow).

The common case (finite, in range, strictly increasing, no jump) is decided in a few vectorized
numpy passes; any irregular chunk falls back to an exact sequential loop, so the result never
depends on how messages are chunked.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

__all__ = ["MESSAGE_REASONS", "REASONS", "TopicGate"]

#: The rejection reasons of single messages (the gate's and the late-arrival check), in report order.
MESSAGE_REASONS: tuple[str, ...] = (
    "nonfinite",
    "out_of_range",
    "frame_id",
    "duplicate",
    "out_of_order",
    "clock_jump",
    "late",
)
#: Every rejection reason the shadow counts (message and window level), in report order.
REASONS: tuple[str, ...] = (
    *MESSAGE_REASONS,
    "stale_temperature",
    "missing_topic",
    "sparse_window",
    "outlier",
)


class TopicGate:
    """Gate state of one topic.

    Attributes:
        frame_id: expected frame id (None: not checked).
        lo, hi: accepted value range (inclusive).
        jump_ns: clock-jump threshold in ns; confirm: messages needed to accept a new time base.
        last_ns: last accepted stamp (None before the first).
        jump_count, jump_last_ns: consecutive jumped messages and the last of them.

    """

    def __init__(self, frame_id: str | None, lo: float, hi: float, jump_ns: int, confirm: int) -> None:
        self.frame_id = frame_id
        self.lo, self.hi = float(lo), float(hi)
        self.jump_ns = int(jump_ns)
        self.confirm = int(confirm)
        self.last_ns: int | None = None
        self.jump_count = 0
        self.jump_last_ns = 0

    def __call__(
        self,
        stamp_ns: np.ndarray,
        value: np.ndarray,
        frame_id: np.ndarray | str | None,
        clock_ns: tuple[int, int] | None,
        counts: Counter,
    ) -> np.ndarray:
        """Return the boolean mask of accepted messages and add rejections to ``counts``.

        ``clock_ns`` is the span (first, latest) of accepted stamps over all topics, or None; a
        topic's first message must lie within ``clock_jump_s`` of it.
        """
        stamps = np.asarray(stamp_ns, dtype=np.int64)
        vals = np.asarray(value, dtype=float)
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
            if isinstance(frame_id, str):
                good_frame = np.full(len(stamps), frame_id in (self.frame_id, ""))
            else:
                frames = np.asarray(frame_id, dtype=object)
                good_frame = (frames == self.frame_id) | (frames == "")
            bad = int(np.count_nonzero(ok & ~good_frame))
            if bad:
                counts["frame_id"] += bad
            ok &= good_frame
        idx = np.flatnonzero(ok)
        if not len(idx):
            return ok
        s = stamps[idx]
        if self.last_ns is None:
            ds = np.diff(s)
            first_ok = self._near_clock(int(s[0]), clock_ns)
        else:
            ds = np.diff(s, prepend=np.int64(self.last_ns))
            first_ok = True
        if first_ok and self.jump_count == 0 and np.all(ds > 0) and np.all(ds <= self.jump_ns):
            self.last_ns = int(s[-1])
            return ok
        keep = self._sequential(s, clock_ns, counts)
        ok[idx[~keep]] = False
        return ok

    def _near_clock(self, stamp: int, clock_ns: tuple[int, int] | None) -> bool:
        return clock_ns is None or clock_ns[0] - self.jump_ns <= stamp <= clock_ns[1] + self.jump_ns

    def _sequential(self, s: np.ndarray, clock_ns: tuple[int, int] | None, counts: Counter) -> np.ndarray:
        keep = np.zeros(len(s), dtype=bool)
        for i, stamp in enumerate(s.tolist()):
            last = self.last_ns
            if last is None:
                if self._near_clock(stamp, clock_ns):
                    keep[i] = True
                    self.last_ns = stamp
                    continue
                jumped = True
            elif stamp == last:
                counts["duplicate"] += 1
                continue
            elif stamp < last:
                if last - stamp > self.jump_ns:
                    counts["clock_jump"] += 1
                else:
                    counts["out_of_order"] += 1
                continue
            else:
                jumped = stamp - last > self.jump_ns
            if not jumped:
                keep[i] = True
                self.last_ns = stamp
                self.jump_count = 0
                continue
            consistent = self.jump_count > 0 and 0 < stamp - self.jump_last_ns <= self.jump_ns
            self.jump_count = self.jump_count + 1 if consistent else 1
            self.jump_last_ns = stamp
            if self.jump_count >= self.confirm:
                keep[i] = True
                self.last_ns = stamp
                self.jump_count = 0
            else:
                counts["clock_jump"] += 1
        return keep

    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        return {
            "last_ns": -1 if self.last_ns is None else self.last_ns,
            "has_last": self.last_ns is not None,
            "jump_count": self.jump_count,
            "jump_last_ns": self.jump_last_ns,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the state."""
        self.last_ns = int(state["last_ns"]) if bool(state["has_last"]) else None  # type: ignore[call-overload]
        self.jump_count = int(state["jump_count"])  # type: ignore[call-overload]
        self.jump_last_ns = int(state["jump_last_ns"])  # type: ignore[call-overload]
