"""Window buffer: accepted samples in, closed 60 s windows out, many windows per call, vectorized.

The per-window counts and means come from the one window aggregator, ``bridge_shadow.windowing``.

Windows are fixed in stamp time, ``[k W, (k + 1) W)``. Window ``k`` is *due* once every force
topic has an accepted stamp at or past its end (or the data clock is ``topic_timeout_s`` past it)
and the air temperature has a reading at or past its end (or the clock is the temperature horizon
``max(topic_timeout_s, temperature_stale_s)`` past it). Each condition is monotone in ``k``, so
the due windows are a prefix ``[next_k, k_end)`` computed in O(1), and all of them are aggregated
at once: per-window sample counts, mean forces and mean matched temperatures come from
``np.bincount`` over every buffered sample, so a poll costs a few numpy calls however many windows
it closes.

Temperature at each force stamp is ``linear`` (interpolated between the bracketing readings) or
``hold`` (the last reading); a sample is stale when the reading it relies on is further than
``temperature_stale_s`` away. A window with stale samples is *used*, not skipped (a record taken
while the air logger paused is still a state of the supports; on 2022-04-11 the public air
temperature pauses from 13:05 to 13:40, when a later record of the lowering would have been taken):
its temperature is the interpolated or held one, and ``stale_variance`` adds what the air can have
done in the meantime. Window ``k`` only sees readings stamped before its end plus the
horizon, so a window's result does not depend on how much later data had been ingested when it
closed (chunking). A window that cannot see the first temperature reading ever accepted (none
yet, or it lies past the window's end plus the horizon) is not stale but *uncompensated*
(temperature NaN): a record without a temperature topic still estimates, loudly, also when a
later record with temperature arrives before its windows close (the traffic screen's hold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.estimate.inputs.traffic import PIECE_SILENCE_NS, screen_record
from bridge_shadow.windowing import sorted_union, window_index, window_stats

__all__ = [
    "AIR_DRIFT_K_PER_S",
    "AIR_RANGE_K",
    "SampleBuffer",
    "WindowBatch",
    "WindowBuffer",
    "stale_variance",
]

_NEVER = np.iinfo(np.int64).max
#: The largest daily range of the air at the bridge, K, and the fastest it changes, K/s: the
#: bridge's own March 2022 record (``Weather/TemperatureComparisonMUC.csv``: -3.9 to 19.7 C on
#: 2022-03-23, 23.6 K) and that range as a half-cosine rise over the 9 h from sunrise to the
#: afternoon maximum, whose steepest rate is ``pi / 2 x 23.6 K / 9 h = 4.1 K/h``.
AIR_RANGE_K = 23.6
AIR_DRIFT_K_PER_S = 0.5 * np.pi * AIR_RANGE_K / (9.0 * 3600.0)


def stale_variance(age_s: float, stale_s: float) -> float:
    """Return the variance (K^2) of a window's air temperature that rests on a reading ``age_s`` away.

    0 within ``stale_s`` (``temperature_stale_s``: the reading is the temperature); beyond it the
    air may have moved by up to ``AIR_DRIFT_K_PER_S x age`` since, in either direction, and by no
    more than a day's range (``AIR_RANGE_K``) however long ago: taken as the standard deviation (a
    held reading on the steepest rise is off by that much, an interpolated one by less).
    """
    if not age_s > stale_s:
        return 0.0
    return float(min(AIR_DRIFT_K_PER_S * age_s, AIR_RANGE_K) ** 2)


_NONE = -(2**62)
_SEEN = _NONE + 1  # the first temperature reading is visible to every window still open


class _Record:
    """Where the current record stands for the traffic screen (plain data, compared exactly).

    Attributes:
        scan_ns: force stamps before this were followed already.
        last_ns: the latest force stamp followed (None before the first).
        mode: ``0`` no open record (none yet, or it ended), ``1`` open and held since ``start_ns``,
            ``2`` open and released (it grew longer than the hold: passes unscreened).
        start_ns: first stamp of a held record (kept only while held, so that two front ends that
            both released a record behave alike whenever it started).
        piece_ns, before_ns: in a held record, the first stamp after its latest silence of
            ``PIECE_SILENCE_NS`` (a recording that stopped and started again, minutes apart) and
            the last stamp before that silence (``_NONE``: no such silence).

    """

    def __init__(
        self,
        scan_ns: int = _NONE,
        last_ns: int | None = None,
        mode: int = 0,
        start_ns: int = _NONE,
        piece_ns: int = _NONE,
        before_ns: int = _NONE,
    ) -> None:
        self.scan_ns, self.last_ns, self.mode, self.start_ns = scan_ns, last_ns, mode, start_ns
        self.piece_ns, self.before_ns = piece_ns, before_ns

    @property
    def open(self) -> bool:
        """Whether a record is open."""
        return self.mode != 0

    @property
    def holding(self) -> bool:
        """Whether the open record is held."""
        return self.mode == 1

    def begin(self, first_ns: int) -> None:
        """Start a held record at ``first_ns``."""
        self.mode, self.start_ns, self.last_ns = 1, first_ns, first_ns
        self.piece_ns = self.before_ns = _NONE

    def released(self, last_ns: int) -> None:
        """Take an open record as released, last followed at ``last_ns`` (a bag cut out of one)."""
        self.mode, self.last_ns, self.start_ns = 2, last_ns, _NONE
        self.piece_ns = self.before_ns = _NONE

    def resume(self, first_ns: int) -> None:
        """Note that the open record goes on at ``first_ns`` after a silence of a piece or longer."""
        if self.mode == 1 and self.last_ns is not None:
            self.piece_ns, self.before_ns = first_ns, self.last_ns

    def extend(self, last_ns: int, hold_ns: int) -> list[tuple[int, int]]:
        """Extend the open record to ``last_ns``; once longer than ``hold_ns``, release it.

        A held record that grows longer than the hold only because a recording started again
        minutes after the last one stopped (two 12-minute records 7 to 9 minutes apart, inside
        ``gap_s`` of each other) is two recordings: the part before the silence ends there and is
        returned as ``[(first, last)]`` to screen, and the record is held on from the piece after
        it, when that piece fits the hold (before, the pair was released unscreened and the test
        car's plateaus in both stayed data: the 10 mm state read 1.2-1.8 mm short).
        """
        self.last_ns = last_ns
        if self.mode != 1 or last_ns - self.start_ns <= hold_ns:
            return []
        if self.piece_ns != _NONE and last_ns - self.piece_ns <= hold_ns:
            done = [(self.start_ns, self.before_ns)]
            self.start_ns, self.piece_ns, self.before_ns = self.piece_ns, _NONE, _NONE
            return done
        self.mode, self.start_ns, self.piece_ns, self.before_ns = 2, _NONE, _NONE, _NONE
        return []

    def end(self) -> list[tuple[int, int]]:
        """End the open record; return ``[(first, last)]`` when it was held (to screen), else ``[]``."""
        done = [(self.start_ns, int(self.last_ns))] if self.mode == 1 and self.last_ns is not None else []
        self.mode, self.start_ns, self.piece_ns, self.before_ns = 0, _NONE, _NONE, _NONE
        return done

    def state_dict(self) -> dict[str, int]:
        """Plain-data state."""
        last = _NONE if self.last_ns is None else self.last_ns
        return {
            "scan_ns": self.scan_ns,
            "last_ns": last,
            "mode": self.mode,
            "start_ns": self.start_ns,
            "piece_ns": self.piece_ns,
            "before_ns": self.before_ns,
        }

    @classmethod
    def from_state_dict(cls, state: dict[str, int]) -> _Record:
        """Restore from ``state_dict``."""
        last = int(state["last_ns"])
        return cls(
            int(state["scan_ns"]),
            None if last == _NONE else last,
            int(state["mode"]),
            int(state["start_ns"]),
            int(state.get("piece_ns", _NONE)),  # a checkpoint from before the piece split: none
            int(state.get("before_ns", _NONE)),
        )


class SampleBuffer:
    """Accepted samples of one topic not yet consumed: sorted stamps (ns) and values, in chunks."""

    def __init__(self) -> None:
        self.stamps: list[np.ndarray] = []
        self.values: list[np.ndarray] = []

    def append(self, stamps: np.ndarray, values: np.ndarray) -> None:
        """Append samples whose stamps are later than every buffered one."""
        if len(stamps):
            self.stamps.append(stamps)
            self.values.append(values)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """All buffered samples as two arrays (concatenated once, then kept as one chunk)."""
        if len(self.stamps) > 1:
            self.stamps = [np.concatenate(self.stamps)]
            self.values = [np.concatenate(self.values)]
        if not self.stamps:
            return np.empty(0, np.int64), np.empty(0)
        return self.stamps[0], self.values[0]

    def take_before(self, end_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """Remove and return the samples with stamp < ``end_ns``."""
        s, v = self.arrays()
        i = int(np.searchsorted(s, end_ns, side="left"))
        self.stamps, self.values = ([s[i:]], [v[i:]]) if i < len(s) else ([], [])
        return s[:i], v[:i]

    def keep_from(self, index: int) -> None:
        """Forget the first ``index`` samples."""
        s, v = self.arrays()
        if index > 0:
            self.stamps, self.values = ([s[index:]], [v[index:]]) if index < len(s) else ([], [])

    def drop_between(self, lo_ns: int, hi_ns: int) -> int:
        """Forget the samples with ``lo_ns <= stamp < hi_ns``; return how many."""
        s, v = self.arrays()
        gone = (s >= lo_ns) & (s < hi_ns)
        n = int(np.count_nonzero(gone))
        if n:
            self.stamps, self.values = ([s[~gone]], [v[~gone]]) if n < len(s) else ([], [])
        return n

    def first_ns(self) -> int | None:
        """Earliest buffered stamp, or None."""
        return int(self.stamps[0][0]) if self.stamps else None

    def last_ns(self) -> int | None:
        """Latest buffered stamp, or None."""
        return int(self.stamps[-1][-1]) if self.stamps else None

    def state_dict(self) -> dict[str, np.ndarray]:
        """Plain-data state."""
        s, v = self.arrays()
        return {"stamps": s.copy(), "values": v.copy()}

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore the samples."""
        self.stamps, self.values = [], []
        self.append(np.asarray(state["stamps"], np.int64), np.asarray(state["values"], float))


@dataclass
class WindowBatch:
    """Closed windows that held force data, in window order.

    Attributes:
        k: (n,) int64, window index (window ``[k W, (k + 1) W)``).
        samples: (n, 2) int64, accepted force samples per channel.
        force_n: (n, 2) N, mean force per channel (NaN where a channel is empty).
        temp_c: (n, 2) C, mean matched air temperature per channel (NaN when unknown).
        reason: (n,) object, ``""`` (usable) or ``missing_topic`` / ``sparse_window`` /
            ``traffic``.
        cut: (n, 2) int64, samples per channel the traffic screen cut (``estimate.inputs.traffic``).
        temp_age_s: (n,) s, the largest distance from a force sample of the window to the air
            reading its matched temperature rests on (0 without a matched temperature); beyond
            ``temperature_stale_s`` the window's temperature is *stale* (``Shadow`` widens its
            compensation by what the air can do in that time).
        parked: per record screened into these windows that ended with vehicles parked on the
            bridge (``traffic.parked_start``): the window of the record's end, the stamp (ns)
            from which they were cut, the record's end (ns) and their load per channel (N: the
            median of the cut samples over the median of the last kept minute before them; NaN
            without a kept sample before them).

    """

    k: np.ndarray
    samples: np.ndarray
    force_n: np.ndarray
    temp_c: np.ndarray
    reason: np.ndarray
    cut: np.ndarray
    temp_age_s: np.ndarray
    parked: list[tuple[int, int, int, float, float]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.k)

    @classmethod
    def empty(cls) -> WindowBatch:
        """Return a batch without windows."""
        return cls(
            np.empty(0, np.int64),
            np.empty((0, 2), np.int64),
            np.empty((0, 2)),
            np.empty((0, 2)),
            np.empty(0, object),
            np.empty((0, 2), np.int64),
            np.empty(0),
        )

    def select(self, rows: np.ndarray) -> WindowBatch:
        """Return the windows at ``rows`` (a boolean mask or indices), with their records' parked."""
        k = self.k[rows]
        kept = set(k.tolist())
        return WindowBatch(
            k,
            self.samples[rows],
            self.force_n[rows],
            self.temp_c[rows],
            self.reason[rows],
            self.cut[rows],
            self.temp_age_s[rows],
            [p for p in self.parked if p[0] in kept],
        )

    @classmethod
    def concat(cls, batches: list[WindowBatch]) -> WindowBatch:
        """Return the windows of ``batches`` one after the other."""
        if not batches:
            return cls.empty()
        out = cls(*(np.concatenate([getattr(b, f) for b in batches]) for f in _FIELDS))
        out.parked = [p for b in batches for p in b.parked]
        return out


_FIELDS = ("k", "samples", "force_n", "temp_c", "reason", "cut", "temp_age_s")


class WindowBuffer:
    """Buffers accepted samples and closes due windows in batches.

    Attributes:
        w_ns: window length, ns.
        timeout_ns: ``topic_timeout_s`` in ns; horizon_ns: temperature horizon in ns.
        match: ``linear`` or ``hold``.
        min_samples: fewer accepted samples in a channel make the window ``sparse_window``.
        force: one ``SampleBuffer`` per channel; temp: the air-temperature readings.
        next_k: the first window not closed yet (None before the first force sample).
        temp_first_ns: stamp of the first temperature reading accepted (None: none yet). A window
            that cannot see it (it lies past the window's end plus the horizon) is uncompensated,
            however late the window closes (a record held for the traffic screen).
        gap_ns: a silence of both force channels this long ends a record (``gap_s``).
        hold_ns: records at most this long are held until they end and traffic-screened
            (``traffic_hold_s``; 0: no screen). record: where the current record stands.

    """

    def __init__(
        self,
        window_s: float,
        timeout_s: float,
        stale_s: float,
        match: str = "linear",
        min_samples: int = 1,
        gap_s: float = 600.0,
        hold_s: float = 0.0,
        traffic_threshold_n: float = 300.0,
        traffic_margin_s: float = 10.0,
        traffic_vehicle_max_n: float = float("inf"),
    ) -> None:
        ns = 1_000_000_000
        self.w_ns = round(window_s * ns)
        self.gap_ns = round(gap_s * ns)
        self.hold_ns = round(hold_s * ns)
        self.traffic_threshold_n = float(traffic_threshold_n)
        self.traffic_margin_s = float(traffic_margin_s)
        self.traffic_vehicle_max_n = float(traffic_vehicle_max_n)
        self.record = _Record()
        #: records that grew longer than the hold and passed unscreened: ``[first stamp, first + hold]``
        self.released: list[list[int]] = []
        self.timeout_ns = round(timeout_s * ns)
        self.horizon_ns = round(max(timeout_s, stale_s) * ns)
        self.match = match
        self.min_samples = int(min_samples)
        self.force = [SampleBuffer(), SampleBuffer()]
        self.temp = SampleBuffer()
        self.next_k: int | None = None
        self.temp_first_ns: int | None = None

    # -- input --------------------------------------------------------------------------------
    def add_forces(self, channel: int, stamps: np.ndarray, values: np.ndarray) -> int:
        """Buffer accepted force samples; return how many were ``late`` (window already closed)."""
        if not len(stamps):
            return 0
        if self.next_k is None:
            self.next_k = int(stamps[0]) // self.w_ns
        late = stamps < self.next_k * self.w_ns
        n_late = int(np.count_nonzero(late))
        if n_late:
            stamps, values = stamps[~late], values[~late]
        self.force[channel].append(stamps, values)
        return n_late

    def add_temperature(self, stamps: np.ndarray, values: np.ndarray) -> None:
        """Buffer accepted air-temperature readings."""
        if len(stamps):
            first = int(stamps[0])
            self.temp_first_ns = first if self.temp_first_ns is None else min(self.temp_first_ns, first)
            self.temp.append(stamps, values)

    @property
    def temp_seen(self) -> bool:
        """Whether any temperature reading was ever accepted."""
        return self.temp_first_ns is not None

    @property
    def holds_data(self) -> bool:
        """Whether forces are buffered in windows not closed yet."""
        return any(b.first_ns() is not None for b in self.force)

    # -- closing --------------------------------------------------------------------------------
    def due_end(self, clock_ns: int, force_last_ns: list[int | None]) -> int:
        """First window index that is not due on the data clock (windows before it are due)."""
        w = self.w_ns
        lasts = [s for s in force_last_ns if s is not None]
        k_past = min(lasts) // w if len(lasts) == len(force_last_ns) else -(2**62)
        k_forces = max(k_past, (clock_ns - self.timeout_ns) // w)
        t_last = self.temp.last_ns()
        k_temp = max(-(2**62) if t_last is None else t_last // w, (clock_ns - self.horizon_ns) // w)
        return min(k_forces, k_temp)

    def close_until(self, k_end: int, force_last_ns: list[int | None], final: bool = False) -> WindowBatch:
        """Close every window before ``k_end`` and aggregate those that held force data.

        With the traffic screen on, the windows of a record that has not ended and is not yet
        longer than the hold stay open; a record that ended is screened as its windows close.
        ``final``: the data ends here (``flush``).
        """
        if self.next_k is None or k_end <= self.next_k:
            return WindowBatch.empty()
        screened: list[tuple[int, int]] = []
        if self.hold_ns > 0:
            screened = self._scan(k_end * self.w_ns, final)
            if self.record.holding:
                k_end = min(k_end, self.record.start_ns // self.w_ns)
            if k_end <= self.next_k:
                return WindowBatch.empty()
        end_ns = k_end * self.w_ns
        taken = [b.take_before(end_ns) for b in self.force]
        cut: list[np.ndarray] = [np.empty(0, np.int64), np.empty(0, np.int64)]
        parked: list[tuple[int, int, int, float, float]] = []
        for start, last in screened:
            taken, cut = self._screen(taken, cut, start, last, parked)
        batch = self._aggregate(taken, cut)
        batch.parked = parked
        self.next_k = self._next_window(k_end, force_last_ns)
        self._prune_temperature(self.next_k * self.w_ns)
        first = self.temp_first_ns
        if first is not None and first != _SEEN and (self.next_k + 1) * self.w_ns + self.horizon_ns > first:
            # every window still to close sees a reading: when it came no longer matters (two front
            # ends that saw their first reading at different times behave alike from here)
            self.temp_first_ns = _SEEN
        return batch

    def flush(self, force_last_ns: list[int | None]) -> WindowBatch:
        """Close every window that holds data (the end of a record); later data will be late."""
        last = [b.last_ns() for b in self.force]
        if self.next_k is None or not any(s is not None for s in last):
            return WindowBatch.empty()
        k_end = max(s for s in last if s is not None) // self.w_ns + 1
        return self.close_until(k_end, force_last_ns, final=True)

    @property
    def held_since_ns(self) -> int | None:
        """First stamp of the record held for the traffic screen (None: nothing held)."""
        return self.record.start_ns if self.record.holding else None

    # -- the traffic screen ---------------------------------------------------------------------
    def _scan(self, end_ns: int, final: bool) -> list[tuple[int, int]]:
        """Follow the records through the force stamps before ``end_ns`` not scanned yet.

        Every window before ``end_ns`` is due, so every sample before it has arrived (a later one
        is late). Returns the records that ended and are to be screened, as ``(first, last)``
        stamps; a record that grew longer than the hold is released (``record.holding`` False).
        """
        rec = self.record
        parts = []
        for b in self.force if end_ns > rec.scan_ns else ():
            for st in reversed(b.stamps):  # the unscanned samples are in the last chunks
                if st[-1] < rec.scan_ns:
                    break
                if st[0] < end_ns:  # (a chunk of the windows not due yet holds none of them)
                    parts.append(st[(st >= rec.scan_ns) & (st < end_ns)])
        rec.scan_ns = max(rec.scan_ns, end_ns)
        new = np.sort(np.concatenate(parts)) if parts else np.empty(0, np.int64)
        ended: list[tuple[int, int]] = []
        if len(new):
            step = np.diff(new, prepend=new[0] if rec.last_ns is None else rec.last_ns)
            cuts = np.flatnonzero(step >= PIECE_SILENCE_NS).tolist()  # a gap's, or a piece's
            if not rec.open:
                cuts = [0, *[c for c in cuts if c > 0]]
            for i, seg in zip([-1, *cuts], np.split(new, cuts), strict=True):
                if not len(seg):
                    continue
                if i >= 0 and (not rec.holding or step[i] >= self.gap_ns):  # a new record starts at seg[0]
                    # after a silence of a piece, a released (long) record does not go on: the
                    # recording that starts is a record of its own, held and screened (a load-test
                    # record minutes after hours of ambient monitoring)
                    ended.extend(rec.end())
                    rec.begin(int(seg[0]))
                elif i >= 0:  # the record goes on after a silence: a recording that started again
                    rec.resume(int(seg[0]))
                start = rec.start_ns if rec.holding else None
                ended.extend(rec.extend(int(seg[-1]), self.hold_ns))
                if start is not None and rec.mode == 2:  # released: said (``released``), not screened
                    self.released.append([int(start), int(start) + self.hold_ns])  # when it passed the hold
        if rec.open and (final or end_ns - rec.last_ns >= self.gap_ns):
            ended.extend(rec.end())
        return ended

    def _screen(
        self,
        taken: list[tuple[np.ndarray, np.ndarray]],
        cut: list[np.ndarray],
        first: int,
        last: int,
        parked: list[tuple[int, int, int, float, float]],
    ) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[np.ndarray]]:
        """Cut the traffic of the record ``[first, last]`` (stamps) from the samples ``taken``.

        Vehicles parked at the record's end are appended to ``parked`` (``WindowBatch.parked``).
        """
        lo = [int(np.searchsorted(s, first, side="left")) for s, _ in taken]
        hi = [int(np.searchsorted(s, last, side="right")) for s, _ in taken]
        since: list[int] = []
        keeps = screen_record(
            [s[a:b] for (s, _), a, b in zip(taken, lo, hi, strict=True)],
            [v[a:b] for (_, v), a, b in zip(taken, lo, hi, strict=True)],
            self.traffic_threshold_n,
            self.traffic_margin_s,
            self.traffic_vehicle_max_n,
            since,
        )
        for t in since:
            loads = []
            for (s, v), a, b, keep in zip(taken, lo, hi, keeps, strict=True):
                rs, rv = s[a:b], v[a:b]
                on, ahead = rs >= t, keep & (rs < t)
                if on.any() and ahead.any():  # the last kept minute before them
                    ahead &= rs >= rs[ahead][-1] - 60 * 10**9
                    loads.append(float(np.median(rv[on]) - np.median(rv[ahead])))
                else:
                    loads.append(float("nan"))
            parked.append((int(last) // self.w_ns, int(t), int(last), loads[0], loads[1]))
        out, gone = [], []
        for (s, v), a, b, keep, c in zip(taken, lo, hi, keeps, cut, strict=True):
            mask = np.ones(len(s), bool)
            mask[a:b] = keep
            out.append((s[mask], v[mask]))
            gone.append(np.concatenate([c, s[~mask]]))
        return out, gone

    def _next_window(self, k: int, force_last_ns: list[int | None]) -> int:
        """Skip windows that can never receive data (empty buffers, every channel past them)."""
        firsts = [b.first_ns() for b in self.force]
        if any(f is not None for f in firsts):
            return max(k, min(f for f in firsts if f is not None) // self.w_ns)
        lasts = [s for s in force_last_ns if s is not None]
        return max(k, min(lasts) // self.w_ns) if lasts else k

    def _prune_temperature(self, end_ns: int) -> None:
        """Keep the last reading at or before ``end_ns`` (a left bracket) and everything later."""
        ts, _ = self.temp.arrays()
        self.temp.keep_from(int(np.searchsorted(ts, end_ns, side="right")) - 1)

    def _aggregate(self, taken: list[tuple[np.ndarray, np.ndarray]], cut: list[np.ndarray]) -> WindowBatch:
        if not (len(cut[0]) or len(cut[1])):
            one = self._one_window(taken)
            if one is not None:
                return one
        w = self.w_ns
        ks = [window_index(s, w) for s, _ in taken]
        k_cut = [window_index(c, w) for c in cut]
        k_all = sorted_union([*ks, *k_cut])
        n = len(k_all)
        if not n:
            return WindowBatch.empty()
        n_cut = np.zeros((n, 2), np.int64)
        for c, k in enumerate(k_cut):
            if len(k):  # only a screened record has cut samples
                n_cut[:, c] = np.bincount(np.searchsorted(k_all, k), minlength=n)
        samples = np.zeros((n, 2), np.int64)
        force = np.full((n, 2), np.nan)
        temp = np.full((n, 2), np.nan)
        age = np.zeros(n)
        ts, tv = self.temp.arrays()
        for c, ((stamps, values), k) in enumerate(zip(taken, ks, strict=True)):
            if not len(stamps):
                continue
            row = np.searchsorted(k_all, k)
            forces = window_stats(row, values, n)
            has = forces.count > 0
            samples[:, c] = forces.count
            force[has, c] = forces.mean[has]
            if self.temp_first_ns is None:
                continue
            matched, dist = self._match(stamps, k, ts, tv)
            blind = (k + 1) * w + self.horizon_ns <= self.temp_first_ns  # no reading visible yet
            matched[blind], dist[blind] = np.nan, 0.0
            temp[has, c] = window_stats(row, matched, n).mean[has]
            np.maximum.at(age, row, dist / 1e9)
        sparse = np.any(samples < self.min_samples, axis=1)
        reason = np.full(n, "", dtype=object)
        reason[sparse] = "sparse_window"
        reason[np.any(samples == 0, axis=1)] = "missing_topic"
        reason[sparse & np.any(n_cut > 0, axis=1)] = "traffic"
        return WindowBatch(k_all.astype(np.int64), samples, force, temp, reason, n_cut, age)

    def _one_window(self, taken: list[tuple[np.ndarray, np.ndarray]]) -> WindowBatch | None:
        """``_aggregate`` of samples that all fall in one window, both channels there (else None).

        A live node closes one window at a time: the same sums in the same order as the general
        path (``window_stats``' ``bincount``), without its grouping.
        """
        s0, s1 = taken[0][0], taken[1][0]
        if not (len(s0) and len(s1)):
            return None
        w = self.w_ns
        k = int(s0[0]) // w
        if int(s0[-1]) // w != k or int(s1[0]) // w != k or int(s1[-1]) // w != k:
            return None
        force, temp = [math.nan, math.nan], [math.nan, math.nan]
        age = 0.0
        ts, tv = self.temp.arrays()
        # no reading at all, or none visible yet: the temperature stays NaN and the age 0
        first = self.temp_first_ns
        matching = first is not None and (k + 1) * w + self.horizon_ns > first
        # a logger that samples both load cells at once stamps them alike: one match serves both
        same_stamps = matching and len(s0) == len(s1) and bool((s0 == s1).all())
        rows = np.zeros(len(s0), dtype=np.intp)
        for c, (stamps, values) in enumerate(taken):
            if len(rows) != len(values):
                rows = np.zeros(len(values), dtype=np.intp)
            force[c] = float(np.bincount(rows, values, minlength=1)[0]) / len(values)
            if not matching:
                continue
            if c == 0 or not same_stamps:
                matched, dist = self._match_one(stamps, k, ts, tv)
            temp[c] = float(np.bincount(rows, matched, minlength=1)[0]) / len(values)
            age = max(age, float(dist.max()) / 1e9)
        sparse = min(len(s0), len(s1)) < self.min_samples
        return WindowBatch(
            np.array([k], dtype=np.int64),
            np.array([[len(s0), len(s1)]], dtype=np.int64),
            np.array([force]),
            np.array([temp]),
            np.array(["sparse_window" if sparse else ""], dtype=object),
            np.zeros((1, 2), np.int64),
            np.array([age]),
        )

    def _match_one(
        self, t: np.ndarray, k: int, ts: np.ndarray, tv: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``_match`` of one window's stamps ``t`` (in stamp order), each between two visible readings.

        The live case (``linear``): every stamp has a reading at or before it and one after it,
        visible to window ``k``, so ``_match``'s masks are all true and its selections the plain
        arrays: the same operations on the same numbers, a third of the numpy calls. Otherwise
        ``_match``.
        """
        if self.match != "linear" or not len(ts):
            return self._match(t, np.int64(k), ts, tv)
        right = np.searchsorted(ts, t, side="right")
        limit = int(np.searchsorted(ts, (k + 1) * self.w_ns + self.horizon_ns, side="left"))
        if int(right[0]) < 1 or int(right[-1]) >= limit:  # (stamps in order: the first and last bound all)
            return self._match(t, np.int64(k), ts, tv)
        left = right - 1
        t_left, t_right = ts[left], ts[right]
        d_left, d_right = t - t_left, t_right - t
        v_left = tv[left]
        frac = d_left.astype(float) / (t_right - t_left).astype(float)
        return v_left + frac * (tv[right] - v_left), np.minimum(d_left, d_right).astype(float)

    def _match(
        self, t: np.ndarray, k: np.ndarray, ts: np.ndarray, tv: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Temperature at force stamps ``t`` of windows ``k``: ((n,) C, (n,) ns to the reading it rests on).

        Readings at or past ``(k + 1) W + horizon`` are invisible to window ``k``.
        """
        if not len(ts):
            return np.full(len(t), np.nan), np.zeros(len(t))
        right = np.searchsorted(ts, t, side="right")
        left = right - 1
        limit = np.searchsorted(ts, (k + 1) * self.w_ns + self.horizon_ns, side="left")
        has_l = left >= 0
        has_r = right < limit
        li = np.maximum(left, 0)  # right lies in [0, len(ts)]: left is below the end, right above -1
        ri = np.minimum(right, len(ts) - 1)
        d_left = np.where(has_l, t - ts[li], _NEVER)
        if self.match == "hold":
            temp = np.where(has_l, tv[li], tv[0])
            return temp, np.where(has_l, d_left, ts[0] - t).astype(float)
        d_right = np.where(has_r, ts[ri] - t, _NEVER)
        both = has_l & has_r
        span = np.where(both, ts[ri] - ts[li], 1).astype(float)
        frac = np.where(both, d_left, 0).astype(float) / span
        temp = np.where(has_l, tv[li], tv[ri]) + np.where(both, frac * (tv[ri] - tv[li]), 0.0)
        return temp, np.minimum(d_left, d_right).astype(float)

    # -- state ----------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        return {
            "force": [b.state_dict() for b in self.force],
            "temp": self.temp.state_dict(),
            "next_k": _NONE if self.next_k is None else self.next_k,
            "temp_first_ns": _NONE if self.temp_first_ns is None else self.temp_first_ns,
            "record": self.record.state_dict(),
            "released": [list(r) for r in self.released],
        }

    def behaviour_state(
        self, state: dict[str, object], force_floor_ns: list[int | None] | None = None
    ) -> dict[str, object]:
        """``state`` (a ``state_dict()`` of a buffer of these parameters) less what no later window reads.

        Two buffers whose behaviour states are equal close equal windows from equal messages.
        Beyond ``released`` (bookkeeping) that is, as a window's close forgets them (a buffer
        that has closed no window yet, a record held for the traffic screen, still holds them):

        - the air readings before the last one at or before every force stamp still to be matched
          (``_match`` rests a stamp on the last reading at or before it and the first after it);
        - when the first reading came, once every window such a stamp can fall in sees it (``_SEEN``).

        Force stamps still to be matched lie at or after the first open window's start (earlier
        ones are ``late``), and per channel at or after its first buffered stamp, or, with nothing
        buffered, at or after ``force_floor_ns`` (None: not known; a gate accepts only stamps after
        its last accepted one).
        """
        out = {k: v for k, v in state.items() if k != "released"}
        k = int(state["next_k"])  # type: ignore[call-overload]
        if k == _NONE:
            return out
        floors = list(force_floor_ns) if force_floor_ns is not None else [None] * len(self.force)
        for c, fs in enumerate(state["force"]):  # type: ignore[attr-defined]
            stamps = np.asarray(fs["stamps"], np.int64)
            if len(stamps):
                floors[c] = int(stamps[0])
        low = k * self.w_ns
        if all(f is not None for f in floors):
            low = max(low, min(floors))  # type: ignore[type-var]
        temp = state["temp"]
        ts = np.asarray(temp["stamps"], np.int64)  # type: ignore[index]
        i = int(np.searchsorted(ts, low, side="right")) - 1
        if i > 0:
            out["temp"] = {"stamps": ts[i:], "values": np.asarray(temp["values"])[i:]}  # type: ignore[index]
        first = int(state["temp_first_ns"])  # type: ignore[call-overload]
        if first not in (_NONE, _SEEN) and (low // self.w_ns + 1) * self.w_ns + self.horizon_ns > first:
            out["temp_first_ns"] = _SEEN
        return out

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the state."""
        for b, s in zip(self.force, state["force"], strict=True):  # type: ignore[call-overload]
            b.load_state_dict(s)
        self.temp.load_state_dict(state["temp"])  # type: ignore[arg-type]
        k = int(state["next_k"])  # type: ignore[call-overload]
        self.next_k = None if k == _NONE else k
        first = int(state["temp_first_ns"])  # type: ignore[call-overload]
        self.temp_first_ns = None if first == _NONE else first
        self.record = _Record.from_state_dict(state["record"])  # type: ignore[arg-type]
        # (a checkpoint written before releases were kept has none)
        self.released = [[int(a), int(b)] for a, b in state.get("released", [])]  # type: ignore[union-attr]
