"""A settlement while the noise model is young: a vehicle over the warm-up does not hide it (issue 19).

Found by a reviewing helper session (stop 77) and left then: the 10 mm record three times back to
back from the data's start (one 36-minute recording, unscreened), 10 mm lower from the second copy,
an ordinary vehicle of 20 kN parked in minutes 1-7. The warm-up's noise model, fitted on ten windows
six of which carried it, read a window sd of 20 kN and a lag-one correlation of 0.9; the step's
windows passed the detector's trigger one by one as data, the refit took the step for noise, and the
stream ended at -2.6 / -3.3 mm for -20, no event, no warning. While the noise model rests on fewer
than three warm-ups of windows, a jump beyond any vehicle on the windows' own scale
(``events.warmup.new_state_at_last``) opens a provisional segment whose windows are held and read
as after a gap (``Shadow._young_step``, ``_open_young``, ``_young_mixed``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.events.warmup import jump_goes_on, new_state_at_last, over_median_ratio
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.loadtest_score import score_stream
from bridge_shadow.twin.real_records import Piece, Scenario, build, with_vehicle

W = 60 * 10**9
VEHICLE = 30e3  # N, the traffic screen's heaviest vehicle (``traffic_vehicle_max_n``)


def _ar1(rng: np.random.Generator, n: int, phi: float, sd: float = 1.0) -> np.ndarray:
    y = np.empty((n, 2))
    y[0] = rng.standard_normal(2)
    for i in range(1, n):
        y[i] = phi * y[i - 1] + np.sqrt(1.0 - phi * phi) * rng.standard_normal(2)
    return sd * y


def test_the_ratio_over_the_median_is_exact_for_exponentials() -> None:
    """``P(X > c M) = probability`` (Rényi's representation), against 400,000 draws."""
    rng = np.random.default_rng(5)
    for m in (5, 12):
        c = over_median_ratio(m, 0.01)
        x = rng.exponential(3.0, (400_000, m + 1))
        rate = np.mean(x[:, -1] > c * np.median(x[:, :-1], axis=1)) if m % 2 else None
        if rate is None:  # an even count: the lower median, as the function takes it
            rate = np.mean(x[:, -1] > c * np.sort(x[:, :-1], axis=1)[:, m // 2 - 1])
        assert rate == pytest.approx(0.01, rel=0.08), (m, rate)
    assert over_median_ratio(6, 1e-3) > over_median_ratio(12, 1e-3) > over_median_ratio(29, 1e-3)


@pytest.mark.parametrize("phi", [0.0, 0.9])
def test_noise_alone_opens_no_young_segment(phi: float) -> None:
    """AR(1) noise of 6 to 30 windows: the scale rule alone fires at most 1.5 %, with the vehicle never.

    Measured over 20,000 runs each: 0.3-1.0 % at the default 0.1 % (the robust scale is read off
    the same few differences, as in the warm-up's rules); noise of 1 kN never moves the sum 30 kN.
    """
    rng = np.random.default_rng(11)
    for n in (6, 11, 30):
        runs = [_ar1(rng, n, phi) for _ in range(2000)]
        alone = np.mean([new_state_at_last(y, np.arange(n), 1e-3, 0.0) for y in runs])
        assert alone <= 0.015, (n, alone)
        kn = [new_state_at_last(1e3 * y, np.arange(n), 1e-3, VEHICLE) for y in runs]
        assert not any(kn)


def test_a_jump_beyond_any_vehicle_after_a_parked_load_is_a_new_state() -> None:
    """A vehicle that came and went in stages over most of the windows, then a settlement's jump.

    The step rules ask a jump to dwarf every other difference, which the load's stages (5-7 kN)
    prevent; this rule reads the jump against the median difference and the vehicle bound.
    """
    rng = np.random.default_rng(2)
    hump = np.array([0, 5, 12, 13, 16, 17, 15, 7.5, 1.6, -0.4, -2.1, -2.1]) * 1e3
    y = np.column_stack([hump, hump]) + _ar1(rng, len(hump), 0.5, 500.0)
    k = np.arange(len(hump) + 1)
    lowered = np.vstack([y, y[-1] - 35e3])  # the sum -70 kN: a 10 mm lowering of this bridge
    assert new_state_at_last(lowered, k, 1e-3, VEHICLE)
    parked = np.vstack([y, y[-1] + 12e3])  # +24 kN: a vehicle's
    assert not new_state_at_last(parked, k, 1e-3, VEHICLE)
    half = np.vstack([y, y[-1] - 17e3, y[-1] - 35e3])  # the step inside the window before
    assert new_state_at_last(half, np.arange(len(half)), 1e-3, VEHICLE)
    assert jump_goes_on(half, np.arange(len(half)), 1e-3)  # that window holds both states
    back = np.vstack([y, y[-1] - 35e3, y[-1] - 34e3])
    assert not jump_goes_on(back, np.arange(len(back)), 1e-3)  # the next window stays


@pytest.fixture(scope="module")
def surrogate():
    return load_surrogate()


def _stream(folder: Path, surrogate, kn: float) -> Scenario:
    step = (-0.01, -0.01)
    pieces = [Piece("lowered", 0.0), Piece("lowered", 0.2, step), Piece("lowered", 0.4, step)]
    sc = build(folder / "Settlements", surrogate.A, pieces)
    sc.data = with_vehicle(sc.data, sc.starts_ns[0], 1e3 * kn, 1.0, 7.0)
    return sc


@pytest.mark.realdata
@pytest.mark.parametrize("kn", [10.0, 20.0, 25.0])
def test_a_vehicle_over_the_warm_up_hides_no_settlement(munich_data: Path, surrogate, kn: float) -> None:
    """The helper's stream: the event at the second copy, the interval holding -20 mm, nothing lost.

    Before: -3.0 / -3.7 (10 kN), -2.6 / -3.3 (20 kN), -2.4 / -3.1 mm (25 kN), no event, not
    covered. The error left (-17.9 / -18.5 mm) is the recorded test car's, data in a recording
    longer than the traffic hold (README "Continuous monitoring is not screened"): the same
    stream without the added vehicle ends at -18.1 / -18.8.
    """
    sc = _stream(munich_data, surrogate, kn)
    res = Shadow(load_config(), surrogate).run(sc.data)
    s = score_stream(sc, res)
    assert s.events_right and s.covered and not s.lost_windows, (1e3 * res.mean_m, s)
    assert np.all(np.abs(s.error_m) < 0.15 * 0.02), 1e3 * res.mean_m  # before: 17 mm off
    assert res.rejected["outlier"] == 0


@pytest.mark.realdata
def test_a_checkpoint_while_the_new_state_is_held_changes_nothing(munich_data: Path, surrogate) -> None:
    """Stopped three windows after the young jump (its windows held) and resumed: the same answer.

    The young windows (``Shadow._young``) travel in the checkpoint, those still queued as the
    same objects.
    """
    config = load_config().replace(traffic_hold_s=0.0)  # windows reach the shadow as the data come
    sc = _stream(munich_data, surrogate, 20.0)
    whole = Shadow(config, surrogate).run(sc.data)
    assert [e.window for e in whole.events] == [sc.starts_ns[1] // W]
    stop = sc.starts_ns[1] + 3 * W
    first = Shadow(config, surrogate)
    first.run(sc.data.select(lambda t: t < stop), flush=False)
    assert first._fresh_open and first._young  # mid-hold, young
    resumed = Shadow.from_state_dict(first.state_dict(), config, surrogate)
    assert [w.k for w in resumed._young] == [w.k for w in first._young]
    rest = resumed.run(sc.data.select(lambda t: t >= stop))
    assert [e.window for e in rest.events] == [e.window for e in whole.events]
    assert np.allclose(rest.mean_m, whole.mean_m, rtol=1e-9, atol=1e-12)
    assert np.allclose(rest.covariance_m2, whole.covariance_m2, rtol=1e-9, atol=1e-15)


@pytest.mark.realdata
def test_replay_live_reads_the_young_jump_as_direct(munich_data: Path, surrogate, tmp_path) -> None:
    """The node (``replay --live``) and the direct replay of the helper's stream: one answer.

    At 10 Hz (every 10th sample: the node's path is the same at any rate); the young jump's windows
    are held and read as after a gap in both, the event at the second copy.
    """
    pytest.importorskip("rclpy")
    from test_loadtest_days import _live_and_direct

    sc = _stream(munich_data, surrogate, 20.0)
    data = sc.data.select(lambda stamps: np.arange(len(stamps)) % 10 == 0)
    live, direct = _live_and_direct(data, tmp_path)
    assert [e["window"] for e in live["events"]] == [e["window"] for e in direct["events"]]
    assert [e["window"] for e in direct["events"]] == [sc.starts_ns[1] // W]


@pytest.mark.realdata
@pytest.mark.parametrize(("kn", "minutes"), [(25.0, (14.0, 24.0)), (30.0, (20.0, 30.0))])
def test_a_vehicle_after_the_step_leaves_the_detector_its_run(
    munich_data: Path, surrogate, kn, minutes
) -> None:
    """The reference record three times, 10 mm lower from the second copy, a vehicle parked after the step.

    Found by a reviewing helper (stop 79, 180 such streams): where the detector holds the step's
    window its run decides, as before the young rule; opening the provisional segment there too,
    the vehicle among the held windows after the jump took the new state's level with it: -2.57 /
    -2.04 mm ± 5.9 (25 kN) and -2.81 / -2.37 ± 6.2 (30 kN) for -10, nothing said. The rule acts
    only where the detector would take the jump as data (``ChangeDetector.takes_as_data``).
    """
    step = (-0.01, -0.01)
    sc = build(
        munich_data / "Settlements",
        surrogate.A,
        [Piece("ref", 0.0), Piece("ref", 0.2, step), Piece("ref", 0.4, step)],
    )
    sc.data = with_vehicle(sc.data, sc.starts_ns[0], 1e3 * kn, *minutes)
    res = Shadow(load_config(), surrogate).run(sc.data)
    s = score_stream(sc, res)
    assert s.covered and (res.events or any(c.likely for c in res.changes)), (1e3 * res.mean_m, s)


def test_takes_as_data_is_what_step_does() -> None:
    """``ChangeDetector.takes_as_data`` changes nothing and says whether ``step`` takes a window at once."""
    from bridge_shadow.estimate.events.detector import ChangeDetector

    rng = np.random.default_rng(9)
    det = ChangeDetector(vehicle_max_n=30.0)
    det.set_noise(np.array([0.5, 0.5]), 1e6)
    r, apa = (1.0, 0.2, 1.0), (0.1, 0.0, 0.1)
    level = np.zeros(2)
    taken = 0
    for k in range(600):
        if k in (200, 400):
            level = level + rng.choice([-8.0, 8.0], 2)
        v = level + rng.standard_normal(2) * (6.0 if k % 97 == 0 else 1.0)
        v_t = (float(v[0]), float(v[1]))
        held_before = bool(det.pending)
        said = det.takes_as_data(k, v_t, r, apa)
        assert det.takes_as_data(k, v_t, r, apa) == said  # nothing changed by asking
        d = det.step(k, v_t, r, apa, k)
        if held_before:
            assert not said  # a run is held: every window joins its judgement
        else:  # taken at once, or held as a run's first window
            assert said == (d.accept == [k]) and said != any(p.k == k for p in det.pending), k
        taken += said
        if d.event or d.change:
            level = np.zeros(2)  # a new segment: innovations against it
            det.prev = None
    assert 300 < taken < 600  # both answers were given


@pytest.mark.realdata
def test_a_raise_over_two_windows_is_one_change(munich_data: Path, surrogate) -> None:
    """The 10 mm record three times from the data's start, raised 10 mm from the second copy.

    The raise goes on over two windows; both are left out (the jump went on over them) and the
    step rule among the held windows finds the new state after them. Before, that opened a second
    segment and left the young jump's own empty at probability one half: the change split in two
    (0.5, 0.29), no event, nothing warned (a reviewing helper, stop 79). Now one event, covered.
    """
    up = (0.01, 0.01)
    pieces = [Piece("lowered", 0.0), Piece("lowered", 0.2, up), Piece("lowered", 0.4, up)]
    sc = build(munich_data / "Settlements", surrogate.A, pieces)
    res = Shadow(load_config(), surrogate).run(sc.data)
    s = score_stream(sc, res)
    assert s.covered and len(res.events) == 1, (1e3 * res.mean_m, s, [c.to_json() for c in res.changes])
    assert abs(res.events[0].window - sc.starts_ns[1] // W) <= 2
    assert not [c for c in res.changes if c.windows == 0]
