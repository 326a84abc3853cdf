"""The surrogate's model uncertainty: its settlement covariance against samples of (A, u0)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.errors import ConfigError
from bridge_shadow.model.parameters import PARAMETERS
from bridge_shadow.model.surrogate_file import (
    Discrepancy,
    ModelCovariance,
    Surrogate,
    load_surrogate,
    save_surrogate,
)

A = np.array([[17.6e6, -11.9e6], [-11.9e6, 17.6e6]])
U0 = np.array([234e3, 234e3])


def _cov(rng: np.random.Generator) -> np.ndarray:
    g = rng.normal(size=(6, 6)) * np.array([2e5, 1e5, 1e5, 2e5, 500.0, 500.0])[:, None]
    return g @ g.T / 6


def test_linearized_covariance_matches_monte_carlo_of_the_inverse_map() -> None:
    rng = np.random.default_rng(3)
    cov = _cov(rng)
    s = Surrogate(A, U0, model_cov=cov)
    x = np.array([-10e-3, -10e-3])
    y = s.reactions(x)  # the measured reactions of a settlement x
    theta = rng.multivariate_normal(np.r_[A.ravel(), U0], cov, size=20000)
    xs = np.array([np.linalg.solve(t[:4].reshape(2, 2), y - t[4:]) for t in theta])
    np.testing.assert_allclose(s.model_covariance(x), np.cov(xs.T), rtol=0.05)


@pytest.mark.parametrize("kind", ["committed", "six", "discrepancy only"])
def test_the_float_hot_path_equals_the_matrix_formula(kind: str) -> None:
    """``ModelCovariance`` (the shadow's per-window form) against ``Surrogate.model_covariance``."""
    rng = np.random.default_rng(11)
    disc = Discrepancy((-0.01, -0.012), (0.0, 0.001), 0.3, 0.6)
    s = {
        "committed": load_surrogate(),  # 12 x 12 model uncertainty and a discrepancy
        "six": Surrogate(A, U0, model_cov=_cov(rng)),
        "discrepancy only": Surrogate(A, U0, discrepancy=disc),
    }[kind]
    fast = ModelCovariance(s)
    xs = np.vstack([rng.uniform(-0.04, 0.01, size=(50, 2)), [[0.0, 0.0], [-0.01, -0.012], [-0.03, 0.002]]])
    for x in xs:
        c00, c01, c11 = fast(float(x[0]), float(x[1]))
        ref = s.model_covariance(x)
        scale = float(np.max(np.abs(ref))) + 1e-300
        np.testing.assert_allclose([[c00, c01], [c01, c11]], ref, rtol=1e-10, atol=1e-12 * scale)


def test_no_model_uncertainty_adds_nothing_and_round_trips(tmp_path: Path) -> None:
    assert np.all(Surrogate(A, U0).model_covariance(np.ones(2)) == 0.0)  # exact: no terms to add
    s = Surrogate(A, U0, model_cov=_cov(np.random.default_rng(1)))
    back = load_surrogate(save_surrogate(s, tmp_path / "s.yaml"))
    np.testing.assert_allclose(back.model_cov, s.model_cov, rtol=1e-12)
    with pytest.raises(ConfigError):
        Surrogate(A, U0, model_cov=-np.eye(6))


def test_parameter_priors_are_consistent() -> None:
    for p in PARAMETERS.values():
        lo, hi = p.relative_bounds()
        assert lo < 0.0 <= hi or (p.upper is not None and hi == pytest.approx(0.0))
        assert p.log_sigma > 0


def test_a_step_carries_the_uncertainty_of_A_only() -> None:
    rng = np.random.default_rng(5)
    cov = _cov(rng)
    s = Surrogate(A, U0, model_cov=cov)
    step = np.array([-10e-3, -10e-3])
    dy = A @ step  # the measured change of the reactions for this step
    theta = rng.multivariate_normal(np.r_[A.ravel(), U0], cov, size=20000)
    steps = np.array([np.linalg.solve(t[:4].reshape(2, 2), dy) for t in theta])  # u0 cancels
    np.testing.assert_allclose(s.model_covariance(step, with_u0=False), np.cov(steps.T), rtol=0.05)
