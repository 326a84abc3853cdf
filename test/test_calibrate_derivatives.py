"""Every derivative the calibration uses, against central finite differences of full FE solves.

``ForwardModel.evaluate`` gives ``d(A, u0, thermal) / d log p`` for each of the 14 parameters
with a prior: the FE ones by the adjoint route (``model.adjoint``, no extra solve), the support
springs in closed form (``calibrate.forward.series_springs``), and the FE ones through the springs
in series (``S dA S'``). Each is compared with ``(f(p e^h) - f(p e^-h)) / 2h`` of full solves at a
point away from the as-built one (springs, a partly open hogging joint, partial composite action,
slipping connectors). ``CalibrationProblem``'s Jacobian (whitened residuals, jack-error columns,
the uniform thermal term) is compared with central differences of its residuals, and the
placeholder bearing sensitivity (``model.sensitivities``) with the exact series-spring map.

The derivatives are exact for whatever mesh the model has, so a mesh coarser than ``coarse``
(1.25 m elements, one across a web: 880 nodes) serves and keeps the 25 FE solves to a few
seconds. Tolerances: ``rtol`` 1e-3 of the difference, plus ``atol`` 1e-7 of the quantity's own
scale (central differences with ``h = 1e-4`` agree to 1e-9..1e-7 of it: truncation ``h^2`` and the
solver's rounding over ``2h``); every derivative checked is at least ten times that ``atol``.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from bridge_shadow.calibrate.change import MeasuredChange
from bridge_shadow.calibrate.forward import Evaluation, ForwardModel
from bridge_shadow.calibrate.problem import CalibrationProblem, PairData
from bridge_shadow.model.config import BridgeConfig, load_bridge_config
from bridge_shadow.model.parameters import PARAMETERS

#: Relative step in log(p) (and in the whitened coordinates of the problem).
H = 1e-4
RTOL, ATOL_SCALE = 1e-3, 1e-7
#: A point away from the as-built one (fractions inside (0, 1) so that p e^h is still valid).
POINT = {
    "support_spring_south": 3e7,
    "support_spring_north": 8e7,
    "slab_joint_opening": 0.3,
    "composite_action": 0.8,
    "connector_stiffness": 5e8,
}
#: Coarser than the ``coarse`` level: one element across a web, 1.25 m along the girders.
ROUGH = {"dx": 1.25, "web": 1, "half_flange": 1, "cantilever": 1, "between": 2, "connector": 1, "brace": 1}


@pytest.fixture(scope="module")
def forward() -> ForwardModel:
    base = load_bridge_config()
    data = copy.deepcopy(base.data)
    data["mesh"]["coarse"] = dict(ROUGH)
    cfg = BridgeConfig(data, base.path, base.sha256).with_overrides(POINT)
    return ForwardModel(cfg, "coarse", tuple(PARAMETERS))


@pytest.fixture(scope="module")
def at_point(forward: ForwardModel) -> Evaluation:
    return forward.evaluate({}, derivatives=True)


def _close(derivative: np.ndarray, fd: np.ndarray, scale: float, what: str) -> None:
    atol = ATOL_SCALE * scale
    np.testing.assert_allclose(derivative, fd, rtol=RTOL, atol=atol, err_msg=what)


def test_fourteen_parameters_are_calibrated() -> None:
    assert len(PARAMETERS) == 14


@pytest.mark.parametrize("name", list(PARAMETERS))
def test_parameter_derivative_equals_central_difference(forward, at_point, name: str) -> None:
    q = forward.names.index(name)
    v = forward.cfg.params[name]
    plus = forward.evaluate({name: v * np.exp(H)}, derivatives=False)
    minus = forward.evaluate({name: v * np.exp(-H)}, derivatives=False)
    fd_a = (plus.A - minus.A) / (2 * H)
    fd_u0 = (plus.u0 - minus.u0) / (2 * H)
    a_scale = np.abs(at_point.A).max()
    u_scale = np.abs(at_point.u0).max()
    t_scale = max(np.abs(t).max() for t in at_point.thermal.values())
    _close(at_point.dA[q], fd_a, a_scale, f"{name}: dA")
    _close(at_point.du0[q], fd_u0, u_scale, f"{name}: du0")
    for case in at_point.thermal:
        fd_t = (plus.thermal[case] - minus.thermal[case]) / (2 * H)
        _close(at_point.dthermal[case][q], fd_t, t_scale, f"{name}: dthermal {case}")
    # the check says something: this parameter moves A (or u0) well beyond the tolerance
    assert max(np.abs(fd_a).max() / a_scale, np.abs(fd_u0).max() / u_scale) > 10 * ATOL_SCALE


def test_calibration_jacobian_equals_central_difference(forward) -> None:
    names = ("support_spring_south", "support_spring_north", "E_concrete", "slab_joint_opening")
    model = ForwardModel(forward.cfg, "coarse", names, forward.store)  # the solves are shared
    change = MeasuredChange(
        dR_n=np.array([-2.3e4, -4.2e4]),
        cov_n2=np.array([[2.5e3**2, 1.0e6], [1.0e6, 1.8e3**2]]),
        air_temp_change_k=2.0,  # the uniform thermal term enters the residual and its Jacobian
    )
    pair = PairData("lowering", np.array([-0.01, -0.01]), np.array([5e-4, 5e-4]), change)
    problem = CalibrationProblem(model, [pair])
    u = np.array([0.3, -0.2, 0.1, -0.4, 0.5, -0.5])  # parameters, then the two jack errors
    r, jac = problem(u)
    assert jac is not None and jac.shape == (r.size, problem.dim)
    for k in range(problem.dim):
        step = np.zeros(problem.dim)
        step[k] = H
        fd = (problem(u + step, jacobian=False)[0] - problem(u - step, jacobian=False)[0]) / (2 * H)
        scale = np.abs(jac[:, k]).max()
        assert scale > 0.1, problem.labels()[k]  # every coordinate moves the residual
        np.testing.assert_allclose(jac[:, k], fd, rtol=1e-5, atol=1e-7 * scale, err_msg=problem.labels()[k])


def test_placeholder_bearing_sensitivity_is_the_derivative_of_the_series_spring() -> None:
    """``dA/dr = A_e A_e / k_b`` (and ``u0``, thermal through ``A_e A^-1``) of a bearing in series."""
    from bridge_shadow.model.sensitivities import (
        BEARING_STIFFNESS_N_PER_M,
        placeholder_sensitivities,
        support_spring_change,
    )
    from bridge_shadow.model.surrogate_file import load_surrogate

    s = load_surrogate()
    k_b = BEARING_STIFFNESS_N_PER_M
    sens = placeholder_sensitivities(s)["bearing_stiffness"]
    h = 1e-5

    def bearing(r: float):
        return support_spring_change(s, [(1 + r) * k_b] * 2)[0]

    plus, minus = bearing(h), bearing(-h)
    a_e = np.linalg.inv(np.linalg.inv(s.A) + np.eye(2) / k_b)
    fd_a = (plus.A - minus.A) / (2 * h)
    np.testing.assert_allclose(sens.dA, fd_a, rtol=1e-5, atol=1e-9 * np.abs(a_e).max())
    np.testing.assert_allclose(sens.du0, (plus.u0 - minus.u0) / (2 * h), rtol=1e-5, atol=1e-6)
    for case, t in sens.dthermal.items():
        fd = (plus.thermal[case] - minus.thermal[case]) / (2 * h)
        np.testing.assert_allclose(t, fd, rtol=1e-5, atol=1e-9 * max(np.abs(fd).max(), 1.0))
