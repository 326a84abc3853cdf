"""``calibrate --check``: a surrogate scored on record pairs with a known imposed settlement."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.calibrate.change import MeasuredChange
from bridge_shadow.calibrate.check import check_pair
from bridge_shadow.cli import main
from bridge_shadow.model.surrogate_file import load_surrogate


def _run(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, dict]:
    code = main(argv)
    out = capsys.readouterr().out
    return code, json.loads(out) if "--json" in argv else {}


def test_check_against_monte_carlo_of_the_measurement_and_the_model(root: Path) -> None:
    """The interval is the measurement's and the model's spread, checked by sampling both."""
    sur = load_surrogate(root / "config" / "surrogate.yaml")
    assert sur.model_cov is not None
    d_r = sur.A @ np.array([-0.010, -0.008])
    cov_r = np.array([[4.0, 1.0], [1.0, 2.0]]) * 1e6  # N^2
    c = check_pair("p", MeasuredChange(d_r, cov_r), sur, np.array([-0.010, -0.008]), np.full(2, 5e-4))
    np.testing.assert_allclose(c.x_m, [-0.010, -0.008], rtol=1e-9)
    rng = np.random.default_rng(1)
    n = 40_000
    theta = rng.multivariate_normal(np.zeros(6), sur.model_cov[:6, :6], n)  # [A11, A12, A21, A22, u0...]
    noise = rng.multivariate_normal(np.zeros(2), cov_r, n)
    xs = np.empty((n, 2))
    for i in range(n):  # a reading through a perturbed A of a change that the true A made
        a = sur.A + theta[i, :4].reshape(2, 2)
        xs[i] = np.linalg.solve(sur.A, d_r + noise[i] - (a - sur.A) @ c.x_m)
    np.testing.assert_allclose(np.cov(xs.T), c.cov_m2, rtol=0.05, atol=1e-10)
    js = c.to_dict()
    assert js["held95"] == [True, True] and js["consistent95"] and js["chi2"] < 1e-12


def test_check_refuses_calibration_options(capsys, root: Path) -> None:
    code = main(["calibrate", "--check", str(root / "config" / "surrogate.yaml"), "--out", "/tmp/x.yaml"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--out" in err[0]


@pytest.mark.realdata
def test_real_pair_the_default_holds_the_lowering_and_agrees_with_the_online_shadow(
    munich_data: Path, root: Path, capsys
) -> None:
    code, js = _run(capsys, ["calibrate", "--check", str(root / "config" / "surrogate.yaml"), "--json"])
    p = js["pairs"][0]
    assert code == 0 and all(p["held95"]) and abs(p["common_error_rel"]) < 0.05
    code, js = _run(capsys, ["calibrate", "--check", str(root / "config" / "surrogate_fe.yaml"), "--json"])
    assert code == 1 and js["pairs"][0]["common_error_rel"] < -0.3  # the as-built model: about half
    # an independent reading of the same records: the online shadow's event (spline compensation,
    # GLR change detection, filter chain) over both records imported as one stream
    from bridge_shadow.estimate import Shadow, load_config
    from bridge_shadow.importers import import_csv

    folder = munich_data / "Settlements"
    data, _ = import_csv(
        [
            folder / "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
            folder / "UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
            folder / "TemperatureData2022-04-11.zip",
        ]
    )
    events = Shadow(load_config(), load_surrogate()).run(data).to_json()["events"]
    assert len(events) == 1
    np.testing.assert_allclose(events[0]["size_m"], p["x_m"], atol=1e-3)  # within 1 mm of 10
