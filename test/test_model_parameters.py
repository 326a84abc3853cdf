"""The parameter priors agree with config/bridge.yaml and say where they come from."""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.model.config import MAY_BE_INFINITE, load_bridge_config
from bridge_shadow.model.parameters import PARAMETERS


def test_prior_centres_are_the_bridge_yaml_values() -> None:
    """Every named parameter is in bridge.yaml; its prior centre is the file's value.

    Except the support springs: as built they are absent (.inf, a rigid support) and their prior
    centre is the physically reasoned stiffness of the real support system (parameters.py).
    """
    params = load_bridge_config().params
    for name, p in PARAMETERS.items():
        assert name in params, name
        if name in MAY_BE_INFINITE:
            assert np.isinf(params[name]) and np.isfinite(p.centre)
        else:
            assert p.centre == params[name], name


def test_fractions_are_bounded_at_one_and_every_prior_has_a_source() -> None:
    for p in PARAMETERS.values():
        assert p.source and p.unit
        if p.kind == "fraction":
            assert p.upper == 1.0 and p.centre == 1.0 and p.high == 1.0
        assert p.low < p.centre <= p.high and p.plausible(p.centre)
        assert p.source and len(p.source) > 40  # a sentence that names the source


# -- priors from sources: every derived number is recomputed from the formulas it cites ---------


def test_support_spring_prior_is_the_series_of_its_components() -> None:
    from bridge_shadow.model.parameters import SUPPORT_COMPONENTS, series_prior

    low, median, high = series_prior(SUPPORT_COMPONENTS)
    for side in ("support_spring_south", "support_spring_north"):
        p = PARAMETERS[side]
        # Monte Carlo of 400k draws: the table's rounded numbers within 3 %
        np.testing.assert_allclose([p.low, p.centre, p.high], [low, median, high], rtol=0.03)
    # a series is softer than its softest part: the median below every component's median
    assert median < min(m for m, *_ in SUPPORT_COMPONENTS.values())


def test_component_ranges_are_the_cited_formulas() -> None:
    from bridge_shadow.model.parameters import (
        SUPPORT_COMPONENTS,
        footing_stiffness,
        jack_oil_column_stiffness,
    )

    jack, _, found = (SUPPORT_COMPONENTS[k] for k in ("jack", "packing", "foundation"))
    # an unlocked 50 t cylinder: 0.7 GPa effective bulk modulus, 71 cm^2, 0.15 m of oil
    assert jack_oil_column_stiffness(0.7e9, 71e-4, 0.15) == pytest.approx(jack[1], rel=0.15)
    # Poulos and Davis: a rigid square footing E B / ((1 - nu^2) 0.82)
    assert footing_stiffness(10e6, 0.5) == pytest.approx(found[1], rel=0.05)
    assert footing_stiffness(300e6, 2.0) == pytest.approx(found[2], rel=0.05)
    assert footing_stiffness(60e6, 1.0) == pytest.approx(found[0], rel=0.05)


def test_bolted_connector_and_bearings_follow_the_eurocodes() -> None:
    from bridge_shadow.model.parameters import (
        bolt_bearing_stiffness,
        bolt_shear_stiffness,
        laminated_bearing_stiffness,
        series_stiffness,
    )

    # EN 1993-1-8 Table 6.11 for an M20 10.9 bolt: k_11 E = 16 d^2 f_ub / 16 = 400 kN/mm
    assert bolt_shear_stiffness(0.020, 1000e6) == pytest.approx(4.0e8, rel=1e-12)
    # k_12 E = 24 k_b k_t d f_u, k_t = 1.5 * 16.5 / 16 on the HEA340 flange
    assert bolt_bearing_stiffness(0.020, 0.0165, 360e6) == pytest.approx(24 * 1.25 * 1.546875 * 20 * 360e3)
    bolt = series_stiffness(bolt_shear_stiffness(0.020, 1000e6), bolt_bearing_stiffness(0.020, 0.0165, 360e6))
    per_metre = 8 * bolt
    assert per_metre == pytest.approx(PARAMETERS["connector_stiffness"].centre, rel=0.15)
    # EN 1337-3: a thin-layer pad of the flange width is the bearing centre, a thick one its low end
    assert laminated_bearing_stiffness(0.3, 0.4, 0.008, 3) == pytest.approx(
        PARAMETERS["bearing_stiffness"].centre, rel=0.05
    )
    assert laminated_bearing_stiffness(0.3, 0.3, 0.012, 5) == pytest.approx(
        PARAMETERS["bearing_stiffness"].low, rel=0.25
    )
    # the closed form itself: a 1 m^2 block 1 m thick of an incompressible layer (S large) -> E_b
    rigid_in_shear = laminated_bearing_stiffness(1.0, 1.0, 1.0, 1, shear_modulus_pa=1e16)
    assert rigid_in_shear == pytest.approx(2.0e9, rel=1e-6)
    assert series_stiffness(2.0, 2.0, float("inf")) == pytest.approx(1.0)


