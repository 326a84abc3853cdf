"""Adjoint sensitivities (no extra solve) against finite differences of full FE solves.

Here the support spring is an FE element (in the calibration it is applied in closed form:
``test_calibrate_derivatives.py`` checks all 14 parameters that way). The derivatives are exact on
any mesh, so both use the same mesh coarser than ``coarse`` (``ROUGH``) to keep the solves cheap.
"""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.model.adjoint import parameter_derivatives
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.solution import solve_bridge

# a point away from the as-built one: springs, a partly open joint, a slipping connector
POINT = {
    "support_spring_south": 3e7,
    "support_spring_north": 8e7,
    "slab_joint_opening": 0.3,
    "connector_stiffness": 5e8,
}
# a spring (closed-form chain in the calibration, FE here), the hogging joints, and the concrete
# modulus (its thermal loads scale with it: the df term)
NAMES = ("support_spring_south", "slab_joint_opening", "E_concrete")
H = 1e-3  # relative step of the central difference in log(p)


@pytest.fixture(scope="module")
def case():
    import copy

    from test_calibrate_derivatives import ROUGH

    from bridge_shadow.model.config import BridgeConfig

    built = load_bridge_config()
    data = copy.deepcopy(built.data)
    data["mesh"]["coarse"] = dict(ROUGH)
    cfg = BridgeConfig(data, built.path, built.sha256).with_overrides(POINT)
    base = solve_bridge(cfg, "coarse")
    return cfg, base, parameter_derivatives(cfg, base, NAMES, "coarse")


@pytest.mark.parametrize("name", NAMES)
def test_adjoint_equals_central_difference(case, name) -> None:
    cfg, _, derivs = case
    v = cfg.params[name]
    plus = solve_bridge(cfg.with_overrides({name: v * np.exp(H)}), "coarse")
    minus = solve_bridge(cfg.with_overrides({name: v * np.exp(-H)}), "coarse")
    d = derivs[name]
    scale = np.abs(d.A).max()
    np.testing.assert_allclose(d.A, (plus.A - minus.A) / (2 * H), rtol=1e-4, atol=1e-5 * scale)
    np.testing.assert_allclose(d.u0, (plus.u0 - minus.u0) / (2 * H), rtol=1e-3, atol=1e-3)
    for c in d.thermal:
        fd = (plus.thermal[c] - minus.thermal[c]) / (2 * H)
        np.testing.assert_allclose(d.thermal[c], fd, rtol=1e-3, atol=1e-4 * max(np.abs(fd).max(), 1.0))


def test_support_spring_leaves_u0_and_an_absent_spring_has_no_sensitivity(case) -> None:
    cfg, base, derivs = case
    np.testing.assert_array_equal(derivs["support_spring_south"].u0, 0.0)  # set, not computed (adjoint)
    rigid = cfg.with_overrides({"support_spring_north": np.inf})
    d = parameter_derivatives(rigid, base, ("support_spring_north",), "coarse")["support_spring_north"]
    assert np.all(d.A == 0.0) and np.isinf(d.value)  # set, not computed: an absent spring
