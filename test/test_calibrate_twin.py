"""Calibration on truth-twin pairs whose reality differs from the model (support springs in series).

The twin's reality is the coarse FE model with support springs the estimator's model lacks; the
calibration sees only the bags (never truth.yaml) and must recover the springs within its
posterior intervals, and its surrogate must map a withheld, later 20 mm lowering to within 5 %.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from bridge_shadow.calibrate.change import measured_change, record_level
from bridge_shadow.calibrate.records import load_record
from bridge_shadow.cli import main
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.bag import write_twin_bag
from bridge_shadow.twin.reality import reality_from_parameters
from bridge_shadow.twin.truth import read_truth

REALITY = {"support_spring_south": 2.0e7, "support_spring_north": 6.0e7}
RECORD = {"days": 15 / 1440, "rate_hz": 2.0, "seed": 4, "effects": {"traffic": 2.5e4}}


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("calib_twin")
    reality = reality_from_parameters(REALITY, "coarse")
    kw = {"surrogate": reality.surrogate, "sensitivities_block": reality.block, "reality": reality.info}
    bags = {}
    for name, start, step in (
        ("before", "2022-04-11T08:36", ()),
        ("after", "2022-04-11T09:20", [(0.0, -0.010, -0.010)]),
        ("after_20mm", "2022-04-11T10:00", [(0.0, -0.020, -0.020)]),
    ):
        bags[name], _ = write_twin_bag(root / name, start=start, steps=step, **RECORD, **kw)
    spec = {
        "mesh": "coarse",
        "pairs": [
            {
                "name": "twin_10mm",
                "before": str(bags["before"]),
                "after": str(bags["after"]),
                "imposed_m": [-0.010, -0.010],
                "imposed_sd_m": [1e-4, 1e-4],
            }
        ],
        "explanations": {"as_built": [], "support_springs": list(REALITY)},
    }
    bags["spec"] = root / "calibration.yaml"
    bags["spec"].write_text(yaml.safe_dump(spec))
    bags["out"] = root / "calibrated.yaml"
    return bags


@pytest.fixture(scope="module")
def calibrated(pair):
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["calibrate", str(pair["spec"]), "--out", str(pair["out"]), "--json", "--no-sweeps"])
    assert code == 0
    return json.loads(buf.getvalue())


def test_a_pair_given_with_the_wrong_sign_is_said_to_fit_nothing(pair, calibrated, tmp_path, capsys) -> None:
    """The twin's 10 mm pair given as +10 mm: no explanation fits the measured change, and it is said.

    The evidence ranks the explanations against each other; on stand-ins of the real day a 20 mm
    pair given as +20 mm was explained at probability 1.00 (chi2 112.7 on 6 numbers) and would
    have been written as the model without a word. The pair as made fits (no misfit).
    """
    import contextlib
    import io

    assert calibrated["misfit"] is None and calibrated["warnings"] == []
    spec = yaml.safe_load(pair["spec"].read_text())
    spec["pairs"][0]["imposed_m"] = [0.010, 0.010]
    wrong = tmp_path / "wrong_sign.yaml"
    wrong.write_text(yaml.safe_dump(spec))
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["calibrate", str(wrong), "--json", "--no-sweeps"]) == 0
    js = json.loads(buf.getvalue())
    bad = js["misfit"]
    assert bad is not None and bad["kind"] == "data" and bad["chi2_data"] > bad["bound"]
    assert js["warnings"] and "WARN: no explanation fits the measured changes" in capsys.readouterr().err


def test_the_twin_reality_differs_from_the_estimators_model(pair, root) -> None:
    truth = read_truth(pair["after"])
    assert truth["reality"]["source"] == "fe" and truth["reality"]["overrides"] == REALITY
    as_built = load_surrogate(root / "config" / "surrogate_fe.yaml").A
    real = np.array(truth["surrogate"]["A"])
    assert np.all(np.diag(real) < 0.8 * np.diag(as_built))  # soft supports under both bearings
    d_r = real @ [-0.01, -0.01]
    assert d_r[1] < 1.5 * d_r[0]  # and an unequal split of a common lowering (as-built: equal)


def test_calibration_recovers_the_support_springs_within_their_intervals(calibrated) -> None:
    assert calibrated["chosen"] == "support_springs"
    table = {r["name"]: r for r in calibrated["explanations"]}
    assert table["support_springs"]["delta_log_evidence"] == 0.0  # exact: the chosen one less itself
    assert table["as_built"]["delta_log_evidence"] < -10.0  # the as-built model cannot explain it
    for name, truth in REALITY.items():
        post = table["support_springs"]["map"][name]
        assert post["low95"] < truth < post["high95"], (name, post)
        assert post["posterior_to_prior_sd"] < 0.5  # the data, not the prior, fixed it


def test_calibrated_surrogate_maps_a_withheld_20mm_lowering_within_5_percent(pair, calibrated, root) -> None:
    surrogate = load_surrogate(pair["out"])
    assert surrogate.model_cov is not None and surrogate.provenance["calibration"]["chosen_explanation"]
    change = measured_change(
        record_level(load_record([pair["before"]])), record_level(load_record([pair["after_20mm"]]))
    )
    x = np.linalg.solve(surrogate.A, change.dR_n)
    np.testing.assert_allclose(x, [-0.020, -0.020], rtol=0.05)
    # the uncalibrated model misses it by far more
    fe = load_surrogate(root / "config" / "surrogate_fe.yaml")
    assert np.abs(np.linalg.solve(fe.A, change.dR_n) / -0.020 - 1.0).max() > 0.15


def test_check_passes_the_calibrated_surrogate_on_the_withheld_lowering_and_fails_the_as_built(
    pair, calibrated, root, tmp_path, capsys
) -> None:
    """``calibrate --check`` on a later pair: what a user runs when the next lowering is recorded."""
    later = {"name": "later_20mm", "before": str(pair["before"]), "after": str(pair["after_20mm"])}
    spec = tmp_path / "later.yaml"
    spec.write_text(
        yaml.safe_dump({"pairs": [{**later, "imposed_m": [-0.02, -0.02], "imposed_sd_m": [1e-4, 1e-4]}]})
    )
    capsys.readouterr()
    assert main(["calibrate", str(spec), "--check", str(pair["out"]), "--json"]) == 0
    p = json.loads(capsys.readouterr().out)["pairs"][0]
    assert abs(p["common_error_rel"]) < 0.05 and p["held95"] == [True, True] and p["consistent95"]
    assert min(p["model_sigma_m"]) > 0  # the calibrated model's own uncertainty is in the interval
    fe = root / "config" / "surrogate_fe.yaml"
    assert main(["calibrate", str(spec), "--check", str(fe)]) == 1
    text = capsys.readouterr().out
    assert "MISSES" in text and "NOT consistent" in text and "no model uncertainty" in text


def test_synth_reality_from_a_surrogate_file_and_a_bad_calibration_file(root, tmp_path, capsys) -> None:
    fe = root / "config" / "surrogate_fe.yaml"
    bag = tmp_path / "bag"
    argv = ["synth", "--out", str(bag), "--days", "0.01", "--rate", "0.1", "--reality-surrogate", str(fe)]
    assert main(argv) == 0
    truth = read_truth(bag)
    assert truth["reality"] == {"source": "file", "path": str(fe)}
    np.testing.assert_allclose(truth["surrogate"]["A"], load_surrogate(fe).A, rtol=1e-12)
    capsys.readouterr()
    assert main(["calibrate", str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing.yaml" in err[0]


def _joined(a, b):
    """One stream of two records (the second after the first), as an import of both would give."""
    from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

    forces = {
        ch: ForceSeries(
            np.r_[a.forces[ch].stamp_ns, b.forces[ch].stamp_ns],
            np.r_[a.forces[ch].force_n, b.forces[ch].force_n],
            np.r_[a.forces[ch].frame_id, b.forces[ch].frame_id],
        )
        for ch in a.forces
    }
    ta, tb = a.temperature, b.temperature
    temp = TemperatureSeries(
        np.r_[ta.stamp_ns, tb.stamp_ns],
        np.r_[ta.temp_c, tb.temp_c],
        frame_id=np.r_[ta.frame_id, tb.frame_id],
    )
    return MonitoringData(forces, temp)


def test_the_calibrated_shadow_follows_a_withheld_20mm_lowering(pair, calibrated) -> None:
    """Online, not in-sample: the before record and the withheld 20 mm record as one stream."""
    from bridge_shadow.estimate import Shadow, ShadowConfig

    surrogate = load_surrogate(pair["out"])
    data = _joined(load_record([pair["before"]]), load_record([pair["after_20mm"]]))
    shadow = Shadow(ShadowConfig(), surrogate)
    result = shadow.run(data)
    js = result.to_json()
    assert len(js["events"]) == 1  # the lowering, and nothing else (the test car crosses both records)
    step = np.array(js["events"][0]["size_m"])
    np.testing.assert_allclose(step, [-0.020, -0.020], rtol=0.05)
    assert js["events"][0]["size_significant95"] and js["events"][0]["size_chi2"] > 100.0
    mean, cov = result.mean_m, result.covariance_m2
    np.testing.assert_allclose(mean, [-0.020, -0.020], rtol=0.05)  # the twin's supports start at 0
    assert np.all(np.abs(mean + 0.020) < 1.96 * np.sqrt(np.diag(cov)))  # its interval holds the truth


def test_with_prior_sensitivity_the_surrogate_averages_the_prior_sets(pair, calibrated, tmp_path) -> None:
    """``--prior-sensitivity`` with ``choose: average``: the surrogate averages over the prior sets too.

    Its ``A`` is the evidence-weighted mean over every explanation under every set not chosen after
    the data, not the sources' set alone (issue 20: where one prior is centred must not decide the
    default surrogate), and its model uncertainty holds the spread between the sets.
    """
    import contextlib
    import io

    out = tmp_path / "by_sets.yaml"
    buf = io.StringIO()
    args = ["calibrate", str(pair["spec"]), "--out", str(out), "--json", "--no-sweeps", "--prior-sensitivity"]
    with contextlib.redirect_stdout(buf):
        assert main(args) == 0
    doc = json.loads(buf.getvalue())
    avg = doc["model_average"]
    assert avg["prior_sets"]["sets"] == ["sources", "first_written", "wide"]
    assert set(avg["weights"]) >= {"support_springs (sources)", "support_springs (wide)"}
    assert abs(sum(avg["weights"].values()) - 1.0) < 1e-9
    sources = next(r for r in doc["prior_sensitivity"] if r["prior_set"] == "sources")
    written = load_surrogate(out)
    np.testing.assert_allclose(written.A, avg["A"], rtol=1e-9)
    # the sets' springs differ (first_written's centre 2e8, wide's doubled sd): so does the average
    assert not np.allclose(avg["A"], sources["model_average"]["A"], rtol=1e-6)
    alone = load_surrogate(pair["out"])  # the sources' average (the module's fixture)
    assert np.all(np.diag(written.model_cov)[:4] >= 0.5 * np.diag(alone.model_cov)[:4])