def test_the_plausible_range_is_the_priors_central_999_interval() -> None:
    from scipy import stats

    from bridge_shadow.model.parameters import Z_PLAUSIBLE

    assert stats.norm.cdf(Z_PLAUSIBLE) - stats.norm.cdf(-Z_PLAUSIBLE) == pytest.approx(0.999, abs=1e-12)
    for p in PARAMETERS.values():
        # the source's range is the prior's central 95 % interval (split normal in log)
        np.testing.assert_allclose(np.exp(p.to_log([-1.959963984540054, 0.0])), [p.low, p.centre], rtol=1e-12)
        if p.kind != "fraction":
            assert np.exp(p.to_log(1.959963984540054)) == pytest.approx(p.high, rel=1e-12)
        lo, hi = p.bounds
        assert lo < p.low and (hi > p.high or hi == p.upper)
        np.testing.assert_allclose(np.exp(p.to_log(-Z_PLAUSIBLE)), lo, rtol=1e-12)
        assert p.plausible(lo) and p.plausible(hi) and not p.plausible(0.99 * lo)
        for v in (lo, p.low, p.centre, p.high if p.kind != "fraction" else p.centre):
            assert np.exp(p.to_log(p.to_whitened(v))) == pytest.approx(v, rel=1e-12)


def test_calibrate_and_gap_read_one_table_of_ranges() -> None:
    """Calibrate's bounds and the gap's plausible ranges are the same numbers (issue 20)."""
    from bridge_shadow.calibrate.change import MeasuredChange
    from bridge_shadow.calibrate.forward import ForwardModel, SolutionStore
    from bridge_shadow.calibrate.problem import CalibrationProblem, PairData
    from bridge_shadow.effects import plausible_range

    cfg = load_bridge_config()
    names = ("bearing_stiffness", "connector_stiffness", "slab_joint_opening", "support_spring_south")
    pair = PairData("p", [-0.01, -0.01], [5e-4, 5e-4], MeasuredChange(np.zeros(2), np.eye(2)))
    prob = CalibrationProblem(ForwardModel(cfg, "coarse", names, SolutionStore()), [pair])
    lo = np.exp(prob.log_values(prob.lower))
    hi = np.exp(prob.log_values(prob.upper))
    for i, name in enumerate(names):
        p = PARAMETERS[name]
        if name == "support_spring_south":
            np.testing.assert_allclose(plausible_range("support_spring"), [lo[i], hi[i]], rtol=1e-12)
        else:
            r_lo, r_hi = plausible_range(name)  # the gap's relative change r around the centre
            gap = [(1 + r_lo) * p.centre, (1 + r_hi) * p.centre]
            np.testing.assert_allclose(gap, [lo[i], hi[i]], rtol=1e-9)  # 1 + r cancels near r = -1


def test_prior_sets_change_what_they_say() -> None:
    from bridge_shadow.errors import ConfigError
    from bridge_shadow.model.parameters import PRIOR_SETS, prior_table

    assert next(iter(PRIOR_SETS)) == "sources" and prior_table("sources") == PARAMETERS
    for name in ("first_written", "after_fit"):
        table = prior_table(name)
        changed = {k for k in PARAMETERS if table[k] != PARAMETERS[k]}
        assert changed == {"support_spring_south", "support_spring_north"}
    assert prior_table("first_written")["support_spring_south"].centre == 2e8
    assert prior_table("after_fit")["support_spring_south"].high == 1e9
    wide = prior_table("wide")
    for k, p in PARAMETERS.items():
        assert wide[k].centre == p.centre
        assert wide[k].sigma_low == pytest.approx(2 * p.sigma_low, rel=1e-12)
        assert wide[k].sigma_high == pytest.approx(2 * p.sigma_high, rel=1e-12)
    with pytest.raises(ConfigError):
        prior_table("optimistic")
