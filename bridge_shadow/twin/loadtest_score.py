"""Score a shadow's replay of a load-test day against its truth (for tests and benchmarks).

``score_day``: a twin load-test day (``twin.loadtest``); ``score_stream``: a stream built from
the real records (``twin.real_records``).

The criteria of issue 19 for one seed: every step found as an event at the right record (the first
record with data after the change), no car-free window of a new state rejected, the final estimate
within 10 % of the truth, and whether the 95 % interval holds it (a rate over seeds).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from bridge_shadow.estimate.result import ReplayResult

__all__ = ["DayScore", "StreamScore", "car_excursions", "score_day", "score_stream"]


@dataclass(frozen=True)
class DayScore:
    """One seed's result.

    Attributes:
        events_right: one event per change, each inside the record where the new state begins.
        lost_windows: car-free windows of a new state rejected as outliers.
        within_10pct: the final estimate within 10 % of the true final settlement (per support).
        covered: the final 95 % interval holds the truth on both supports.
        error_m: (2,) final estimate minus truth, m; sigma_m: (2,) its published sd, m.

    """

    events_right: bool
    lost_windows: int
    within_10pct: bool
    covered: bool
    error_m: np.ndarray
    sigma_m: np.ndarray

    @property
    def passed(self) -> bool:
        """The per-seed criteria (coverage is a rate over seeds)."""
        return self.events_right and not self.lost_windows and self.within_10pct


def score_day(res: ReplayResult, truth: dict[str, Any], window_s: float = 60.0) -> DayScore:
    """Score ``res`` (a replay of ``load_test_day``'s stream) against its ``truth``."""
    w = round(window_s * 1e9)
    starts, ends = truth["record_start_ns"], truth["record_end_ns"]
    x = np.asarray(truth["record_x_m"], float)
    used = [o.end_ns for o in res.outputs if o.updated]
    with_data = [i for i in range(len(starts)) if any(starts[i] < t <= ends[i] + w for t in used)]
    if "step_ns" in truth:  # steps inside records (``scheduled_day``): each event from its step to the
        # end of the record that holds the first used window after it (a dropout may hide the step)
        changes = []
        for t in truth["step_ns"]:
            first = min((u for u in used if u > t), default=None)
            rec = [i for i in with_data if first is not None and starts[i] < first <= ends[i] + w]
            if rec:
                changes.append((t, ends[rec[0]]))
    else:
        changes = [(starts[b], ends[b]) for a, b in pairwise(with_data) if np.any(np.abs(x[b] - x[a]) > 1e-9)]
    found = sorted(e.time_ns for e in res.events)
    events_right = len(found) == len(changes) and all(
        a - w < t < b for t, (a, b) in zip(found, changes, strict=True)
    )
    car = truth["stops"]

    def car_on(end_ns: int) -> bool:
        return any(t0 < end_ns and t1 > end_ns - w for t0, t1, _, _ in car)

    first_change = changes[0][0] if changes else 2**62
    lost = sum(
        1 for o in res.outputs if o.reason == "outlier" and o.end_ns > first_change and not car_on(o.end_ns)
    )
    end = x[with_data[-1]] if with_data else x[-1]
    err = res.mean_m - end
    sd = np.sqrt(np.diag(res.covariance_m2))
    return DayScore(
        events_right,
        lost,
        bool(np.all(np.abs(err) <= 0.1 * np.abs(end))),
        bool(np.all(np.abs(err) <= 1.96 * sd)),
        err,
        sd,
    )


@dataclass(frozen=True)
class StreamScore:
    """One real-record stream's result (``twin.real_records.Scenario``).

    Attributes:
        events_right: the events are exactly one at each changed record, at its first window the
            shadow used (a record's first minutes can be screened out: the test car, a window too
            sparse to use).
        spurious: event windows where no record's state changed.
        unreported: changed records with neither an event nor a likely unconfirmed change.
        lost_windows: windows of a changed record rejected as outliers.
        within: the final estimate within 10 % of the truth, or 1 mm (per support).
        covered: the final 95 % interval holds the truth (per support).
        error_m: (2,) final estimate minus truth, m; sigma_m: (2,) its published sd, m.
        missed: changed records (their first used window) without an event there, whether or not
            an unconfirmed change reports them.
        lost_under_car: those of ``lost_windows`` that are the recorded test car parked on the state
            the shadow then held (``_car_excursion``): an excursion rejected, no state lost.

    """

    events_right: bool
    spurious: list[int]
    unreported: list[int]
    lost_windows: int
    within: bool
    covered: bool
    error_m: np.ndarray
    sigma_m: np.ndarray
    missed: list[int] = field(default_factory=list)
    lost_under_car: int = 0

    @property
    def lost_car_free(self) -> int:
        """Windows of a changed record rejected as outliers that were no car on a state then held."""
        return self.lost_windows - self.lost_under_car


def car_excursions(sc: Any, res: ReplayResult, ends_ns: list[int], w: int) -> int:
    """Return how many of the windows ending at ``ends_ns`` are the recorded test car on a state then held.

    ``_car_excursion`` of each, against the windows ``res`` used (``w`` the window length, ns).
    """
    used_ends = sorted(o.end_ns for o in res.outputs if not o.reason)
    return sum(1 for t in ends_ns if _car_excursion(sc, t, w, used_ends))


def _car_excursion(sc: Any, end_ns: int, w: int, used_ends: list[int]) -> bool:
    """Whether the window ending at ``end_ns`` is the test car parked on the state the shadow then held.

    The recorded car stood in the window (``sc.car_ns``), the window lies in pieces of one true
    state (no change inside it; a record cut into slices, as ``lowered_over`` cuts one, is one
    piece where its slices' states are the same), and the next window the shadow used is in a
    piece of that state: the rejected window was an excursion, not a state of its own.
    """
    if not any(a < end_ns and b > end_ns - w for a, b in sc.car_ns):
        return False
    piece = bisect.bisect_right(sc.starts_ns, end_ns - w) - 1
    last = bisect.bisect_right(sc.starts_ns, end_ns - 1) - 1
    if piece < 0 or any(not _same_state(sc, piece, p) for p in range(piece + 1, last + 1)):
        return False
    after = bisect.bisect_right(used_ends, end_ns)
    if after == len(used_ends):
        return False
    held = bisect.bisect_right(sc.starts_ns, used_ends[after] - w) - 1
    return _same_state(sc, held, piece)


def _same_state(sc: Any, a: int, b: int) -> bool:
    """Whether pieces ``a`` and ``b`` of the scenario have the same true state."""
    return bool(np.allclose(sc.pieces[a].truth_m(), sc.pieces[b].truth_m(), rtol=0.0, atol=1e-9))


def score_stream(sc: Any, res: ReplayResult, window_s: float = 60.0) -> StreamScore:
    """Score ``res`` (a replay of ``sc.data``) against the scenario's truth (scoring only)."""
    w = round(window_s * 1e9)
    used = sorted(o.end_ns // w - 1 for o in res.outputs if not o.reason)
    bounds_k = [t // w for t in sc.starts_ns] + [2**62]

    def first_used(i: int) -> int:
        """Return the record's first window that the shadow used (its first window if none was)."""
        k = [u for u in used if bounds_k[i] <= u < bounds_k[i + 1]]
        return k[0] if k else bounds_k[i]

    want = [first_used(i) for i in sc.changes()]
    events = [e.window for e in res.events]
    likely = {c.window for c in res.changes if c.likely}
    bounds = [*sc.starts_ns, 2**62]
    changed = [(bounds[i], bounds[i + 1]) for i in sc.changes()]
    outliers = [o.end_ns for o in res.outputs if o.reason == "outlier"]
    lost_ends = [t for t in outliers if any(a <= t < b + w for a, b in changed)]
    under_car = car_excursions(sc, res, lost_ends, w)
    truth = np.asarray(sc.truth_m, float)
    err = res.mean_m - truth
    sd = np.sqrt(np.diag(res.covariance_m2))
    return StreamScore(
        events == want,
        sorted(set(events) - set(want)),
        sorted(set(want) - set(events) - likely),
        len(lost_ends),
        bool(np.all(np.abs(err) <= np.maximum(0.1 * np.abs(truth), 1e-3))),
        bool(np.all(np.abs(err) <= 1.96 * sd)),
        err,
        sd,
        sorted(set(want) - set(events)),
        under_car,
    )
