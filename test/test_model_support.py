"""Support-system springs, slab-joint opening and the as-built validation of bridge.yaml (coarse mesh)."""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.calibrate.forward import series_springs
from bridge_shadow.errors import ConfigError
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.mesh import build_mesh, hogging_zone
from bridge_shadow.model.solution import solve_bridge
from bridge_shadow.model.surrogate import schur_A

K_S, K_N = 2.0e7, 6.0e7


@pytest.fixture(scope="module")
def cfg():
    return load_bridge_config()


@pytest.fixture(scope="module")
def rigid(cfg):
    return solve_bridge(cfg, "coarse")


@pytest.fixture(scope="module")
def sprung(cfg):
    return solve_bridge(
        cfg.with_overrides({"support_spring_south": K_S, "support_spring_north": K_N}), "coarse"
    )


def test_as_built_has_no_support_springs_and_closed_joints(cfg) -> None:
    assert np.isinf(cfg.params["support_spring_south"]) and np.isinf(cfg.params["support_spring_north"])
    assert cfg.params["slab_joint_opening"] == 1.0


def test_series_springs_closed_form_equals_the_fe(rigid, sprung) -> None:
    """A_eff = (A^-1 + diag(1/k_s, 1/k_n))^-1 exactly; thermal scales by A_eff A^-1; u0 unchanged."""
    c = np.diag([1 / K_S, 1 / K_N])
    a_eff = np.linalg.inv(np.linalg.inv(rigid.A) + c)
    np.testing.assert_allclose(sprung.A, a_eff, rtol=1e-9)
    for case, t in rigid.thermal.items():
        np.testing.assert_allclose(
            sprung.thermal[case], a_eff @ np.linalg.solve(rigid.A, t), rtol=1e-8, atol=1e-6
        )
    # the supports are set under the dead load: the springs do not move u0 (jacks preset instead)
    np.testing.assert_allclose(sprung.u0, rigid.u0, rtol=1e-9)
    assert np.all(sprung.jack_preset > 0)  # the jacks were raised by the springs' compression
    np.testing.assert_allclose(sprung.jack_preset, rigid.u0 / np.array([K_S, K_N]), rtol=0.05)
    a_e, _, t_e, *_ = series_springs(rigid.A, rigid.u0, rigid.thermal, np.array([K_S, K_N]))
    np.testing.assert_allclose(a_e, sprung.A, rtol=1e-9)
    np.testing.assert_allclose(t_e["vertical_gradient"], sprung.thermal["vertical_gradient"], rtol=1e-8)


def test_schur_complement_on_the_foundation_dofs(cfg, sprung) -> None:
    c = cfg.with_overrides({"support_spring_south": K_S, "support_spring_north": K_N})
    np.testing.assert_allclose(schur_A(c, sprung.mesh), sprung.A, rtol=1e-8)


def test_asymmetric_springs_split_a_common_lowering(sprung) -> None:
    """The stiffer support takes the larger drop: the only symmetric-structure way to an unequal split."""
    d_r = sprung.A @ np.array([-0.01, -0.01])
    assert d_r[1] < d_r[0] < 0


def test_hogging_zone_of_a_two_span_beam() -> None:
    assert hogging_zone([15.0, 15.0]) == pytest.approx((11.25, 18.75))
    # unequal spans: the zero-moment points of M(x) = R1 x - w x^2 / 2 from a direct three-moment solve
    l1, l2, w = 12.0, 18.0, 1.0
    m_c = -w * (l1**3 + l2**3) / (8 * (l1 + l2))
    r1 = w * l1 / 2 + m_c / l1
    x = np.linspace(0, l1, 100001)
    m = r1 * x - w * x**2 / 2
    first_hogging = x[np.argmax((m < 0) & (x > 0.1))]
    assert hogging_zone([l1, l2])[0] == pytest.approx(first_hogging, abs=1e-3)


def test_slab_joint_opening_softens_the_hogging_joints_only(cfg, rigid) -> None:
    mesh = build_mesh(cfg.with_overrides({"slab_joint_opening": 0.01}), "coarse")
    hog, sag = mesh.springs["slab_joint_hogging"], mesh.springs["slab_joint"]
    np.testing.assert_allclose(np.unique(mesh.nodes[hog.node_i, 0]), [12.5, 15.0, 17.5], rtol=0, atol=1e-9)
    assert np.all(hog.k[:, 0] < 0.011 * sag.k[: len(hog.k), 0].max())
    np.testing.assert_allclose(hog.k[:, 1], sag.k[: len(hog.k), 1])  # shear kept
    opened = solve_bridge(cfg.with_overrides({"slab_joint_opening": 1e-3}), "coarse")
    assert np.all(opened.A.sum(axis=1) < 0.7 * rigid.A.sum(axis=1))  # composite action lost over the support


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("bearing_stiffness", np.inf),
        ("slab_joint_opening", 0.0),
        ("slab_joint_opening", 1.5),
        ("composite_action", 0.0),
    ],
)
def test_bad_values_are_refused(cfg, name, value) -> None:
    with pytest.raises(ConfigError):
        cfg.with_overrides({name: value})


def test_every_named_parameter_is_overridable(cfg) -> None:
    from bridge_shadow.model.parameters import PARAMETERS

    for name, p in PARAMETERS.items():
        assert cfg.with_overrides({name: p.low}).params[name] == p.low
