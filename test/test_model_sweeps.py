"""Parameter sweeps of the surrogate and the FE-free forward model built on them.

The sweep of the connector stiffness (the sharpest knee of the three swept parameters: the common
mode falls from 5.6 to 2.5 kN/mm over seven decades) is checked against FE solves between its
points, and the forward model (sweep + closed-form support springs) against the FE forward model
of the calibration, an independent route through the same FE.
"""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.calibrate.forward import ForwardModel, SolutionStore
from bridge_shadow.calibrate.surrogate_forward import SurrogateForward
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.parameters import PARAMETERS
from bridge_shadow.model.solution import solve_bridge
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.model.sweeps import SWEEP_POINTS, Sweep, compute_sweeps, read_sweeps, sweep_values

NAME = "connector_stiffness"


def _surrogate(cfg, level: str = "coarse") -> tuple[Surrogate, object]:
    """The surrogate of one FE solve (no Schur check), with the overrides it was solved with."""
    sol = solve_bridge(cfg, level)
    return Surrogate(sol.A, sol.u0, sol.thermal, {"overrides": dict(cfg.overrides)}), sol


@pytest.fixture(scope="module")
def swept():
    cfg = load_bridge_config()
    surrogate, base = _surrogate(cfg)
    sweeps = compute_sweeps(cfg, "coarse", names=(NAME,), base=base)
    return cfg, surrogate, sweeps


def test_sweep_values_span_the_plausible_range_and_hold_the_built_value() -> None:
    values = sweep_values(NAME, 1.6e9)
    lo, hi = PARAMETERS[NAME].bounds
    assert values[0] == pytest.approx(lo) and values[-1] == pytest.approx(hi)
    assert 1.6e9 in values and len(values) == SWEEP_POINTS + 1 and np.all(np.diff(values) > 0)


def test_sweep_interpolates_the_fe_between_its_points(swept) -> None:
    cfg, surrogate, sweeps = swept
    sw = sweeps[NAME]
    # exact at the built value and at a solved point
    assert np.all(sw.change(1.6e9)[0] == 0.0)  # exact: the same spline at the same point, less itself
    k = 2
    change = sw.change(sw.values[k])[0]
    np.testing.assert_allclose(surrogate.A.ravel() + change[:4], sw.A[k].ravel(), rtol=1e-9)
    # between points (geometric middles on both sides of the knee): within 3 % of A's diagonal
    for v in np.sqrt(sw.values[2:4] * sw.values[3:5]):
        fe = solve_bridge(cfg.with_overrides({NAME: float(v)}), "coarse")
        a = surrogate.A + sw.change(float(v))[0][:4].reshape(2, 2)
        np.testing.assert_allclose(np.diag(a), np.diag(fe.A), rtol=0.03)
    # the derivative is the slope of the curve: against a central difference of the interpolant
    v, h = 3e7, 1e-4
    d = sw.change(v)[1]
    fd = (sw.change(v * np.exp(h))[0] - sw.change(v * np.exp(-h))[0]) / (2 * h)
    np.testing.assert_allclose(d, fd, rtol=1e-5, atol=1e-6 * np.abs(d).max())
    # a round trip through the file format
    back = read_sweeps(block={NAME: sw.to_dict()})[NAME]
    np.testing.assert_allclose(back.change(5e7)[0], sw.change(5e7)[0], rtol=1e-12)
    with pytest.raises(Exception, match="ascending"):
        Sweep(NAME, 1.0, np.array([2.0, 1.0]), sw.A[:2], sw.u0[:2], {c: t[:2] for c, t in sw.thermal.items()})


def test_forward_model_without_fe_agrees_with_the_fe(swept) -> None:
    """Sweep + closed-form springs against FE re-solves at the same parameters (values, derivatives)."""
    cfg, surrogate, sweeps = swept
    names = (NAME, "support_spring_south", "support_spring_north")
    fe = ForwardModel(cfg, "coarse", names, SolutionStore())
    fast = SurrogateForward(surrogate, names, sweeps, {})
    for values in (
        {NAME: 3e7, "support_spring_south": 1e7, "support_spring_north": 3e7},
        {NAME: 4e8, "support_spring_south": 5e8, "support_spring_north": np.inf},
    ):
        a, b = fe.evaluate(values), fast.evaluate(values)
        np.testing.assert_allclose(b.A, a.A, rtol=0.02, atol=0.005 * np.abs(a.A).max())
        for case in a.thermal:
            np.testing.assert_allclose(b.thermal[case], a.thermal[case], rtol=0.02, atol=1.0)
        # the support springs' derivatives are exact closed forms on both routes
        np.testing.assert_allclose(b.dA[1:], a.dA[1:], rtol=0.03, atol=0.01 * np.abs(a.dA[1:]).max())
        np.testing.assert_allclose(b.dA[0], a.dA[0], rtol=0.1, atol=0.05 * np.abs(a.dA[0]).max())
    # springs the surrogate was built with are taken out before new ones go in
    sprung_cfg = cfg.with_overrides({"support_spring_south": 2e7, "support_spring_north": 4e7})
    sprung, _ = _surrogate(sprung_cfg)
    again = SurrogateForward(sprung, ("support_spring_south", "support_spring_north"), {}, {})
    rigid = again.evaluate({"support_spring_south": np.inf, "support_spring_north": np.inf})
    np.testing.assert_allclose(rigid.A, surrogate.A, rtol=1e-6)
