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
   must not put the whole start at one end);
3. a flagged run is *traffic* when it lies above the baseline (a vehicle only adds load) and
   comes back inside the record: it touches neither the first nor the last bin with data. A run
   that does not come back is a change of state and stays data; so does one below the baseline.

The samples of the traffic bins are cut; the windows are built from the rest (a window left
with fewer than ``window_min_samples`` is rejected as ``traffic``). A record longer than the hold
limit is released unscreened (continuous monitoring: the detector's transients handle it).
"""

from __future__ import annotations

import itertools

import numpy as np

from bridge_shadow.traffic import flag_car, runs
from bridge_shadow.windowing import window_stats

__all__ = ["BIN_NS", "PIECE_SILENCE_NS", "screen_record"]

#: Bin width of the screen, ns: the calibration's 1 s bins (a car crossing takes seconds).
BIN_NS = 1_000_000_000
#: A silence of both channels this long splits a record into pieces screened one by one, ns: a
#: minute without a sample of a 100 Hz (or 1 Hz) recording is a recording that stopped, not a
#: dropout; a car's run cut in two by it touches each piece's edge and stays data (the screen's
#: rule for a run that does not come back).
PIECE_SILENCE_NS = 60 * BIN_NS


def screen_record(
    stamps: list[np.ndarray],
    values: list[np.ndarray],
    threshold_n: float,
    margin_s: float,
) -> list[np.ndarray]:
    """Screen the samples of one record (per channel, sorted stamps in ns and forces in N).

    Returns, per channel, a (n_c,) bool mask over the record's samples: True where kept. Where
    both channels fall silent for ``PIECE_SILENCE_NS`` inside the record (two recordings minutes
    apart, shorter than ``gap_s``), each piece is screened on its own: a settlement between them
    would otherwise tilt the baseline under both, and neither car would be cut.
    """
    if any(not len(s) for s in stamps):
        return [np.ones(len(s), bool) for s in stamps]
    both = np.unique(np.concatenate(stamps))
    cuts = both[1:][np.diff(both) >= PIECE_SILENCE_NS]
    if not len(cuts):
        return _screen_piece(stamps, values, threshold_n, margin_s)
    keep = [np.ones(len(s), bool) for s in stamps]
    bounds = [int(both[0]), *map(int, cuts), int(both[-1]) + 1]
    for a, b in itertools.pairwise(bounds):
        sel = [(s >= a) & (s < b) for s in stamps]
        piece = _screen_piece(
            [s[m] for s, m in zip(stamps, sel, strict=True)],
            [v[m] for v, m in zip(values, sel, strict=True)],
            threshold_n,
            margin_s,
        )
        for c, m in enumerate(sel):
            keep[c][m] = piece[c]
    return keep


def _screen_piece(
    stamps: list[np.ndarray],
    values: list[np.ndarray],
    threshold_n: float,
    margin_s: float,
) -> list[np.ndarray]:
    """Screen one continuous piece of a record (``screen_record``)."""
    if any(not len(s) for s in stamps):
        return [np.ones(len(s), bool) for s in stamps]
    t0 = min(int(s[0]) for s in stamps)
    n = (max(int(s[-1]) for s in stamps) - t0) // BIN_NS + 1
    idx = [(s - t0) // BIN_NS for s in stamps]
    total = sum(window_stats(i, v, n).mean for i, v in zip(idx, values, strict=True))  # NaN: a channel empty
    flags = flag_car(
        np.arange(n) + 0.5, total, threshold_n, round(margin_s * 1e9 / BIN_NS), empty_is_car=False, parts=2
    )
    valid = np.flatnonzero(np.isfinite(total))  # bins with both channels (sparse data leaves gaps)
    cut = np.zeros(n, bool)
    for a, b in runs(flags.car[valid]):
        if a == 0 or b == len(valid):
            continue  # it does not come back within the record: a change of state
        if np.mean(flags.residual_n[valid[a:b]]) <= 0:
            continue  # below the baseline: not a vehicle
        cut[valid[a] : valid[b - 1] + 1] = True
    return [~cut[i] for i in idx]
