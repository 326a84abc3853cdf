"""Window buffer: per-window counts, means and matched temperatures equal a direct computation."""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.estimate.inputs.windows import WindowBuffer
from bridge_shadow.windowing import sorted_union

W = 60 * 10**9
T0 = 1_700_000_040 * 10**9


def _data(
    seed: int = 0, alike: bool = False
) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray, np.ndarray]:
    """Two force channels (stamped ``alike``: one logger sampling both), and the air with a hole."""
    rng = np.random.default_rng(seed)
    stamps = [np.sort(T0 + rng.integers(0, 30 * W, 900)) for _ in range(2)]
    stamps = [np.unique(s) for s in stamps]
    if alike:
        stamps[1] = stamps[0].copy()
    values = [2e5 + rng.normal(0, 100, len(s)) for s in stamps]
    ts = T0 + np.arange(0, 30 * W, 20 * 10**9)
    ts = np.delete(ts, np.arange(40, 52))  # a 4-minute hole in the temperature
    tv = 5.0 + np.sin(np.arange(len(ts)) / 7.0)
    return stamps, values, ts, tv


def test_batched_windows_equal_a_direct_per_window_computation() -> None:
    stamps, values, ts, tv = _data()
    buf = WindowBuffer(60.0, 30.0, 120.0, "linear", min_samples=3)
    for c in range(2):
        assert buf.add_forces(c, stamps[c], values[c]) == 0
    buf.add_temperature(ts, tv)
    lasts = [int(s[-1]) for s in stamps]
    batch = buf.close_until(buf.due_end(max(lasts[0], lasts[1], int(ts[-1])), lasts), lasts)
    assert len(batch) >= 25
    for j, k in enumerate(batch.k):
        for c in range(2):
            sel = (stamps[c] >= k * W) & (stamps[c] < (k + 1) * W)
            assert batch.samples[j, c] == sel.sum()
            np.testing.assert_allclose(batch.force_n[j, c], values[c][sel].mean(), rtol=1e-14)
            # linear interpolation between bracketing readings (np.interp), held flat beyond them;
            # a window sees the readings up to its end plus the horizon max(timeout, stale) = 120 s
            vis = ts < (k + 1) * W + 120 * 10**9
            matched = np.interp((stamps[c][sel] - T0).astype(float), (ts[vis] - T0).astype(float), tv[vis])
            np.testing.assert_allclose(batch.temp_c[j, c], matched.mean(), rtol=1e-12)
            # the age: the largest distance from a sample to the reading its match rests on (the
            # nearer of the two visible brackets)
            near = np.abs(stamps[c][sel][:, None] - ts[vis][None, :]).min(axis=1)
            assert batch.temp_age_s[j] >= near.max() / 1e9 - 1e-9
            if np.any(near > 120 * 10**9):
                assert batch.reason[j] == "" and batch.temp_age_s[j] > 120.0
    # a window closes once, and later samples of it are late
    assert buf.add_forces(0, np.array([int(batch.k[0]) * W + 5]), np.array([2e5])) == 1


def test_without_any_temperature_windows_are_uncompensated_not_stale() -> None:
    stamps, values, _, _ = _data(1)
    buf = WindowBuffer(60.0, 30.0, 120.0)
    for c in range(2):
        buf.add_forces(c, stamps[c], values[c])
    batch = buf.flush([int(s[-1]) for s in stamps])
    assert len(batch) == 30 and not buf.temp_seen
    assert np.all(np.isnan(batch.temp_c)) and set(batch.reason) == {""}


def test_a_held_record_too_long_only_for_a_recording_started_again_is_split_at_the_silence() -> None:
    """``_Record``: past the hold, the part before the last piece silence ends (to screen), the rest is held.

    A record that is too long without such a silence, or whose piece after it is itself too
    long, is released unscreened as before.
    """
    from bridge_shadow.estimate.inputs.windows import _Record

    m = 60 * 10**9
    rec = _Record()
    rec.begin(0)
    assert rec.extend(12 * m, 30 * m) == []
    rec.resume(20 * m)  # eight minutes of silence, then the next recording
    assert rec.extend(25 * m, 30 * m) == []  # 25 min: inside the hold, held whole
    assert rec.extend(32 * m, 30 * m) == [(0, 12 * m)]  # past it: the first recording ends
    assert rec.holding and rec.start_ns == 20 * m
    assert _Record.from_state_dict(rec.state_dict()).state_dict() == rec.state_dict()
    assert rec.end() == [(20 * m, 32 * m)]
    one = _Record()
    one.begin(0)
    assert one.extend(31 * m, 30 * m) == [] and one.open and not one.holding  # no silence: released
    two = _Record()
    two.begin(0)
    two.resume(m)
    assert two.extend(40 * m, 30 * m) == [] and not two.holding  # the piece after it is too long


