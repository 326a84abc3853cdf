"""FE surrogate of the bridge (coarse mesh): A, u0, thermal, sensitivities against physics and data."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bridge_shadow.cli import main
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.solution import solve_bridge
from bridge_shadow.model.surrogate import (
    SENSITIVITY_PARAMETERS,
    closed_forms,
    compute_surrogate,
    load_sensitivities,
    write_surrogate,
)
from bridge_shadow.model.surrogate_file import load_surrogate

MEASURED_TOTAL_N = 470e3  # DESIGN 3: ~260 + 221 kN (2022-03-07), ~234 + 234 kN (2022-04-11)


@pytest.fixture(scope="module")
def cfg():
    return load_bridge_config()


@pytest.fixture(scope="module")
def coarse_run(cfg):
    return compute_surrogate(cfg, "coarse", sensitivities=True)


@pytest.fixture(scope="module")
def coarse(coarse_run):
    return coarse_run.surrogate


def test_A_symmetric_positive_definite(coarse):
    a = coarse.A
    np.testing.assert_allclose(a, a.T, rtol=1e-8)
    assert np.all(np.linalg.eigvalsh(0.5 * (a + a.T)) > 0)
    assert a[0, 0] > 0 and a[1, 1] > 0
    assert a[0, 1] < 0  # raising FRC-01 unloads FRC-02 (the deck twists about the south bearing)


def test_A_equals_schur_complement(coarse_run):
    rel = coarse_run.surrogate.provenance["schur_check"]["max_rel_diff"]
    assert rel < 1e-8
    np.testing.assert_allclose(coarse_run.schur, coarse_run.surrogate.A, rtol=1e-8)


def test_u0_total_matches_measured_central_reaction(coarse):
    # CIRCULAR: deck_width and slab_thickness were chosen to match this measured reaction
    # (config/bridge.yaml), so this checks that choice, not the model; the two-span share below and
    # the symmetry are the independent checks.
    assert coarse.u0.sum() == pytest.approx(MEASURED_TOTAL_N, rel=0.10)
    # symmetric structure and load: both bearings carry the same (the y restraint is horizontal)
    assert coarse.u0[0] == pytest.approx(coarse.u0[1], rel=1e-3)


def test_u0_is_the_two_span_share_of_the_dead_load(coarse):
    """R_mid = 1.25 w L of a continuous beam: 62.5 % of the total load goes to the middle."""
    prov = coarse.provenance
    assert coarse.u0.sum() / prov["total_dead_load_N"] == pytest.approx(0.625, rel=0.03)


def test_common_mode_lies_between_bare_steel_and_composite_closed_forms(coarse, cfg):
    """Settling both bearings together: per girder, 6 EI / L^3 with EI between steel and composite."""
    cf = closed_forms(cfg)
    common = coarse.A.sum(axis=1)  # reaction change per metre when both bearings rise together
    for k in common:
        assert cf["k_settle_steel_N_per_m"] < k < cf["k_settle_composite_N_per_m"]
        assert k > 0.85 * cf["k_settle_composite_N_per_m"]  # composite action is nearly full


def test_vertical_gradient_between_closed_forms(coarse, cfg):
    cf = closed_forms(cfg)
    v = coarse.thermal["vertical_gradient"]
    assert np.all(v < 0)  # top warmer lifts the deck off the middle support
    for value in v:
        assert cf["gradient_composite_N_per_K"] < value < cf["gradient_steel_N_per_K"]


def test_uniform_temperature_is_restraint_free(coarse):
    """Free longitudinal bearings and one alpha for steel and concrete: ~no reaction change."""
    u = coarse.thermal["uniform"]
    v = coarse.thermal["vertical_gradient"]
    assert np.all(np.abs(u) < 1e-2 * np.abs(v))
    assert np.all(np.abs(u) < 50.0)  # N/K


def test_uniform_temperature_bends_the_section_when_alphas_differ(cfg):
    """The test above could fail: with alpha_concrete = 1.0e-5 the mismatch curvature shows up."""
    sol = solve_bridge(cfg.with_overrides({"alpha_concrete": 1.0e-5}), "coarse")
    assert np.all(np.abs(sol.thermal["uniform"]) > 500.0)


def test_bearing_twist_restraint_stiffens_only_the_differential_mode(coarse, cfg):
    """A point (rocker) central bearing lets the girders twist: softer differential, same common mode."""
    rocker = solve_bridge(cfg.with_overrides({"central_bearing_twist_restraint": 0.0}), "coarse")
    np.testing.assert_allclose(rocker.A.sum(axis=1), coarse.A.sum(axis=1), rtol=2e-3)
    diff, diff_rocker = coarse.A[0, 0] - coarse.A[0, 1], rocker.A[0, 0] - rocker.A[0, 1]
    assert diff_rocker < 0.8 * diff
    # TUNED TARGET, not evidence: central_bearing_twist_restraint = 1 was chosen so that the paper's
    # +-0.7 mm for the measured 260 / 221 kN split follows (~28 kN/mm, DESIGN 2, 3); this line checks
    # the tuning. The calibration (README, Calibration) shows the data cannot fix this mode.
    assert 19.5e3 / 0.7e-3 == pytest.approx(diff, rel=0.15)


def test_transverse_gradient_loads_the_warm_south_girder(coarse):
    t = coarse.thermal["transverse_gradient"]
    assert t[0] > 0 > t[1]
    assert t[0] == pytest.approx(-t[1], rel=1e-3)


def test_lowering_both_bearings_unloads_both(coarse, cfg):
    du = coarse.A @ np.array([-0.01, -0.01])
    cf = closed_forms(cfg)
    assert np.all(du < 0)
    for value in du:
        assert -0.01 * cf["k_settle_composite_N_per_m"] < value < -0.01 * cf["k_settle_steel_N_per_m"]


def test_sensitivities_match_a_direct_perturbation(coarse_run, cfg):
    """The derivative per unit relative change predicts the response at -5 % (fractions sit at 1)."""
    sens = coarse_run.sensitivities
    assert set(SENSITIVITY_PARAMETERS) <= set(sens)
    base = coarse_run.base
    for name in ("bearing_stiffness", "connector_stiffness", "slab_joint_opening"):
        minus = solve_bridge(cfg.with_overrides({name: cfg.params[name] * 0.95}), "coarse")
        d_a = np.asarray(sens[name]["A"])
        np.testing.assert_allclose(base.A - minus.A, 0.05 * d_a, rtol=0.05, atol=1e-3 * np.abs(d_a).max())
    for name in ("support_spring_south", "support_spring_north"):  # absent as built: no relative change
        assert np.all(np.asarray(sens[name]["A"]) == 0.0)  # set, not computed: zeros for an absent spring
        i = ("support_spring_south", "support_spring_north").index(name)
        soft = solve_bridge(cfg.with_overrides({name: 1e10}), "coarse")  # compliance 1e-10 m/N
        d_c = np.asarray(sens[name]["compliance"]["A"])
        scale = np.abs(d_c).max() * 1e-10
        np.testing.assert_allclose(soft.A - base.A, 1e-10 * d_c, rtol=0.02, atol=1e-4 * scale)
        assert d_c[i, i] < 0
    # stiffer bearings and joints make the structure stiffer at the bearings
    assert np.all(np.diag(sens["bearing_stiffness"]["A"]) > 0)
    assert np.all(np.sum(sens["connector_stiffness"]["A"], axis=1) > 0)


@pytest.mark.slow
def test_mesh_convergence_coarse_to_default(coarse, cfg):
    default = solve_bridge(cfg, "default")
    np.testing.assert_allclose(coarse.A.sum(axis=1), default.A.sum(axis=1), rtol=2e-3)
    np.testing.assert_allclose(coarse.A, default.A, rtol=0.03)
    np.testing.assert_allclose(coarse.u0, default.u0, rtol=2e-3)
    for case in ("vertical_gradient", "transverse_gradient"):
        np.testing.assert_allclose(coarse.thermal[case], default.thermal[case], rtol=0.01)


def test_write_and_load_round_trip(coarse_run, tmp_path):
    path = write_surrogate(coarse_run, tmp_path / "s.yaml")
    back = load_surrogate(path)
    # exact: the floats written and read back (a copy through the file, no arithmetic)
    np.testing.assert_array_equal(back.A, coarse_run.surrogate.A)
    np.testing.assert_array_equal(back.u0, coarse_run.surrogate.u0)
    for k, v in coarse_run.surrogate.thermal.items():
        np.testing.assert_array_equal(back.thermal[k], v)
    sens = load_sensitivities(path)
    np.testing.assert_array_equal(
        sens["bearing_stiffness"]["A"], coarse_run.sensitivities["bearing_stiffness"]["A"]
    )
    assert back.provenance["mesh"] == "coarse"


def test_cli_json_overrides_vtk_with_deflected_shapes_and_png(tmp_path, capsys):
    """One FE run of the CLI: its JSON, a ``--set`` override, the file, the VTK and the PNG."""
    meshio = pytest.importorskip("meshio")
    out = tmp_path / "s.yaml"
    code = main(
        [
            "surrogate",
            "--mesh",
            "coarse",
            "--no-sensitivities",
            "--no-sweeps",  # the sweeps: test_model_sweeps.py
            "--set",
            "composite_action=0.5",
            "--out",
            str(out),
            "--vtk",
            str(tmp_path / "vtk"),
            "--png",
            str(tmp_path / "model.png"),
            "--json",
        ]
    )
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert {"A", "u0", "thermal", "provenance"} <= set(doc)
    assert doc["provenance"]["overrides"] == {"composite_action": 0.5}
    assert set(doc["thermal"]) == {"uniform", "vertical_gradient", "transverse_gradient"}
    assert out.is_file()
    mesh = meshio.read(doc["provenance"]["vtk"])
    assert len(mesh.points) == doc["provenance"]["nodes"]
    names = set(mesh.point_data)
    for case in (
        "settle FRC-01",
        "settle FRC-02",
        "dead",
        "uniform",
        "vertical_gradient",
        "transverse_gradient",
    ):
        assert f"{case}:displacement" in names
    # the unit settlement of FRC-01 lifts its ground node (x 15, y -1, flange level) by exactly 1 m,
    # the flange above it by 1 m less the bearing's compression
    at = np.flatnonzero(np.linalg.norm(mesh.points - [15.0, -1.0, 0.018], axis=1) < 1e-9)
    lifted = np.sort(mesh.point_data["settle FRC-01:displacement"][at, 2])
    assert len(at) == 2
    assert lifted[1] == pytest.approx(1.0, abs=1e-12)
    assert 0.99 < lifted[0] < 1.0
    assert (tmp_path / "model.png").stat().st_size > 10_000


def test_cli_writes_nothing_without_out(root, capsys):
    """The README's `surrogate --json` must not touch the committed files (issue 13, item 9)."""
    before = {p.name: p.read_bytes() for p in (root / "config").glob("surrogate*.yaml")}
    code = main(["surrogate", "--mesh", "coarse", "--no-sensitivities", "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["provenance"]["written_to"] is None
    assert {p.name: p.read_bytes() for p in (root / "config").glob("surrogate*.yaml")} == before


def test_cli_bad_parameter_is_one_line_exit_2(tmp_path, capsys):
    code = main(["surrogate", "--mesh", "coarse", "--set", "nonsense=1", "--out", str(tmp_path / "s.yaml")])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nonsense" in err[0]
