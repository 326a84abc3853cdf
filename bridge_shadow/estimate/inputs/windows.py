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
``temperature_stale_s`` away. Window ``k`` only sees readings stamped before its end plus the
horizon, so a window's result does not depend on how much later data had been ingested when it
closed (chunking). While no temperature reading has ever been accepted, windows are not stale but
*uncompensated* (temperature NaN): a record without a temperature topic still estimates, loudly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bridge_shadow.windowing import window_index, window_stats

__all__ = ["SampleBuffer", "WindowBatch", "WindowBuffer"]

_NEVER = np.iinfo(np.int64).max


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
            ``stale_temperature``.

    """

    k: np.ndarray
    samples: np.ndarray
    force_n: np.ndarray
    temp_c: np.ndarray
    reason: np.ndarray

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
        )


class WindowBuffer:
    """Buffers accepted samples and closes due windows in batches.

    Attributes:
        w_ns: window length, ns.
        timeout_ns: ``topic_timeout_s`` in ns; horizon_ns: temperature horizon in ns.
        stale_ns: largest distance to the reading a matched temperature relies on, ns.
        match: ``linear`` or ``hold``.
        min_samples: fewer accepted samples in a channel make the window ``sparse_window``.
        force: one ``SampleBuffer`` per channel; temp: the air-temperature readings.
        next_k: the first window not closed yet (None before the first force sample).
        temp_seen: whether any temperature reading was ever accepted.

    """

    def __init__(
        self,
        window_s: float,
        timeout_s: float,
        stale_s: float,
        match: str = "linear",
        min_samples: int = 1,
    ) -> None:
        ns = 1_000_000_000
        self.w_ns = round(window_s * ns)
        self.timeout_ns = round(timeout_s * ns)
        self.stale_ns = round(stale_s * ns)
        self.horizon_ns = round(max(timeout_s, stale_s) * ns)
        self.match = match
        self.min_samples = int(min_samples)
        self.force = [SampleBuffer(), SampleBuffer()]
        self.temp = SampleBuffer()
        self.next_k: int | None = None
        self.temp_seen = False

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
            self.temp_seen = True
            self.temp.append(stamps, values)

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

    def close_until(self, k_end: int, force_last_ns: list[int | None]) -> WindowBatch:
        """Close every window before ``k_end`` and aggregate those that held force data."""
        if self.next_k is None or k_end <= self.next_k:
            return WindowBatch.empty()
        end_ns = k_end * self.w_ns
        taken = [b.take_before(end_ns) for b in self.force]
        batch = self._aggregate(taken)
        self.next_k = self._next_window(k_end, force_last_ns)
        self._prune_temperature(self.next_k * self.w_ns)
        return batch

    def flush(self, force_last_ns: list[int | None]) -> WindowBatch:
        """Close every window that holds data (the end of a record); later data will be late."""
        last = [b.last_ns() for b in self.force]
        if self.next_k is None or not any(s is not None for s in last):
            return WindowBatch.empty()
        k_end = max(s for s in last if s is not None) // self.w_ns + 1
        return self.close_until(k_end, force_last_ns)

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

    def _aggregate(self, taken: list[tuple[np.ndarray, np.ndarray]]) -> WindowBatch:
        w = self.w_ns
        ks = [window_index(s, w) for s, _ in taken]
        present = [np.unique(k) for k in ks]
        k_all = np.union1d(present[0], present[1])
        n = len(k_all)
        if not n:
            return WindowBatch.empty()
        samples = np.zeros((n, 2), np.int64)
        force = np.full((n, 2), np.nan)
        temp = np.full((n, 2), np.nan)
        stale = np.zeros(n, bool)
        ts, tv = self.temp.arrays()
        for c, ((stamps, values), k) in enumerate(zip(taken, ks, strict=True)):
            if not len(stamps):
                continue
            row = np.searchsorted(k_all, k)
            forces = window_stats(row, values, n)
            has = forces.count > 0
            samples[:, c] = forces.count
            force[has, c] = forces.mean[has]
            if not self.temp_seen:
                continue
            matched, flag = self._match(stamps, k, ts, tv)
            temp[has, c] = window_stats(row, matched, n).mean[has]
            stale |= np.bincount(row, weights=flag, minlength=n) > 0
        reason = np.full(n, "", dtype=object)
        reason[stale] = "stale_temperature"
        reason[np.any(samples < self.min_samples, axis=1)] = "sparse_window"
        reason[np.any(samples == 0, axis=1)] = "missing_topic"
        return WindowBatch(k_all.astype(np.int64), samples, force, temp, reason)

    def _match(
        self, t: np.ndarray, k: np.ndarray, ts: np.ndarray, tv: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Temperature at force stamps ``t`` of windows ``k``: ((n,) C, (n,) stale flag as float).

        Readings at or past ``(k + 1) W + horizon`` are invisible to window ``k``.
        """
        if not len(ts):
            return np.full(len(t), np.nan), np.ones(len(t))
        right = np.searchsorted(ts, t, side="right")
        left = right - 1
        limit = np.searchsorted(ts, (k + 1) * self.w_ns + self.horizon_ns, side="left")
        has_l = left >= 0
        has_r = right < limit
        li = np.clip(left, 0, len(ts) - 1)
        ri = np.clip(right, 0, len(ts) - 1)
        d_left = np.where(has_l, t - ts[li], _NEVER)
        if self.match == "hold":
            temp = np.where(has_l, tv[li], tv[0])
            return temp, (d_left > self.stale_ns).astype(float)
        d_right = np.where(has_r, ts[ri] - t, _NEVER)
        both = has_l & has_r
        span = np.where(both, ts[ri] - ts[li], 1).astype(float)
        frac = np.where(both, d_left, 0).astype(float) / span
        temp = np.where(has_l, tv[li], tv[ri]) + np.where(both, frac * (tv[ri] - tv[li]), 0.0)
        return temp, (np.minimum(d_left, d_right) > self.stale_ns).astype(float)

    # -- state ----------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        return {
            "force": [b.state_dict() for b in self.force],
            "temp": self.temp.state_dict(),
            "next_k": -(2**62) if self.next_k is None else self.next_k,
            "temp_seen": self.temp_seen,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the state."""
        for b, s in zip(self.force, state["force"], strict=True):  # type: ignore[call-overload]
            b.load_state_dict(s)
        self.temp.load_state_dict(state["temp"])  # type: ignore[arg-type]
        k = int(state["next_k"])  # type: ignore[call-overload]
        self.next_k = None if k == -(2**62) else k
        self.temp_seen = bool(state["temp_seen"])