def _one_by_one(match: str, ts: np.ndarray, tv: np.ndarray, one_window: bool, seed: int, alike: bool = False):
    """Close the windows of ``_data(seed, alike)`` one at a time (a live node's pace); return the batches.

    Also the number of windows' temperature matches (at the force stamps), and of ``_match`` calls.
    """
    stamps, values, _, _ = _data(seed, alike)
    buf = WindowBuffer(60.0, 30.0, 120.0, match, min_samples=30)
    if not one_window:
        buf._one_window = lambda taken: None  # the general path alone
    calls = {"_match": 0, "_match_one": 0}
    for name in calls:
        inner = getattr(buf, name)

        def counted(*a, name=name, inner=inner):
            calls[name] += 1
            return inner(*a)

        setattr(buf, name, counted)
    lasts = [int(s[-1]) for s in stamps]
    for c in range(2):
        buf.add_forces(c, stamps[c], values[c])
    buf.add_temperature(ts, tv)
    out = []
    while buf.next_k is not None and buf.holds_data:
        out.append(buf.close_until(buf.next_k + 1, lasts))
    # a window's match: ``_match_one`` at the live pace (``_match`` only where it falls back to it)
    return out, (calls["_match_one"] if one_window else calls["_match"]), calls["_match"]


@pytest.mark.parametrize("alike", [False, True])
def test_one_window_at_a_time_equals_the_general_aggregate(alike: bool) -> None:
    """``WindowBuffer._one_window`` (the live pace) gives the general path's sums, NaNs, ages, reasons.

    ``alike``: both load cells stamped alike (one logger sampling both, as the real records and the
    live benchmark's stream are): the short path matches the temperature once for both.
    """
    _, _, ts, tv = _data()
    late = ts >= T0 + 12 * W  # the first reading after the first windows: those are blind to it
    cases = [("linear", ts, tv), ("hold", ts, tv), ("linear", ts[late], tv[late]), ("linear", ts[:0], tv[:0])]
    for seed, (match, t, v) in enumerate(cases):
        fast, fast_matches, fast_general = _one_by_one(match, t, v, True, seed, alike)
        slow, slow_matches, _ = _one_by_one(match, t, v, False, seed, alike)
        assert len(fast) == len(slow) == 30
        if len(t) and match == "linear" and len(t) == len(ts):  # every window sees a reading
            assert slow_matches == 60 and fast_matches == (30 if alike else 60)
            assert fast_general < fast_matches / 2  # most between two readings: ``_match`` not called
        reasons = set()
        for a, b in zip(fast, slow, strict=True):
            np.testing.assert_array_equal(a.k, b.k)  # integers
            np.testing.assert_array_equal(a.samples, b.samples)  # integer counts
            np.testing.assert_array_equal(a.cut, b.cut)  # integer counts
            assert list(a.reason) == list(b.reason)
            reasons.update(a.reason)
            for field in ("force_n", "temp_c", "temp_age_s"):
                np.testing.assert_allclose(getattr(a, field), getattr(b, field), rtol=1e-15, atol=0.0)
        assert reasons == {"", "sparse_window"}  # 30 samples a window on average: both kinds
        temps = np.concatenate([a.temp_c for a in fast])
        assert np.isnan(temps).any() == (match == "linear" and len(t) < len(ts))


def test_sorted_union_is_numpys_unique_of_the_concatenation() -> None:
    """``sorted_union`` (runs collapsed first) equals ``np.unique`` of the parts, sorted or not, empty too."""
    rng = np.random.default_rng(5)
    for _ in range(500):
        parts = []
        for _ in range(int(rng.integers(1, 5))):
            part = rng.integers(-5, 20, int(rng.integers(0, 40)))
            parts.append(np.sort(part) if rng.random() < 0.7 else part)
        expected = np.unique(np.concatenate(parts))
        got = sorted_union(parts)
        assert got.dtype == expected.dtype
        np.testing.assert_array_equal(got, expected)  # exact: integers
    # two channels' stamps (ns) of a 12-minute record, distinct, partly shared
    a = np.sort(rng.integers(1_650_000_000 * 10**9, 1_650_000_720 * 10**9, 20_000))
    b = np.sort(np.concatenate([a[::3], rng.integers(1_650_000_000 * 10**9, 1_650_000_720 * 10**9, 10_000)]))
    np.testing.assert_array_equal(sorted_union([a, b]), np.unique(np.concatenate([a, b])))  # exact: integers
