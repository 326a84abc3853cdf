"""Event detector on synthetic innovations.

AR(1) noise raises no event, a step is found at its window,
a spike is an outlier, a passing load is not an event, a slow ramp is data (no lock-out).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from bridge_shadow.estimate.events import ChangeDetector

PHI = 0.9
R = (1.0, 0.3, 1.0)  # single-window covariance of the innovations (unit sd, correlated channels)
APA = (1e-4, 0.0, 1e-4)


def ar1(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    e = rng.normal(size=(n, 2)) @ np.linalg.cholesky(np.array([[1.0, 0.3], [0.3, 1.0]])).T
    return lfilter([np.sqrt(1 - PHI**2)], [1.0, -PHI], e, axis=0)


def run(y: np.ndarray) -> tuple[dict[int, str], list[tuple[int, float]]]:
    """Feed window values; return each window's verdict and the events (first window, GLR).

    The innovation is the value minus the current segment's mean (a stand-in for ``y - A x``): the
    windows of an event start a new segment, as in the shadow.
    """
    det = ChangeDetector()
    det.set_noise(np.array([PHI, PHI]), 1e6)
    verdict: dict[int, str] = {}
    events = []
    segment: list[int] = []

    def apply(d) -> None:
        for k in d.reject:
            verdict[k] = "reject"
        for k in d.accept_before:
            verdict[k] = "accept"
            segment.append(k)
        if d.event:
            events.append((d.event[0], d.glr))
            segment.clear()
            for k in d.event:
                verdict[k] = "event"
                segment.append(k)
        for k in d.accept:
            verdict[k] = "accept"
            segment.append(k)

    for k, yk in enumerate(y):
        level = y[segment].mean(axis=0) if segment else np.zeros(2)
        v = yk - level
        apply(det.step(k, (float(v[0]), float(v[1])), R, APA, k))
    apply(det.flush())
    assert sorted(verdict) == list(range(len(y)))  # every window decided once
    return verdict, events


def test_ar1_noise_raises_no_event_and_loses_few_windows() -> None:
    for seed in range(3):
        verdict, events = run(ar1(6000, seed))
        assert not events
        assert sum(v == "reject" for v in verdict.values()) < 6  # at most the extreme tail


def test_a_step_is_found_at_its_window_and_confirmed_within_a_few() -> None:
    for size in (6.0, 50.0, 5000.0):
        v = ar1(800, 11)
        v[400:] += [size, -0.5 * size]
        verdict, events = run(v)
        assert [k for k, _ in events] == [400], (size, events)
        assert all(verdict[k] == "event" for k in range(400, 404))  # confirmed after 4 windows


def test_a_spike_is_an_outlier_and_a_passing_load_is_not_an_event() -> None:
    v = ar1(600, 5)
    v[200] += [40.0, 40.0]  # one wild window
    v[300:303] += [8.0, 8.0]  # a test car parked for three windows, then gone
    verdict, events = run(v)
    assert not events and verdict[200] == "reject"
    assert all(verdict[k] in ("accept", "reject") for k in range(300, 303))


def test_a_slow_ramp_is_data_not_an_event() -> None:
    v = ar1(2000, 9)
    v += np.linspace(0, 12.0, 2000)[:, None]  # a drift the estimate does not follow
    verdict, events = run(v)
    assert not events
    assert sum(v == "accept" for v in verdict.values()) > 1900  # no lock-out


def test_an_event_whose_size_region_holds_zero_says_so() -> None:
    """The JSON flags a detected change whose settlement size is not significant at 95 %."""
    from bridge_shadow.estimate.result import EventRecord

    cov = np.array([[1.0, 0.5], [0.5, 2.0]]) * 1e-6  # m^2: sigma 1 and 1.4 mm
    small = EventRecord(1, 60 * 10**9, 5, np.array([-0.5e-3, 0.4e-3]), cov, 30.0, np.zeros(2))
    large = EventRecord(1, 60 * 10**9, 5, np.array([-5e-3, -5e-3]), cov, 30.0, np.zeros(2))
    d2 = small.size_m @ np.linalg.inv(cov) @ small.size_m  # independent of the record's solve
    assert np.isclose(small.to_json()["size_chi2"], d2, rtol=1e-9)
    assert not small.to_json()["size_significant95"]
    assert large.to_json()["size_significant95"]
    # the threshold is the chi-square quantile, not a number typed from memory
    from scipy.stats import chi2

    from bridge_shadow.estimate.result import CHI2_2DOF_95

    assert np.isclose(CHI2_2DOF_95, chi2.ppf(0.95, 2), rtol=1e-12)
