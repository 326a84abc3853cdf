"""Honest uncertainty: 95% intervals cover the true settlement under AR(1) load-cell noise."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest
from scipy.signal import lfilter

from bridge_shadow.engine import Mapper, serial_mapper
from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.series import MonitoringData

SEEDS = 250
WINDOWS = 160  # 2 h 40 min of 60 s windows; the first 30 are the noise warm-up


def _ar1(rng: np.random.Generator, phi: float, shape: tuple[int, ...]) -> np.ndarray:
    """Stationary AR(1) with unit variance along the last axis, all series at once."""
    e = rng.normal(size=shape)
    x = np.empty(shape)
    x[..., 0] = e[..., 0]
    x[..., 1:], _ = lfilter(
        [np.sqrt(1.0 - phi**2)], [1.0, -phi], e[..., 1:], axis=-1, zi=(phi * e[..., 0])[..., None]
    )
    return x


def _seed_hits(case: tuple[np.ndarray, np.ndarray], config: ShadowConfig) -> np.ndarray:
    """One seed's record through the shadow: does its 95% interval hold the truth? [south, north, ellipse]."""
    noise, truth = case
    sur = placeholder_surrogate()
    stamps = 1_700_000_000 * 10**9 + np.arange(noise.shape[1], dtype=np.int64) * 10**9  # 1 Hz
    forces = sur.reactions(truth)[None, :] + noise.T
    temp_stamps = stamps[::10]
    data = MonitoringData.from_arrays(stamps, forces, temp_stamps, np.full(len(temp_stamps), 5.0))
    result = Shadow(config, sur).run(data)
    err = result.mean_m - truth
    sd = np.sqrt(np.diag(result.covariance_m2))
    hits = np.zeros(3, dtype=bool)
    hits[:2] = np.abs(err) <= 1.96 * sd
    hits[2] = err @ np.linalg.solve(result.covariance_m2, err) <= 5.991  # chi2(2) 95%
    return hits


def coverage(
    phi: float,
    config: ShadowConfig,
    seeds: int = SEEDS,
    windows: int = WINDOWS,
    mapper: Mapper = serial_mapper,
) -> np.ndarray:
    """Fraction of seeds whose 95% interval holds the truth: [south, north, 2-D ellipse].

    The seeds' records are drawn here, at once; ``mapper`` runs the shadow on each (in parallel
    on Dask with ``engine.client_mapper``: the same records, the same answers).
    """
    rng = np.random.default_rng(2024)
    n = windows * 60  # 1 Hz forces, 60 s windows
    sigma = np.array([150.0, 200.0])  # N per sample, above the paper's floor
    noise = _ar1(rng, phi, (seeds, 2, n)) * sigma[None, :, None]
    truth = rng.normal(0.0, 3e-4, (seeds, 2))  # drawn from the prior
    one = partial(_seed_hits, config=config)
    hits = np.array(mapper(one, [(noise[s], truth[s]) for s in range(seeds)]))
    return hits.mean(axis=0)


@pytest.mark.slow
@pytest.mark.parametrize("phi", [0.0, 0.95])
def test_adaptive_noise_keeps_95_percent_intervals_calibrated(phi: float, engine: Mapper) -> None:
    cov = coverage(phi, ShadowConfig(smoothing="none"), mapper=engine)
    print(f"phi = {phi}: coverage south {cov[0]:.2f}, north {cov[1]:.2f}, ellipse {cov[2]:.2f}")
    assert np.all((cov >= 0.90) & (cov <= 0.98)), cov


def test_iid_noise_model_is_overconfident_under_ar1() -> None:
    # the check above could fail: with R = Sigma_E / m (white-noise assumption) and phi = 0.95
    # the intervals are about 6x too narrow and cover far less than 95%.
    cov = coverage(
        0.95,
        ShadowConfig(smoothing="none", noise_mode="fixed", noise_sigma_n=[150.0, 200.0]),
        seeds=30,
        windows=60,
    )
    assert np.all(cov < 0.6), cov
