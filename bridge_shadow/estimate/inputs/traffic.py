"""The traffic screen of a short record: cut the excursions of a vehicle that come back.

On a load-test day every record holds car-free minutes at its start and end and a test car
parked for minutes in between (+3 to +11 kN per bearing on the 2022-04-11 records). Taken as
data, those plateaus are read as strongly correlated noise (an AR(1) of phi ~0.99), the
provisional segment after a gap gets an sd of ~3.5 mm instead of ~0.24 mm, and a real
settlement stays an unconfirmed change (issue 19). The window buffer therefore holds a record
until it ends (a silence of ``gap_s`` in both force channels, or the end of the data) and, when
it is at most ``traffic_hold_s`` long, screens it here before its windows close:

1. 1 s bins from the record's first stamp, the mean force of each channel per bin; the bins
   holding both channels carry the sum (a record sampled every few seconds leaves the rest empty);
2. the calibration's car rule (``bridge_shadow.traffic.flag_car``) on that sum, its first
   baseline from the lowest fifth of each half of the record (a drift of ~1 kN through a record
   must not put the whole start at one end), no bin of it more than the threshold above its
   half's lowest, and only quiet bins (``first_free``, ``quiet``: a burst of sensor noise is no
   car-free level);
3. a flagged run is *traffic* when it lies above the baseline (a vehicle only adds load) and
   comes back inside the record: it touches neither the first nor the last bin with data. A run
   that does not come back is a change of state and stays data; so does one below the baseline.
   A run whose vehicle-heavy part ends before the record does, the bins after it no further off
   the straight baseline than a record's drift, came back (``_fell_back``). A run that touches
   the record's end is looked at again: the record is split where its
   car-free level drops (a settlement inside the record), or rises by more than the heaviest
   vehicle (``traffic_vehicle_max_n``: a support raised inside it), and each side is screened
   against its own baseline (``split_bin``);
4. a load that arrived as a vehicle does and stayed to the record's end, no heavier than the
   heaviest vehicle, is a vehicle *parked at the end* (``parked_start``): cut from its arrival on
   and reported (``screen_record``'s ``parked``), since the record cannot show it leave; the
   screen cannot tell it from a raise of the support at that moment, which the report names;
5. so, in time reversed, is a load on the bridge when the record began that rolled off as a
   vehicle does: cut up to its departure (the minutes of the state before a lowering that
   happened so, were it one: the state after it keeps every window).

A record whose recording stopped and started again inside it (a silence of ``PIECE_SILENCE_NS``)
is screened in pieces where the car-free level changes across a silence, and as one stretch with
the silence's bins empty where it does not (``_state_bounds``); a vehicle on the bridge at both
sides of a silence with a change is cut on both (``_screen_states``).

The samples of the traffic bins are cut; the windows are built from the rest (a window left
with fewer than ``window_min_samples`` is rejected as ``traffic``). A record longer than the hold
limit is released unscreened (continuous monitoring: the detector's transients handle it); a
recording that starts again after a silence of ``PIECE_SILENCE_NS`` or more is a record of its
own, held and screened, also after a released one (2022-04-11's load records followed its
three-hour ambient and lowering records after silences of 3 minutes).
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from bridge_shadow.traffic import flag_car, runs
from bridge_shadow.windowing import sorted_union, window_stats

__all__ = [
    "BIN_NS",
    "MAX_SPLITS",
    "MIN_SIDE_BINS",
    "PIECE_SILENCE_NS",
    "first_free",
    "parked_start",
    "screen_record",
    "split_bin",
    "support_start",
]

#: Bin width of the screen, ns: the calibration's 1 s bins (a car crossing takes seconds).
BIN_NS = 1_000_000_000
#: A silence of both channels this long may split a record into pieces screened one by one, ns: a
#: minute without a sample of a 100 Hz (or 1 Hz) recording is a recording that stopped, not a
#: dropout. The pieces stay apart where the car-free level changes across the silence
#: (``_state_bounds``; a car parked across such a silence is cut on both sides, ``_screen_states``);
#: a pause without a change is one stretch, so that a car parked across it comes back on its far
#: side and is cut.
PIECE_SILENCE_NS = 60 * BIN_NS
#: A state change inside a record is looked for only with a minute on either side of it (a shorter
#: state has no window of its own: the detector reads it), and at most this many times per piece.
MIN_SIDE_BINS = 60
MAX_SPLITS = 3
#: A vehicle parked at a record's end drove on: its load rose over at least this many 1 s bins from
#: 10 to 90 % of it (``parked_start``). A step (a support that slipped, or a step added to a record)
#: falls inside one bin and shows in at most two, the one it fell in holding part of it: from the
#: first bin at 10 % to the first at 90 % it takes at most one bin, so two tell a vehicle from it.
#: A car that comes to a stop on the bridge rolls onto it over seconds (the test car on
#: 2022-04-11's reference record, 10 to 90 % of its 10.7 kN: 7 s), and one driving off leaves
#: faster (the second test car leaving that record at minute 8: 3 s, two bins by this count). It
#: was 3 until 2026-11-29, a bin of margin the derivation does not ask for; 2 was chosen after
#: that departure, read as no vehicle, left the car in 7 of 122 streams beginning under it.
PARKED_RISE_BINS = 2
#: How far, in ``threshold_n``, the load that arrived may exceed the load still there at the
#: record's end, or fall short of half of it (``parked_start``): the car-free level drifts by up
#: to about 1 kN through a record (``first_free``), 3 x 300 N, while a vehicle that left on top of
#: a change (a car gone, a state raised by about its load) takes at least the lightest parked
#: plateau, 3 kN, ten thresholds. The shortfall: the second of two vehicles of one load (the
#: reference record's two test cars, 10.3 kN each) carries half of the load at the end, which a
#: drift of tens of newtons put just below or above ``top / 2``.
PARKED_DRIFT_THRESHOLDS = 3.0
#: The lightest load, in ``threshold_n``, taken as vehicles parked at a record's end: ten, the
#: lightest parked plateau of the test car (3 kN; ``traffic_threshold_n`` is a tenth of it). A
#: record's car-free level drifts by up to 1-2 kN through it (the sun on the deck, a warming
#: morning), and a lighter rise that stays is that drift as often as a vehicle: data, as before.
PARKED_MIN_THRESHOLDS = 10.0


def screen_record(
    stamps: list[np.ndarray],
    values: list[np.ndarray],
    threshold_n: float,
    margin_s: float,
    vehicle_max_n: float,
    parked: list[int] | None = None,
) -> list[np.ndarray]:
    """Screen the samples of one record (per channel, sorted stamps in ns and forces in N).

    Returns, per channel, a (n_c,) bool mask over the record's samples: True where kept. Where
    both channels fall silent for ``PIECE_SILENCE_NS`` inside the record (two recordings minutes
    apart, shorter than ``gap_s``) and the car-free level changes across the silence, each piece is
    screened on its own: a settlement between them would otherwise tilt the baseline under both,
    and neither car would be cut. Pieces on one level are screened together (``_state_bounds``).
    ``parked``: where given, the stamp (ns) of the first bin cut as vehicles parked at the
    record's end (``parked_start``) is appended to it.
    """
    if any(not len(s) for s in stamps):
        return [np.ones(len(s), bool) for s in stamps]
    both = sorted_union(stamps)
    cuts = both[1:][np.diff(both) >= PIECE_SILENCE_NS]
    bounds = [int(both[0]), int(both[-1]) + 1]
    if len(cuts):
        bounds = _state_bounds(
            stamps, values, [bounds[0], *map(int, cuts), bounds[1]], threshold_n, vehicle_max_n
        )
    if len(bounds) > 2:
        return _screen_states(stamps, values, bounds, (threshold_n, margin_s, vehicle_max_n), parked)
    idx, total = _bin_total(stamps, values)
    done = _screen_bins(total, threshold_n, round(margin_s * 1e9 / BIN_NS), vehicle_max_n)
    if parked is not None and done.parked >= 0:
        parked.append(int(bounds[0]) + done.parked * BIN_NS)
    return [~done.cut[i] for i in idx]


def _screen_states(
    stamps: list[np.ndarray],
    values: list[np.ndarray],
    bounds: list[int],
    rule: tuple[float, float, float],
    parked: list[int] | None = None,
) -> list[np.ndarray]:
    """Screen the pieces of a record whose car-free level changes across silences (``_state_bounds``).

    ``rule``: ``threshold_n``, ``margin_s``, ``vehicle_max_n`` of ``screen_record``. Each piece is
    screened against its own baseline, as a record of its own (a run touching a silence does not
    come back), except where a vehicle stood across a silence: the piece before ends with a run
    above its baseline at the silence and the piece after begins with one above its own, neither
    heavier than any vehicle (``vehicle_max_n``; ``_Screened.tail_n`` / ``head_n``), i.e. a test
    car parked while the logger paused and the state changed, arriving before the silence and
    leaving after it. There the silence is a split, not an end of the record (``_screen_bins``'
    split of a state change inside a record, at a place the recording gives), and both halves of
    the car are cut. A run at one side only stays data: with nothing on the bridge at the other
    side it is what a further state looks like too (the rule of ``_holds_a_further_state``).
    Screened as records of their own, both halves of such a car stayed data and the change was
    read as two events of 87 % and 13 % of it (the pause study of ``benchmarks/loadtest_days.py``);
    cutting a run at one side too cut the drifting end of a record before a silence and lost
    windows of the state after it.
    """
    threshold_n, margin_s, vehicle_max_n = rule
    margin = round(margin_s * 1e9 / BIN_NS)
    sels, bins = [], []
    for a, b in itertools.pairwise(bounds):
        sel = [(s >= a) & (s < b) for s in stamps]
        part = [s[m] for s, m in zip(stamps, sel, strict=True)]
        vals = [v[m] for v, m in zip(values, sel, strict=True)]
        sels.append(sel)
        bins.append(_bin_total(part, vals) if all(map(len, part)) else None)

    def screened(i: int, ends: tuple[bool, bool]) -> _Screened | None:
        piece = bins[i]
        return (
            None if piece is None else _screen_bins(piece[1], threshold_n, margin, vehicle_max_n, ends=ends)
        )

    # the loads at the silences, each piece screened with its silences as splits
    inner = [screened(i, (i == 0, i == len(bins) - 1)) for i in range(len(bins))]
    across = [
        a is not None and b is not None and _vehicle_across(a, b, vehicle_max_n)
        for a, b in itertools.pairwise(inner)
    ]
    keep = [np.ones(len(s), bool) for s in stamps]
    for i, sel in enumerate(sels):
        ends = (i == 0 or not across[i - 1], i == len(bins) - 1 or not across[i])
        done = inner[i] if ends == (i == 0, i == len(bins) - 1) else screened(i, ends)
        if done is None:
            continue
        idx = bins[i][0]
        for c, m in enumerate(sel):
            keep[c][m] = ~done.cut[idx[c]]
        if parked is not None and done.parked >= 0:  # bins from the piece's first stamp
            parked.append(min(int(s[m][0]) for s, m in zip(stamps, sel, strict=True)) + done.parked * BIN_NS)
    return keep


def _vehicle_across(before: _Screened, after: _Screened, vehicle_max_n: float) -> bool:
    """Whether a vehicle stood across the silence between two pieces (``_screen_states``)."""
    loads = np.array([before.tail_n, after.head_n])
    return bool(np.all(np.isfinite(loads)) and np.all(loads <= vehicle_max_n))


def _state_bounds(
    stamps: list[np.ndarray],
    values: list[np.ndarray],
    bounds: list[int],
    threshold_n: float,
    vehicle_max_n: float,
) -> list[int]:
    """Keep the silences across which the car-free level changes as piece bounds; join the others.

    A vehicle only adds load, so each piece's lowest 1 s bin sum is its car-free level (or, for a
    piece the car covers, above it). Across a silence where the next piece's level lies more than
    ``threshold_n`` below the lowest level of the stretch so far, or more than ``vehicle_max_n``
    above it (``split_bin``'s rule for a state change inside a record), the pieces are two states
    and are screened one by one. Otherwise the recording only paused (a logger that
    stopped for minutes inside a record, maybe while the test car was parked): the pieces are one
    stretch with empty bins in the silence, and a vehicle on the bridge across it comes back on
    its far side and is cut (screened piece by piece, its run touched each piece's edge and stayed
    data: the car's windows went into the level or were rejected as outliers, the noise model
    grew, and a real 10 mm change after a gap fell to probability 0.11, unreported).
    """
    levels = []
    for a, b in itertools.pairwise(bounds):
        sel = [(s >= a) & (s < b) for s in stamps]
        _, total = _bin_total(
            [s[m] for s, m in zip(stamps, sel, strict=True)], [v[m] for v, m in zip(values, sel, strict=True)]
        )
        levels.append(float(np.nanmin(total)) if np.any(np.isfinite(total)) else np.nan)
    kept = [bounds[0]]
    level = levels[0]  # the stretch's car-free level so far: its lowest piece (a piece may be all car)
    for i in range(1, len(bounds) - 1):
        step = levels[i] - level  # NaN (a piece without both channels): a new piece
        if -threshold_n <= step <= vehicle_max_n:
            level = min(level, levels[i])
        else:
            kept.append(bounds[i])
            level = levels[i]
    return [*kept, bounds[-1]]


def _bin_total(stamps: list[np.ndarray], values: list[np.ndarray]) -> tuple[list[np.ndarray], np.ndarray]:
    """1 s bins from the first stamp: (bin index of each sample, sum of the channels' bin means)."""
    t0 = min(int(s[0]) for s in stamps)
    n = (max(int(s[-1]) for s in stamps) - t0) // BIN_NS + 1
    idx = [(s - t0) // BIN_NS for s in stamps]
    total = sum(window_stats(i, v, n).mean for i, v in zip(idx, values, strict=True))  # NaN: a channel empty
    return idx, total


class _Screened(NamedTuple):
    """The screen of a stretch of bins: bins cut, its baseline at its first and last bin (N), bins free.

    ``head_n`` / ``tail_n``: the load (N above the baseline; the median of its half minute next to
    the bin) of a run cut where it touches the stretch's first / last bin when that bin is a split,
    NaN when none is. ``parked``: the first bin cut as vehicles parked at the record's end (-1:
    none).
    """

    cut: np.ndarray
    first_n: float
    last_n: float
    free: int
    head_n: float = np.nan
    tail_n: float = np.nan
    parked: int = -1


def _screen_bins(
    total: np.ndarray,
    threshold_n: float,
    margin: int,
    vehicle_max_n: float,
    depth: int = 0,
    ends: tuple[bool, bool] = (True, True),
    carried: bool = False,
) -> _Screened:
    """Screen the 1 s bin sums ``total`` (NaN: a bin without both channels); see the module docstring.

    ``ends``: whether the stretch's first and last bins are ends of the record (True) or a split
    made here (False). A flagged run that touches an end of the record does not come back: a
    state change, or a vehicle still on the bridge there. With one (and ``depth < MAX_SPLITS``),
    the stretch is split where the car-free level changes (``split_bin``) and each side screened
    on its own, its first baseline through its lowest bins (``support_start``: a vehicle parked
    for most of a side leaves too few car-free bins for its lowest fifth); a run above the baseline
    that touches the split is a vehicle on the bridge while the state changed, when the left side
    carries it too (``_holds_a_further_state``: otherwise the right side holds a further state and
    is screened again with the split as an open end). A right side screened again so while the
    left side carried a vehicle at the split (``carried``: a settlement under the test car, a
    second one after it left) begins under that vehicle: where it splits again (``split_bin``'s
    rule for a stretch that begins under a vehicle), the split is no end for the first piece,
    whose run at it is the vehicle and is cut (screened as an open end, the car stayed data over
    the state between the settlements: 14.5 mm off the final state of two 10 mm lowerings at
    minutes 6 and 11 of the reference record, the interval missing it); where no split stands
    there, the side is screened as it was before the rule. The split stands when the two
    sides' baselines differ at it by more than ``threshold_n`` (one straight baseline could not
    carry both: a state change inside the record, whose vehicles the tilted baseline would
    otherwise hide) and each side shows car-free bins, at least the margin's worth (noise
    larger than the threshold flags every bin, and the rule has nothing to stand on); a split
    inside a vehicle's excursion leaves baselines that agree (the car-free level on both sides),
    and the stretch is screened whole. A stretch that ends the record with vehicles parked at
    its end (``parked_start``) is cut from their arrival on (less the margin), the bins before it
    screened as the side of a split. So, reversed, is one that begins the record with vehicles
    on the bridge that then left: cut up to their departure (and the margin), the rest screened
    as the side of a split. A record that ends while a load still moves (its last bins not
    ``quiet``, at most the margin's worth: the recording stopped as a vehicle drove off) ends, for
    the screen, at its last quiet bin, and the moving bins are cut: what stays cannot be read
    from a load half gone (the reference record cut at minute 8.3, as its second test car
    left, kept the car as a state of +0.8 mm, or in the new state's level, 2 mm off).
    """
    n = len(total)
    valid = np.flatnonzero(np.isfinite(total))  # bins with both channels (sparse data leaves gaps)
    if ends[1] and depth < MAX_SPLITS and len(valid) > margin:
        calm = quiet(total, threshold_n)[valid]
        moving = len(valid) - 1 - int(np.flatnonzero(calm)[-1]) if calm.any() else len(valid)
        if 0 < moving <= margin:  # the record ends as a load moves: its end is the last quiet bin
            k = int(valid[-moving])
            rest = _screen_bins(total[:k], threshold_n, margin, vehicle_max_n, depth + 1, ends)
            cut = np.concatenate([rest.cut, np.ones(n - k, bool)])
            return _Screened(cut, rest.first_n, rest.last_n, rest.free, rest.head_n, rest.tail_n, rest.parked)
    if ends[0] and depth < MAX_SPLITS:
        p = parked_start(total[valid][::-1], threshold_n, vehicle_max_n, margin)
        if p is not None:  # on the bridge when the recording began, gone at bin len - p
            k = int(valid[min(len(valid) - p + margin, len(valid) - 1)])
            right = _screen_bins(total[k:], threshold_n, margin, vehicle_max_n, depth + 1, (False, ends[1]))
            cut = np.concatenate([np.ones(k, bool), right.cut])
            parked = right.parked + k if right.parked >= 0 else -1
            return _Screened(cut, right.first_n, right.last_n, right.free, np.nan, right.tail_n, parked)
    if ends[1] and depth < MAX_SPLITS:
        p = parked_start(total[valid], threshold_n, vehicle_max_n, margin)
        if p is not None:
            k = int(valid[max(p - margin, 0)])
            left = _screen_bins(total[:k], threshold_n, margin, vehicle_max_n, depth + 1, (ends[0], False))
            cut = np.concatenate([left.cut, np.ones(n - k, bool)])
            return _Screened(cut, left.first_n, left.last_n, left.free, left.head_n, np.nan, k)
    t = np.arange(n) + 0.5
    start = first_free(total, threshold_n) if all(ends) else support_start(total, threshold_n)
    flags = flag_car(t, total, threshold_n, margin, empty_is_car=False, start=start)
    baseline = total - flags.residual_n
    cut = np.zeros(n, bool)
    open_run = False
    head_n = tail_n = np.nan
    near = MIN_SIDE_BINS // 2  # bins next to a split whose median is a run's load there
    for a, b in runs(flags.car[valid]):
        if b == len(valid) and ends[1] and not (a == 0 and ends[0]):
            b = _fell_back(flags.residual_n[valid[a:b]], threshold_n, margin, a, b)
        if (a == 0 and ends[0]) or (b == len(valid) and ends[1]):
            open_run = True
            continue  # it does not come back within the record: a change of state (or see above)
        if np.mean(flags.residual_n[valid[a:b]]) <= 0:
            continue  # below the baseline: not a vehicle
        cut[valid[a] : valid[b - 1] + 1] = True
        # the load next to a split: a vehicle parked across it carries the same load on both sides
        # (crossings and moves elsewhere in the run do not count)
        if a == 0:
            head_n = float(np.median(flags.residual_n[valid[a : min(b, a + near)]]))
        if b == len(valid):
            tail_n = float(np.median(flags.residual_n[valid[max(a, b - near) : b]]))
    free = int(np.sum(~flags.car[valid]))
    whole = _Screened(cut, float(baseline[valid[0]]), float(baseline[valid[-1]]), free, head_n, tail_n)
    if not open_run or depth >= MAX_SPLITS or len(valid) < 2 * MIN_SIDE_BINS:
        return whole
    rule = (threshold_n, margin, vehicle_max_n, depth, ends)
    split = _split(total, valid, *rule, carried)
    if split is None and carried:  # no split stands where the level falls most: as before the rule
        split = _split(total, valid, *rule, False)
    return whole if split is None else split


def _split(
    total: np.ndarray,
    valid: np.ndarray,
    threshold_n: float,
    margin: int,
    vehicle_max_n: float,
    depth: int,
    ends: tuple[bool, bool],
    carried: bool,
) -> _Screened | None:
    """Screen ``total`` as two sides of ``split_bin``'s split (``_screen_bins``); None where none stands."""
    at = split_bin(total[valid], threshold_n, vehicle_max_n, carried)
    if at is None:
        return None
    k = int(valid[at])
    more = (threshold_n, margin, vehicle_max_n, depth + 1)
    left = _screen_bins(total[:k], *more, (ends[0] and not carried, False))
    right = _screen_bins(total[k:], *more, (False, ends[1]))
    step = right.first_n - left.last_n
    if abs(step) <= threshold_n or min(left.free, right.free) < margin or 0 < step <= vehicle_max_n:
        return None  # (0 < step: a rise no heavier than a vehicle that came to stay, as before)
    if _holds_a_further_state(left.tail_n, right.head_n, vehicle_max_n):
        right = _screen_bins(total[k:], *more, (True, ends[1]), carried=bool(np.isfinite(left.tail_n)))
    both = np.concatenate([left.cut, right.cut])
    parked = right.parked + k if right.parked >= 0 else -1
    return _Screened(
        both, left.first_n, right.last_n, left.free + right.free, left.head_n, right.tail_n, parked
    )


def _fell_back(residual_n: np.ndarray, threshold_n: float, margin: int, a: int, b: int) -> int:
    """Return the end of a flagged run ``[a, b)`` that touches the record's end: ``b``, or earlier.

    ``residual_n``: the run's bins above the car rule's baseline (N). The car rule flags bins off
    its straight baseline either way, and the car-free level of a record drifts by up to 1-2 kN
    through it (the reactions creeping back after a lowering, the sun: ``first_free``); where the
    record ends minutes after a vehicle left, that drift bends away from the straight line and the
    last bins are flagged too, joining the vehicle's run to the end, which is then read as not
    coming back (a state change; the car stayed data). A vehicle weighs at least the lightest
    parked plateau (``PARKED_MIN_THRESHOLDS``, 3 kN); where the run's last bin that heavy is
    followed by bins all within that of the baseline, the vehicle left and the rest is the drift:
    the run ends at that bin and the margin after it (within the record: the rest stays data).
    """
    heavy = PARKED_MIN_THRESHOLDS * threshold_n
    loaded = np.flatnonzero(residual_n > heavy)
    if not len(loaded) or loaded[-1] >= len(residual_n) - 1:
        return b
    if np.any(np.abs(residual_n[loaded[-1] + 1 :]) > heavy):
        return b
    return min(a + int(loaded[-1]) + 1 + margin, b - 1)


def _holds_a_further_state(tail_n: float, head_n: float, vehicle_max_n: float) -> bool:
    """Whether the run cut where the right side of a split begins holds more than a vehicle.

    ``tail_n`` / ``head_n``: the loads (N; NaN: none) of the runs cut where the left side ends and
    the right side begins, at the split. Each side's baseline runs through its lowest bins, so a
    further state inside the right side (a second settlement in the record, the level between the
    two steps above the final one) is read as load on top of whatever vehicle is there. It is one
    when the run is heavier than any vehicle (``vehicle_max_n``), or when the left side carries no
    run at the split (nothing on the bridge there to continue); such a side is screened again with
    the split as an end that does not come back: split further, or kept as data, never cut as a
    vehicle, but for the one the left side carried at the split where the side splits again
    (``_screen_bins``' ``carried``). A run no heavier than a vehicle, with a vehicle on the left
    at the split, is vehicles: their number may change there (a second test car arriving 20 s
    before a step, read as a further state by the loads' mismatch that the rule first asked for,
    kept both cars in the new state's level, 1.1 to 2.1 mm).
    """
    if np.isnan(head_n):
        return False
    return bool(np.isnan(tail_n) or head_n > vehicle_max_n)


def first_free(s: np.ndarray, threshold_n: float) -> np.ndarray:
    """Return the bins that start the car rule's baseline on a whole record (NaN: none).

    In each half of the bins with data (its quiet bins, ``quiet``, where it has any), the lowest
    fifth (the calibration's rule, one per half so that a drift of ~1 kN through a record does
    not put the whole start at one end), but no bin
    more than ``threshold_n`` above the half's lowest: a vehicle only adds load, so the lowest bin
    is car-free and so are those near it, while a vehicle on the bridge for more than four fifths
    of a half (a load cell silent over the car-free minutes before it) would otherwise be the
    fifth's and the baseline.
    """
    out = np.zeros(len(s), bool)
    calm = quiet(s, threshold_n)
    for part in np.array_split(np.flatnonzero(np.isfinite(s)), 2):
        if calm[part].any():
            part = part[calm[part]]
        if len(part):
            low = min(float(np.quantile(s[part], 0.2)), float(np.min(s[part])) + threshold_n)
            out[part[s[part] <= low]] = True
    return out


#: Bins with data on each side whose steps a quiet bin's neighbourhood spans (``quiet``).
QUIET_REACH = 2


def quiet(s: np.ndarray, threshold_n: float) -> np.ndarray:
    """Return the bins whose neighbourhood moves by at most ``threshold_n`` a step (NaN: none).

    The neighbourhood: ``QUIET_REACH`` bins with data on each side, every step between them.

    A car-free bin is quiet: the load cells' noise moves a 1 s bin by tens of newtons, a vehicle
    driving on or off by kilonewtons within seconds. A burst of sensor noise (a loose cable, a
    failing amplifier: kilonewtons per sample) scatters its bins both ways; its lowest bins are no
    car-free level, and a baseline started on them sits below every car-free bin, which the car
    rule then flags as a vehicle, leaving the real one in the data. The first baseline is started
    on quiet bins only (where there are any). One step each side would let a third of a white
    burst's bins through (a step of its ``sqrt(2)`` times the bins' scatter stays under the
    threshold that often); the neighbourhood's ``2 QUIET_REACH`` steps let about 1 % through.
    """
    out = np.zeros(len(s), bool)
    idx = np.flatnonzero(np.isfinite(s))
    if len(idx) < 2:
        out[idx] = True
        return out
    loud = np.abs(np.diff(s[idx])) > threshold_n  # step i: between bins i and i + 1 (with data)
    ok = np.ones(len(idx), bool)
    for r in range(QUIET_REACH):  # the steps r before and r after each bin
        ok[r + 1 :] &= ~loud[: len(loud) - r]
        ok[: len(ok) - r - 1] &= ~loud[r:]
    out[idx] = ok
    return out


def support_start(s: np.ndarray, threshold_n: float) -> np.ndarray:
    """Return the bins within ``threshold_n`` of the lowest bin of ``s`` (NaN: none).

    A vehicle only adds load, so the lowest bin is car-free and so are those near it: they start
    ``flag_car``'s fit of a split side, however few of its bins are car-free (a vehicle parked
    across the split fills most of a side: its lowest fifth would be the vehicle's).
    """
    ok = np.isfinite(s)
    out = np.zeros(len(s), bool)
    if ok.any():
        out[ok] = s[ok] <= np.min(s[ok]) + threshold_n
    return out


def _side_minima(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``min(s[:k])`` and ``min(s[k:])`` for every split ``k`` leaving ``MIN_SIDE_BINS`` on each side.

    Index ``i`` is the split ``k = i + MIN_SIDE_BINS``; a vehicle only adds load, so these are the
    car-free levels of the two sides while each has a car-free bin (``split_bin``, ``parked_start``).
    """
    n = len(s)
    before = np.minimum.accumulate(s)[MIN_SIDE_BINS - 1 : n - MIN_SIDE_BINS]
    after = np.minimum.accumulate(s[::-1])[::-1][MIN_SIDE_BINS : n - MIN_SIDE_BINS + 1]
    return before, after


def split_bin(
    s: np.ndarray, threshold_n: float, vehicle_max_n: float = np.inf, carried: bool = False
) -> int | None:
    """Return ``k`` (``MIN_SIDE_BINS <= k <= len(s) - MIN_SIDE_BINS``) where the car-free level changes.

    A vehicle only adds load, so the lowest bin before ``k`` and the lowest from ``k`` on are
    car-free levels of the two sides (as long as each side has a car-free bin). Their difference
    ``D(k)`` is the whole drop, for a drop of the level at ``k0``, from the first car-free bin up
    to ``k0``, and falls once the new state enters the left side: the split is the last ``k``
    within ``threshold_n`` of the largest ``D``. None when no drop exceeds ``threshold_n``, or a
    rise is larger and no heavier than ``vehicle_max_n``: a level that rises and stays to the end
    of a record is what a vehicle parked at its end looks like (the 2022-03-07 record ends so, the
    2022-04-11 ones cut after six minutes too), and the screen keeps it as data, as before; a drop
    that stays is not a vehicle (one parked at the start that leaves splits off with its own
    baseline, kept as data too).

    ``carried``: the stretch begins under a vehicle that was on the bridge at a split before it
    (``_screen_bins``). Its lowest bins before ``k`` are then the vehicle's load until it leaves, and
    ``D`` falls at its departure too, before the state change: the split is where ``D`` falls most
    within ``PARKED_RISE_BINS`` bins (a step shows in at most two), the last ``k`` of that fall
    within ``threshold_n`` of its top; a ``D`` still standing at the last split allowed falls to
    nothing past it. The largest fall is the state change where that is heavier than the vehicle's
    departure (the reference record's test cars: 10 kN each, a 10 mm lowering 50 to 60 kN);
    otherwise it is the departure, where no split stands (the piece before it has no car-free
    bin), and ``_screen_bins`` screens the stretch as before.

    A rise heavier than ``vehicle_max_n`` (the heaviest load the bridge's traffic puts on the
    support) is no vehicle that came to stay but a support raised inside the record. It splits at
    the first ``k`` within ``threshold_n`` of the largest rise ``min(s[k:]) - min(s[:k])``, where
    the record's last level is reached: the vehicles before it are screened against the old
    level's baseline (one baseline through both levels left a test car parked before a 10 mm raise
    as data, its windows rejected as outliers), the last level stays data. A level between two
    raises is cut with the vehicles before the split (a vehicle only adds load, so under a parked
    vehicle no car-free bin tells a raised state from the vehicle on the old one).
    """
    before, after = _side_minima(s)
    drop = before - after
    if not len(drop):
        return None
    rise = -drop.min()
    if drop.max() > max(threshold_n, rise):
        if carried:
            ext = np.concatenate([drop, np.zeros(PARKED_RISE_BINS)])
            i = int(np.argmax(ext[:-PARKED_RISE_BINS] - ext[PARKED_RISE_BINS:]))
            near = drop[i : i + PARKED_RISE_BINS + 1] >= drop[i] - threshold_n
            return i + int(np.flatnonzero(near)[-1]) + MIN_SIDE_BINS
        return int(np.flatnonzero(drop >= drop.max() - threshold_n)[-1]) + MIN_SIDE_BINS
    if rise > max(threshold_n, vehicle_max_n, drop.max()):
        return int(np.flatnonzero(-drop >= rise - threshold_n)[0]) + MIN_SIDE_BINS
    return None


def parked_start(s: np.ndarray, threshold_n: float, vehicle_max_n: float, margin: int) -> int | None:
    """Return the bin where the vehicles parked at the end of ``s`` arrived (None: none).

    ``s``: a record's 1 s bin sums (N), its last bin the record's end. A vehicle only adds load,
    so the load that stays from a split ``k`` to the end is ``min(s[k:]) - min(s[:k])``; its
    largest value, ``top``, is the load at the end above the car-free level before it (when it
    is at least ``PARKED_MIN_THRESHOLDS threshold_n`` and exceeds every drop of that kind: a
    lowered state is no vehicle). The
    vehicles arrived where half of it was first reached, ``k``, and are taken as parked there
    when

    - they arrived as vehicles do: the bins around ``k`` (``margin`` each side) are not all
      ``quiet`` (a vehicle driving on moves a 1 s bin by kN within seconds, a drift never), and
      the load rose from 10 to 90 % over at least ``PARKED_RISE_BINS`` bins (a step falls in one).
      Where ``k`` lies on a level (two vehicles of about one load: half of it reached on the
      first one's plateau), the arrival that completed it is the next bin that is not quiet;
    - the load that arrived is the one still there: the level's rise over the half minutes either
      side of ``k`` lies between ``top / 2`` and ``top``, each within ``PARKED_DRIFT_THRESHOLDS
      threshold_n`` (a vehicle that left on top of a change is none; the second of two vehicles
      of one load carries half of it);
    - from ``k`` to the end no bin carries more than ``vehicle_max_n`` above the car-free level
      (the heaviest load the bridge's traffic puts on the support; a state between two steps
      inside the record is heavier).

    Several vehicles may have come (a second car parked, then gone): the search repeats on the
    bins before ``k``, at most ``MAX_SPLITS`` times, each side at least ``MIN_SIDE_BINS`` long.
    On ``s`` reversed it finds vehicles on the bridge when a record began that left as vehicles do
    (``len(s) - k``: the first bin after they left).
    """
    end, start = len(s), None
    calm = quiet(s, threshold_n)
    span = 3 * margin  # the half minutes either side of an arrival
    for _ in range(MAX_SPLITS):
        part = s[:end]
        n = len(part)
        if n < 2 * MIN_SIDE_BINS:
            break
        before, after = _side_minima(part)
        load = after - before  # min of s[k:] over min of s[:k]
        top = float(load.max())
        if top < PARKED_MIN_THRESHOLDS * threshold_n or top <= float((-load).max()):
            break  # lighter than any parked vehicle (a drift), or a lowered state
        k = int(np.flatnonzero(load >= 0.5 * top)[0]) + MIN_SIDE_BINS
        if calm[max(k - margin, 0) : k + margin].all():
            # on a level: between two vehicles of about one load, the half reached on the first's
            # plateau; the arrival that completed it is the next one (none: a drift)
            moved = np.flatnonzero(~calm[k:n])  # within this part (``calm`` spans the whole record)
            if not len(moved):
                break  # nothing drove on there: a drift
            k += int(moved[0])
        lo = float(np.median(part[max(k - span, 0) : k]))
        rise = float(np.median(part[k : k + span])) - lo
        slack = PARKED_DRIFT_THRESHOLDS * threshold_n
        if not 0.5 * top - slack <= rise <= top + slack:
            break  # the load that arrived there is not the one at the end
        near = part[max(k - span, 0) : k + span]
        rolled = int(np.argmax(near >= lo + 0.9 * rise)) - int(np.argmax(near >= lo + 0.1 * rise))
        if rolled < PARKED_RISE_BINS:
            break  # within a bin or two: a step, not a vehicle rolling on
        start = end = k
    if start is None or float(np.max(s[start:]) - np.min(s[:start])) > vehicle_max_n:
        return None
    return start
