"""Truth-twin scenarios and an independent record.

Steps are followed within a few windows with an honest
interval, a record without events ends exactly where the paper's batch method does.

The coverage over 200 seeds per scenario is measured by ``benchmarks/event_coverage.py``; these tests run
one or two seeds each.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.estimate.settlement.batch import paper_batch_of_run
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.series import MonitoringData
from bridge_shadow.twin.simulate import simulate

SUR = placeholder_surrogate()
W = 60 * 10**9
#: A strong uniform-temperature response, so that a step while the air warms is the worst case
#: for confounding (the placeholder's own is zero).
THERMAL = {"uniform_temperature": 300.0}


def _run(steps=(), effects=None, days: float = 2.5, seed: int = 0, config: ShadowConfig | None = None):
    data, truth = simulate(days=days, rate_hz=0.2, seed=seed, surrogate=SUR, steps=steps, effects=effects)
    shadow = Shadow(config or ShadowConfig(), SUR)
    return shadow, shadow.run(data), truth


def _followed(res, truth, t_day: float, step: np.ndarray, within: int = 8) -> int:
    """Windows after the step until the published estimate has moved by the step (within 3 sigma).

    The change, not the absolute value: online, the level is the mean of the record so far (the
    paper's ``y - g(T) + ybar``), which moves with the mean temperature seen so far when the
    forces follow the temperature strongly; the step is what the event is about.
    """
    h = res.history()
    t = (h["end_ns"] - truth["start_ns"]) / 86_400e9
    before = h["mean_m"][np.flatnonzero(t <= t_day)[-1]]
    after = np.flatnonzero(t > t_day)
    for j, i in enumerate(after[: within + 1]):
        sd = np.sqrt(np.diag(h["covariance_m2"][i]))
        if np.all(np.abs(h["mean_m"][i] - before - step) <= 3.0 * sd + 0.02 * np.abs(step)):
            return j + 1
    return 10**6


@pytest.mark.parametrize(
    ("name", "steps"),
    [
        ("step of both supports while the air warms", [(1.4, -1e-3, -1e-3)]),
        ("step at one bearing only", [(1.55, -0.5e-3, 0.0)]),
        ("two steps a day apart", [(1.4, -1e-3, -1e-3), (2.4, 0.5e-3, -0.5e-3)]),
    ],
)
def test_twin_steps_are_found_and_followed_within_a_few_windows(name: str, steps: list) -> None:
    _, res, truth = _run(steps, THERMAL, days=3.0)
    k0 = truth["start_ns"] // W
    assert len(res.events) == len(steps), (name, [e.window - k0 for e in res.events])
    for (t_day, ds, dn), ev in zip(steps, res.events, strict=True):
        assert abs((ev.window - k0) - t_day * 1440) <= 1  # the estimated change time
        np.testing.assert_allclose(ev.size_m, [ds, dn], atol=4 * np.sqrt(np.diag(ev.covariance_m2)).max())
        assert _followed(res, truth, t_day, np.array([ds, dn])) == 1  # the held windows come out followed
    err = res.mean_m - np.asarray(truth["settlement"]["end_m"])
    assert err @ np.linalg.solve(res.covariance_m2, err) <= 13.8  # chi2(2) 99.9 %


def test_a_slow_drift_under_the_daily_cycle_is_followed_with_process_noise() -> None:
    cfg = ShadowConfig(process_noise_m2_per_s=[1e-13, 1e-13], drift_block_s=1800.0)
    _, res, truth = _run(effects={**THERMAL, "settlement_drift": 2e-4}, days=3.0, config=cfg)
    assert not res.events  # a drift is not a step
    err = res.mean_m - np.asarray(truth["settlement"]["end_m"])
    assert err @ np.linalg.solve(res.covariance_m2, err) <= 13.8  # the end, with an honest interval
    # online: the estimate sinks with the support, day by day (its level is the record so far's)
    h = res.history()
    t = (h["end_ns"] - truth["start_ns"]) / 86_400e9
    day = [np.flatnonzero(t >= d)[0] for d in (1.0, 2.0, 2.99)]
    rate = np.diff(h["mean_m"][day, 0]) / np.diff(t[day])
    np.testing.assert_allclose(rate, -2e-4, rtol=0.35)


@pytest.mark.parametrize("size_m", [1e-4, 1e-2, 5e-2])
def test_steps_from_a_tenth_of_a_millimetre_to_five_centimetres(size_m: float) -> None:
    _, res, truth = _run([(0.8, size_m, 0.0)], days=1.2)
    assert len(res.events) == 1
    sd = np.sqrt(np.diag(res.events[0].covariance_m2))
    np.testing.assert_allclose(res.events[0].size_m, [size_m, 0.0], atol=4 * sd.max() + 1e-3 * size_m)
    err = res.mean_m - np.asarray(truth["settlement"]["end_m"])
    assert err @ np.linalg.solve(res.covariance_m2, err) <= 13.8


def test_a_record_without_events_ends_at_the_papers_batch_posterior() -> None:
    # the paper's batch has no sun term: the shadow without it
    shadow, res, _ = _run(effects=THERMAL, days=1.5, seed=3, config=ShadowConfig(sun_gradient=False))
    assert not res.events and res.updates > 2000
    batch = paper_batch_of_run(shadow, res)
    np.testing.assert_allclose(res.mean_m, batch.mean_m, rtol=1e-8)
    np.testing.assert_allclose(res.covariance_m2, batch.covariance_m2, rtol=1e-8)
    np.testing.assert_allclose(shadow.noise.r1, batch.r1, rtol=1e-8)


def test_an_independent_record_is_recovered_as_the_batch_method_does() -> None:
    """Not from the twin: 1 day at 1 Hz, forces following the air at 400/300 N/K.

    AR(1) noise (phi 0.9, 60 N per sample), settlement offset +0.7/-0.4 mm.
    """
    rng = np.random.default_rng(42)
    n = 86_400
    t0 = 1_650_000_000 * 10**9
    stamps = t0 + np.arange(n, dtype=np.int64) * 10**9
    hours = np.arange(n) / 3600.0
    air = 8.0 + 7.0 * np.sin(2 * np.pi * (hours - 9.0) / 24.0) + np.cumsum(rng.normal(0, 0.002, n))
    x = np.array([0.7e-3, -0.4e-3])
    noise = lfilter([np.sqrt(1 - 0.81)], [1.0, -0.9], rng.normal(0, 60.0, (n, 2)), axis=0)
    forces = SUR.reactions(x) + np.outer(air - air.mean(), [400.0, 300.0]) + noise
    data = MonitoringData.from_arrays(stamps, forces, stamps, air)
    shadow = Shadow(ShadowConfig(), SUR)
    res = shadow.run(data)
    assert not res.events
    sd = np.sqrt(np.diag(res.covariance_m2))
    assert np.all(np.abs(res.mean_m - x) < 0.015e-3) and np.all(np.abs(res.mean_m - x) < 3 * sd)
    assert np.all(sd < 0.01e-3)


def test_monitoring_that_ends_as_a_vehicle_crosses_ends_at_the_state_before_it() -> None:
    """A day of monitoring with traffic, the data ending in the middle of a crossing: no change.

    The last window holds seconds of a 25 kN vehicle on the bridge, beyond the detector's trigger,
    with nothing after it to show the vehicle leave. Taken as a change where the data end, it was
    an unconfirmed change of probability 1 and moved the final estimate by the vehicle's share of
    the window (+0.29 mm on both supports, the truth 0). One window where the data end, no heavier
    than any vehicle, is no state of its own: left out and reported (``at_end``, a warning).
    """
    from bridge_shadow.estimate import load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    sur = load_surrogate()
    data, _ = simulate(1.0, 1.0, 3, {"traffic": 25000.0}, surrogate=sur)
    end = int(data.forces["frc_01"].stamp_ns[35259]) + 1  # seconds into a crossing (09:47 local)
    data = data.select(lambda t: t < end)
    res = Shadow(load_config(), sur).run(data)
    np.testing.assert_allclose(res.mean_m, 0.0, atol=5e-5)  # the truth: no settlement
    assert [c.kind for c in res.changes if c.kind != "run_in_data"] == ["at_end"], res.changes
    (at_end,) = [c for c in res.changes if c.kind == "at_end"]
    assert at_end.likely and np.all(at_end.size_m > 0.0)  # reported, the vehicle's load upward
    assert res.outputs[-1].reason == "step_window"
    assert not res.events
