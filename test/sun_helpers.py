"""Shared by the sun-term tests: random fit windows with a sun covariate, and the chunk/checkpoint check."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bridge_shadow.estimate import Shadow
from bridge_shadow.estimate.compensation.fit import Compensation
from bridge_shadow.estimate.compensation.sums import WindowRows
from bridge_shadow.series import MonitoringData


def sun_rows(comp: Compensation, n: int, seed: int) -> tuple[WindowRows, np.ndarray]:
    """Random windows of two segments: temperatures, a sun covariate, weights, forces.

    The forces hold -3000 / -4000 N per unit of the covariate (0.75 / 0.8 K at -4 / -5 kN/K).
    """
    rng = np.random.default_rng(seed)
    t = rng.uniform(-5.0, 25.0, n)
    s = np.clip(np.sin(np.linspace(0, 9 * np.pi, n)), 0.0, None) * rng.uniform(0.3, 1.0, n)
    seg = (np.arange(n) >= n // 2).astype(np.int64)
    y = np.c_[40.0 * t - 3000.0 * s + 500.0 * seg, -20.0 * t - 4000.0 * s - 800.0 * seg]
    y += rng.normal(0.0, 50.0, (n, 2))
    m = rng.integers(5, 60, (n, 2)).astype(float)
    i0, bv = comp.basis_rows(np.c_[t, t], s)
    return WindowRows(np.arange(n, dtype=np.int64), m, y, np.c_[t, t], i0, bv, seg), s


def assert_chunks_and_checkpoint_change_nothing(
    cfg, sur, data: MonitoringData, whole, tmp_path: Path
) -> None:
    """``data`` fed in chunks, and stopped at its middle, checkpointed and resumed: ``whole``'s result.

    ``cfg`` names the checkpoint (``checkpoint_path`` in ``tmp_path``); returns nothing, asserts.
    """
    chunked = Shadow(cfg, sur).run(data, chunk=997)
    np.testing.assert_allclose(chunked.mean_m, whole.mean_m, rtol=1e-9, atol=1e-12)
    cut = int(np.median(data.forces["frc_01"].stamp_ns))

    def part(lo: int | None, hi: int | None) -> MonitoringData:
        return data.select(lambda t: (t >= (lo or 0)) & (t < (hi or 2**62)), by="stamp_ns")

    a = Shadow(cfg, sur)
    a.run(part(None, cut), flush=False)
    a.save_checkpoint()
    b = Shadow.resume(Path(cfg.checkpoint_path), cfg, sur)
    if a.fit is not None:
        np.testing.assert_allclose(b.fit.sun_evidence, a.fit.sun_evidence, rtol=1e-12)
    res = b.run(part(cut, None))
    np.testing.assert_allclose(res.mean_m, whole.mean_m, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.covariance_m2, whole.covariance_m2, rtol=1e-8, atol=1e-18)
