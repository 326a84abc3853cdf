"""The verification suite: published shell benchmarks, patch tests and closed forms meet their tolerances."""

from __future__ import annotations

import json

import pytest

from bridge_shadow.cli import main
from bridge_shadow.fe import verify
from bridge_shadow.fe.verify import Case, run_cases


@pytest.fixture(scope="module")
def cases() -> dict[str, Case]:
    return {c.name: c for c in run_cases(quick=True)}


def test_every_toleranced_case_passes(cases: dict[str, Case]) -> None:
    failed = [(c.name, c.computed, c.reference) for c in cases.values() if c.passed is False]
    assert not failed


@pytest.mark.parametrize(
    ("name", "reference", "rtol"),
    [
        ("scordelis_lo_16x16", 0.3024, 0.01),
        ("pinched_cylinder_32x32", 1.8248e-5, 0.02),
        ("macneal_rectangular_inplane", 0.1081, 0.02),
        ("macneal_rectangular_outofplane", 0.4321, 0.02),
        ("ss_plate_8x8", 0.0040624, 0.01),
        ("twisted_beam_inplane", 0.005424, 0.02),  # warped quads
        ("twisted_beam_outofplane", 0.001754, 0.02),
        ("two_span_beam_uniform_load", 5 * 25e3 * 15.0 / 4, 0.005),
    ],
)
def test_published_values(cases: dict[str, Case], name: str, reference: float, rtol: float) -> None:
    assert cases[name].reference == reference
    assert cases[name].computed == pytest.approx(reference, rel=rtol)


def test_scordelis_lo_converges(cases: dict[str, Case]) -> None:
    errors = [abs(cases[f"scordelis_lo_{n}x{n}"].ratio - 1) for n in (4, 8, 16)]  # type: ignore[operator]
    assert errors[0] > errors[1] > errors[2]


def test_patch_tests_exact(cases: dict[str, Case]) -> None:
    assert cases["patch_membrane"].computed < 1e-8
    assert cases["patch_bending"].computed < 1e-8


def test_settlement_sign_and_value(cases: dict[str, Case]) -> None:
    # 10 mm downward settlement of the middle support unloads it by 6 EI delta / L^3
    c = cases["two_span_beam_settlement"]
    assert c.computed < 0
    assert c.computed == pytest.approx(-6 * 2.1e11 * 6.447e-3 * 0.01 / 15.0**3, rel=1e-6)


def test_shell_girder_close_to_beam_theory(cases: dict[str, Case]) -> None:
    # reported, not toleranced in verify; shear deformation makes the shell girder a little softer
    for kind in ("settlement", "gradient", "uniform_load"):
        ratio = cases[f"two_span_shell_{kind}"].ratio
        assert ratio is not None and 0.95 < ratio <= 1.0
    assert cases["two_span_shell_uniform_temperature"].passed


def test_thermal_strip_exact() -> None:
    c = verify.thermal_strip(4)
    assert c.computed == pytest.approx(c.reference, rel=1e-9)


def test_cli_json_contract(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["verify", "--json", "--quick"])
    out = json.loads(capsys.readouterr().out)
    keys = ["name", "computed", "reference", "ratio", "tolerance", "mesh", "dofs", "seconds", "passed"]
    assert code == 0
    assert len(out["cases"]) >= 20
    assert all(list(c) == keys for c in out["cases"])
