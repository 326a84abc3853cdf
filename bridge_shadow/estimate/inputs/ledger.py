"""Per-topic input bookkeeping: what each topic delivered, what was rejected and why, said out loud.

A topic whose every message is rejected, or that never delivered, must not pass silently: the
shadow's diagnostics, the replay JSON and a WARN line name the topic, the reason and the value it
expected (``warnings``).
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.series import frame_ids
from bridge_shadow.timefmt import iso_utc

__all__ = ["TOPIC_KEYS", "TopicLedger"]

#: Keys of the three input topics in counters and diagnostics.
TOPIC_KEYS: tuple[str, str, str] = (*CHANNELS, "air_temperature")

#: The share of a topic's messages rejected for their stamps that is said out loud
#: (``TopicLedger.old_stamps_message``); the bundled bags and the real records reject none.
OLD_SHARE = 0.1
_STAMP_REASONS = ("clock_jump", "out_of_order", "duplicate", "late")
_VALUE_REASONS = ("nonfinite", "out_of_range", "frozen", "frame_id")
_OLD_CAUSES = (
    "not used: bags that overlap in time, a logger's clock set back (an hour, where daylight saving "
    "time ends), or a checkpoint (or data before) whose clock is ahead of these stamps; bags that "
    "overlap are read merged by log time when given together (replay BAG BAG ..., or archive), "
    "from a checkpoint made before any of them"
)


@dataclass
class TopicLedger:
    """Accepted and rejected messages of one input topic.

    Attributes:
        key: the topic key (``frc_01``, ``frc_02``, ``air_temperature``).
        expected_frame: the frame id the gate expects (None: not checked).
        value_range: accepted value range (lo, hi) and its unit.
        used: accepted messages; rejected: rejections by reason.
        last_frame: a frame id seen on a message rejected for its frame.
        last_value: a value seen on a message rejected as out of range.
        last_ok_ns: stamp of the last message accepted (in arrival order; -1: none yet).
        tail_n: messages rejected since that one (all of them when none was accepted), whose
            stamps span ``tail_first_ns .. tail_last_ns`` (-1: none): a topic that goes on
            delivering nothing usable to the end of the data (``dead_tail``).

    """

    key: str
    expected_frame: str | None
    value_range: tuple[float, float, str]
    used: int = 0
    rejected: Counter = field(default_factory=Counter)
    last_frame: str | None = None
    last_value: float | None = None
    last_ok_ns: int = -1
    tail_n: int = 0
    tail_first_ns: int = -1
    tail_last_ns: int = -1
    #: the counts of a resumed checkpoint: the warnings judge this run's messages (not saved)
    used_before: int = 0
    rejected_before: Counter = field(default_factory=Counter)
    #: the stamp of the last message the resumed checkpoint's run took (-1: not resumed), and this
    #: run's rejected messages stamped at or before it (not saved: the warnings judge this run)
    resumed_ok_ns: int = -1
    rejected_before_resume: int = 0

    def note(
        self,
        ok: np.ndarray,
        values: np.ndarray,
        frame_id: np.ndarray | str | None,
        counts_before: Counter,
        counts: Counter,
        stamps: np.ndarray | None = None,
    ) -> None:
        """Record one gated batch: ``ok`` mask, the values and frames, and the global counts around it.

        ``stamps`` (the messages' stamps, ns; None: not followed) keep the run of rejected messages
        since the last accepted one (``tail_n``).
        """
        self.used += int(np.count_nonzero(ok))
        if stamps is not None and len(ok):
            stamps = np.asarray(stamps, np.int64)
            if self.resumed_ok_ns >= 0 and not ok.all():
                self.rejected_before_resume += int(np.count_nonzero(~ok & (stamps <= self.resumed_ok_ns)))
            self._follow_tail(ok, stamps)
        for reason, n in counts.items():
            d = n - counts_before.get(reason, 0)
            if d:
                self.rejected[reason] += d
        if ok.all():
            return
        bad = ~ok
        if self.expected_frame is not None and frame_id is not None:
            frames = frame_ids(frame_id, len(ok))
            wrong = bad & (frames != self.expected_frame) & (frames != "")
            if wrong.any():
                self.last_frame = str(frames[np.flatnonzero(wrong)[-1]])
        lo, hi, _ = self.value_range
        out = bad & np.isfinite(values) & ((values < lo) | (values > hi))
        if out.any():
            self.last_value = float(values[np.flatnonzero(out)[-1]])

    def note_taken(self, n: int, last_ns: int) -> None:
        """``note`` of a batch of ``n`` messages all accepted, the last stamped ``last_ns`` (no rejection)."""
        self.used += n
        self.last_ok_ns = last_ns
        if self.tail_n:
            self.tail_n, self.tail_first_ns, self.tail_last_ns = 0, -1, -1

    def _follow_tail(self, ok: np.ndarray, stamps: np.ndarray) -> None:
        if ok[-1]:  # the common case: the batch's last message was taken
            self.last_ok_ns = int(stamps[-1])
            if self.tail_n:
                self.tail_n, self.tail_first_ns, self.tail_last_ns = 0, -1, -1
            return
        taken = np.flatnonzero(ok)
        if taken.size:
            j = int(taken[-1])
            self.last_ok_ns = int(stamps[j])
            self.tail_n, self.tail_first_ns, self.tail_last_ns = 0, -1, -1
            stamps = stamps[j + 1 :]
        if not stamps.size:
            return
        first, last = int(stamps.min()), int(stamps.max())
        self.tail_first_ns = first if self.tail_n == 0 else min(self.tail_first_ns, first)
        self.tail_last_ns = max(self.tail_last_ns, last)
        self.tail_n += len(stamps)

    def dead_tail(self, min_ns: int) -> tuple[int, int, int] | None:
        """``(messages, first_ns, last_ns)`` rejected since the last accepted one, if they span ``min_ns``.

        None when the topic's last message was accepted, or its rejected ones since span less.
        """
        if self.tail_n and self.tail_last_ns - self.tail_first_ns >= min_ns:
            return self.tail_n, self.tail_first_ns, self.tail_last_ns
        return None

    def run_counts(self) -> tuple[int, Counter]:
        """Return this run's used messages and rejections by reason (those since a resumed checkpoint)."""
        return self.used - self.used_before, self.rejected - self.rejected_before

    def all_rejected_message(self) -> str | None:
        """One line when every message of the topic this run was rejected (None otherwise)."""
        used, rejected = self.run_counts()
        total = sum(rejected.values())
        if used or not total:
            return None
        reason, n = rejected.most_common(1)[0]
        detail = {
            "frame_id": f"frame_id {self.last_frame!r}, expected {self.expected_frame!r}"
            + (
                " (parameter check_frame_id; the load cells' frames are the contract's)"
                if self.key in CHANNELS
                else " (parameter temperature_frame_id / check_frame_id)"
            ),
            "out_of_range": f"value {self.last_value!r}, expected {self.value_range[0]:g} .. "
            f"{self.value_range[1]:g} {self.value_range[2]}",
            "nonfinite": "NaN or infinite values, expected finite numbers",
            "clock_jump": f"stamps far from the data before them, {_OLD_CAUSES}",
            "out_of_order": f"stamps older than the data before them, {_OLD_CAUSES}",
            "late": "stamps in windows already closed: the data clock (every topic's stamps, the air's "
            f"too) had passed them, {_OLD_CAUSES}",
        }.get(reason, reason)
        return f"topic {self.key}: all {total} messages rejected ({n} for {reason}: {detail})"

    def old_stamps_message(self) -> str | None:
        """One line when at least ``OLD_SHARE`` of this run's messages were rejected for their stamps.

        A logger's glitches cost a message here and there; a tenth of a topic is a time base at
        odds with the data before it: bags of one bridge that overlap in time, or a checkpoint
        whose clock is ahead of the records (every one of their messages too old).
        """
        share = self._share_rejected(_STAMP_REASONS)
        if share is None:
            return None
        head, counts = share
        rejected = self.run_counts()[1]
        if not any(rejected[r] for r in _STAMP_REASONS if r != "duplicate"):
            # only repeats of the stamp just taken: bags that hold the same readings, read merged
            # (each record's bag with the day's air), lose nothing; the causes below misled there
            return (
                f"{head} repeat the stamp of the message taken just before them ({counts}): readings "
                "given twice, as by bags that each hold the day's air temperature, read merged, or a "
                "logger that repeats its stamps; each stamp is used once, its first message"
            )
        older = rejected["out_of_order"] + rejected["late"] + rejected["clock_jump"]
        if self.resumed_ok_ns >= 0 and older <= self.rejected_before_resume:
            # a checkpoint chain of bags that each hold the day's air: the next bag's copy of the
            # readings the run before took is older than the checkpoint's clock, the rest repeat
            # the held ones; every other cause of old stamps misled there as well
            taken = iso_utc(self.resumed_ok_ns, "seconds")
            return (
                f"{head} rejected for their stamps ({counts}), {self.rejected_before_resume} of them "
                f"stamped at or before the last one the checkpoint's run took ({taken}): "
                "readings that run was given already, as by bags that each hold the day's air "
                "temperature replayed one by one, or data older than the checkpoint; each stamp is used "
                "once, its first message"
            )
        return f"{head} rejected for their stamps ({counts}), {_OLD_CAUSES}"

    def bad_values_message(self) -> str | None:
        """One line when at least ``OLD_SHARE`` of this run's messages were rejected for their values.

        NaN, out of range, a held value (``frozen``) or a wrong frame: a cell that delivers mostly
        garbage is failing, and the counts alone did not say so (a load cell NaN for 59 s of every
        minute passed without a line).
        """
        share = self._share_rejected(_VALUE_REASONS)
        if share is None:
            return None
        head, counts = share
        used = self.run_counts()[0]
        return f"{head} rejected for their values ({counts}): the estimate rests on the {used} others"

    def _share_rejected(self, reasons: tuple[str, ...]) -> tuple[str, str] | None:
        """``("topic K: n of N messages (p %)", counts)`` when ``reasons`` took ``OLD_SHARE`` of this run's.

        None when fewer, or when every message was rejected (``all_rejected_message`` says it).
        """
        used, rejected = self.run_counts()
        those = {r: rejected[r] for r in reasons if rejected[r]}
        total = used + sum(rejected.values())
        n = sum(those.values())
        if not used or not total or n < OLD_SHARE * total:
            return None
        counts = ", ".join(f"{r} {c}" for r, c in those.items())
        return f"topic {self.key}: {n} of {total} messages ({100.0 * n / total:.0f} %)", counts

    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        return {
            "used": self.used,
            "rejected": json.dumps({k: int(v) for k, v in self.rejected.items()}),
            "last_frame": "" if self.last_frame is None else self.last_frame,
            "has_frame": self.last_frame is not None,
            "last_value": np.nan if self.last_value is None else self.last_value,
            "last_ok_ns": self.last_ok_ns,
            "tail_n": self.tail_n,
            "tail_first_ns": self.tail_first_ns,
            "tail_last_ns": self.tail_last_ns,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the bookkeeping."""
        self.used = self.used_before = int(state["used"])  # type: ignore[call-overload]
        self.rejected = Counter({k: int(v) for k, v in json.loads(str(state["rejected"])).items()})
        self.rejected_before = Counter(self.rejected)
        self.last_frame = str(state["last_frame"]) if bool(state["has_frame"]) else None
        v = float(state["last_value"])  # type: ignore[arg-type]
        self.last_value = None if np.isnan(v) else v
        # checkpoints written before the tail was followed have none
        self.last_ok_ns = int(state.get("last_ok_ns", -1))  # type: ignore[call-overload]
        self.resumed_ok_ns, self.rejected_before_resume = self.last_ok_ns, 0
        self.tail_n = int(state.get("tail_n", 0))  # type: ignore[call-overload]
        self.tail_first_ns = int(state.get("tail_first_ns", -1))  # type: ignore[call-overload]
        self.tail_last_ns = int(state.get("tail_last_ns", -1))  # type: ignore[call-overload]
