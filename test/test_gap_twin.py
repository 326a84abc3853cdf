"""The gap diagnosis on truth-twin records with withheld effects (nothing reads the truth).

One record per vocabulary effect at its ``realistic`` magnitude plus a clean one and a mixed one,
3 days, forces at 0.1 Hz (6 samples per 60 s window), simulated once per session and diagnosed in
memory (``diagnose`` without the shadow runs; the command end to end, with them, runs on two bags
written with ``bridge-shadow synth`` whose ``truth.yaml`` is deleted or guarded).
"""

from __future__ import annotations

import builtins
import contextlib
import io
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bridge_shadow.cli import main
from bridge_shadow.effects import EFFECT_NAMES, EFFECTS, SETTLEMENT_EFFECTS, plausible_range
from bridge_shadow.gap.candidates import CANDIDATES
from bridge_shadow.gap.diagnose import diagnose
from bridge_shadow.jsonvalues import jsonable
from bridge_shadow.twin.simulate import simulate

SEED = 11
DAYS = 3.0
RATE = 0.1

#: Several effects at once, as in the demo bag: the paper's offset, sun gradients and a test car.
MIXED = {"settlement_offset": 7e-4, "vertical_gradient": 4.0, "transverse_gradient": 3.0, "traffic": 2.5e4}


def _cli_json(argv: list[str]) -> dict[str, Any]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    assert code == 0
    return json.loads(out.getvalue())


def _synth(out: Path, effect: str | None, days: float = DAYS) -> Path:
    argv = ["synth", "--out", str(out), "--days", str(days), "--rate", str(RATE), "--seed", str(SEED)]
    if effect:
        argv += ["--effect", f"{effect}={EFFECTS[effect].realistic}"]
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(argv) == 0
    return out


@pytest.fixture(scope="session")
def diagnoses() -> dict[str, dict[str, Any]]:
    """Diagnosis summaries (as JSON data) keyed by effect name, "none" and "mixed"."""
    cases: dict[str, dict[str, Any]] = {"none": {}, **{n: {n: EFFECTS[n].realistic} for n in EFFECT_NAMES}}
    cases["mixed"] = MIXED
    out = {}
    for name, effects in cases.items():
        data, _truth = simulate(DAYS, RATE, SEED, effects)  # the truth is not passed on
        out[name] = json.loads(json.dumps(jsonable(diagnose(data).summary)))
    return out


def _named(s: dict[str, Any]) -> list[dict[str, Any]]:
    return ([s["best_effect"]] if s["best_effect"] else []) + s["also_present"]


def test_clean_record_gives_none(diagnoses: dict[str, dict[str, Any]]):
    s = diagnoses["none"]
    assert s["best"] == "none"
    assert s["indistinguishable_from"] == []
    assert s["also_present"] == []
    assert all(not c["significant"] for c in s["candidates"])


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_withheld_effect_is_found(name: str, diagnoses: dict[str, dict[str, Any]]):
    s = diagnoses[name]
    # Model-form effects with x = 0 show through u0 and the thermal response; a stiffness change
    # that keeps u0 (the placeholder connector) leaves too little to find, and must not be guessed.
    if name == "connector_stiffness":
        assert s["best"] in ("none", "connector_stiffness", *s["indistinguishable_from"])
        return
    group = [s["best"], *s["indistinguishable_from"]]
    assert name in group, (s["best"], s["statement"])
    if len(group) > 1:
        assert "cannot be told apart" in s["statement"]
    cand = next(c for c in s["candidates"] if c["effect"] == name)
    assert cand["heldout_reduction"]["total"] >= 0.3
    assert cand["significant"]


#: The JSON is SI; the vocabulary's sensor drift is per day (``synth --effect sensor_drift=300``).
PER_DAY = 1.0 / 86400.0


@pytest.mark.parametrize(
    ("name", "key", "rel", "to_json"),
    [
        ("settlement_offset", "x_south [m]", 0.05, 1.0),
        ("settlement_step", "dx_south [m]", 0.05, 1.0),
        ("sensor_drift", "d [N/s]", 0.2, PER_DAY),
        ("uniform_temperature", "c [N/K]", 0.1, 1.0),
        ("vertical_gradient", "g [K]", 0.25, 1.0),
        ("support_spring", "k_south [N/m]", 0.02, 1.0),
    ],
)
def test_fitted_magnitude_matches_the_withheld_one(
    name: str, key: str, rel: float, to_json: float, diagnoses
):
    cand = next(c for c in diagnoses[name]["candidates"] if c["effect"] == name)
    assert cand["params"][key] == pytest.approx(EFFECTS[name].realistic * to_json, rel=rel)


def test_thermal_lag_time_constant_is_recovered(diagnoses):
    cand = next(c for c in diagnoses["thermal_lag"]["candidates"] if c["effect"] == "thermal_lag")
    # the vocabulary's lag is in hours, the JSON's in seconds
    assert cand["params"]["tau [s]"] == pytest.approx(
        3600.0 * EFFECTS["thermal_lag"].realistic, abs=0.6 * 3600.0
    )
    assert cand["magnitude"]["unit"] == "s"


def test_the_json_has_no_unit_but_si(diagnoses):
    """The contract: SI at every machine interface (``tau [h]``, ``v_south [m/day]`` went out before)."""
    import json
    import re

    for name, js in diagnoses.items():
        text = json.dumps(js)
        assert not re.search(r"\[(h|m/day|N/day|kN|mm)\]", text), name
        units = re.findall(r'"unit": "([^"]*)"', text)
        assert set(units) <= {"m", "m/s", "N/s", "N/K", "K", "s", "1", "N/m", "m/N", "N"}, (name, units)
        assert "hours_between" not in text


def test_the_traffic_candidates_magnitude_is_a_share_not_a_force(diagnoses):
    """Its magnitude is the bearings' two shares summed, unit 1 (it said N: the twin's weight unit)."""
    seen = 0
    for js in diagnoses.values():
        for c in js["candidates"]:
            if c["effect"] == "traffic" and c["magnitude"]["value"] is not None:
                seen += 1
                assert c["magnitude"]["unit"] == "1"
                total = c["params"]["b_south [1]"] + c["params"]["b_north [1]"]
                assert c["magnitude"]["value"] == pytest.approx(total, rel=1e-12, abs=1e-12)
    assert seen


def test_where_points_at_the_north_channel_for_a_north_sensor_drift(diagnoses):
    where = diagnoses["sensor_drift"]["where"]
    assert where["channel_share"]["north"] > 0.8
    assert where["bands"]["slower_than_day"]["north"] > 0.5


def test_where_points_at_daytime_sun_for_a_vertical_gradient(diagnoses):
    where = diagnoses["vertical_gradient"]["where"]
    sun = where["sun"]
    for sup in ("south", "north"):
        assert sun["night_rms_n"][sup] < 0.2 * sun["sunny_rms_n"][sup]
        assert abs(where["sun"]["correlation_with_sun"][sup]) > 0.8
    assert where["model_part"]["part"] == "thermal"


def _within(name: str, params: dict[str, Any], bounds: list[list[float]] | None = None) -> bool:
    """Whether fitted linear parameters lie in their plausible range (the spring: k at least its low)."""
    if name == "support_spring":
        lo = plausible_range(name)[0]
        ks = (params["k_south [N/m]"], params["k_north [N/m]"])
        return all(k is None or k >= lo * (1 - 1e-6) for k in ks)
    from bridge_shadow.gap.si import si_unit_value

    cand = next(c for c in CANDIDATES if c.name == name)
    keys, rng = [], []
    for k in cand.params:  # the fit's names and range in the vocabulary's units, the JSON's in SI
        label, _, unit = k.partition(" [")
        si, lo_hi = si_unit_value(unit.rstrip("]"), list(plausible_range(name)))
        keys.append(f"{label} [{si}]")
        rng.append(lo_hi)
    pairs = zip(keys, bounds or rng, strict=True)
    return all(lo - 1e-9 * abs(lo) <= params[k] <= hi + 1e-9 * abs(hi) for k, (lo, hi) in pairs)


def test_every_named_effect_carries_its_group_and_a_plausible_fit(diagnoses):
    for case, s in diagnoses.items():
        for e in _named(s):
            assert e["group"][0]["effect"] == e["effect"], case
            assert [g["effect"] for g in e["group"][1:]] == e["indistinguishable_from"], case
        # an implausible fit is never listed as present
        for a in s["also_present"]:
            assert _within(a["effect"], a["params"]), (case, a)
        for c in s["candidates"]:
            if c["significant"]:
                assert c["plausible"], (case, c["effect"])
            bounds = None if c["effect"] == "support_spring" else c["plausible_range"]
            assert _within(c["effect"], c["params"], bounds), (case, c["effect"])


def test_stiffness_fits_stay_in_their_prior_range(diagnoses):
    lo_k, _ = plausible_range("support_spring")
    for case, s in diagnoses.items():
        for c in s["candidates"]:
            if c["effect"] == "support_spring" and c["plausible"]:
                ks = [c["params"][k] for k in ("k_south [N/m]", "k_north [N/m]")]
                assert all(k is None or k >= lo_k * (1 - 1e-6) for k in ks), (case, ks)
            if c["effect"] in ("bearing_stiffness", "connector_stiffness", "slab_joint_opening"):
                lo, hi = c["plausible_range"][0]
                assert lo - 1e-12 <= c["params"]["r [1]"] <= hi + 1e-12, (case, c["effect"])


def test_several_effects_at_once_are_all_found(diagnoses):
    s = diagnoses["mixed"]
    named = [s["best"], *(a["effect"] for a in s["also_present"])]
    groups = {g["effect"] for e in _named(s) for g in e["group"]}
    # each injected effect is named, or in the group of one that is; nothing else is named
    assert set(MIXED) <= groups
    assert set(named) <= set(MIXED)
    assert s["also_present"][-1]["cumulative_heldout_reduction"]["total"] >= 0.9
    fitted = {a["effect"]: a["params"] for a in s["also_present"]}
    assert fitted["vertical_gradient"]["g [K]"] == pytest.approx(MIXED["vertical_gradient"], rel=0.2)
    assert fitted["transverse_gradient"]["g [K]"] == pytest.approx(MIXED["transverse_gradient"], rel=0.2)


def test_single_effect_records_report_nothing_else(diagnoses):
    for name in ("settlement_offset", "settlement_drift", "settlement_step", "thermal_lag", "traffic"):
        assert diagnoses[name]["also_present"] == [], name


def test_settlement_effects_say_how_their_size_depends_on_the_model(diagnoses):
    # Without a known settlement the reactions fix A x, not x: a softer model reads the same
    # change as a larger settlement, and the tool says by how much.
    e = diagnoses["settlement_step"]["best_effect"]
    assert e["effect"] in SETTLEMENT_EFFECTS
    soft = e["size_if_model_softer"]
    assert np.all(np.abs(soft["value"]) > np.abs(soft["as_built"]))


@pytest.fixture(scope="module")
def drift_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _synth(tmp_path_factory.mktemp("gap_twin") / "drift", "settlement_drift", days=2.0)


def test_diagnosis_never_opens_truth_yaml(drift_bag: Path, tmp_path: Path, monkeypatch):
    bag = tmp_path / "bag"
    shutil.copytree(drift_bag, bag)
    (bag / "truth.yaml").write_text("effects: {settlement_drift: 0.0002}\n")
    real_open = builtins.open

    def guarded(file, *args, **kwargs):
        assert not str(file).endswith("truth.yaml"), "the diagnosis opened truth.yaml"
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", guarded)
    monkeypatch.setattr(io, "open", guarded)
    s = _cli_json(["gap", str(bag), "--json", "--holdout-days", "1"])
    assert s["best"] == "settlement_drift"
    assert s["validation"] == {"kind": "holdout", "folds": 1}
    # a settlement only: nothing is added to the model, so the shadow runs once and after = before
    assert s["posterior"]["after"]["mean_m"] == s["posterior"]["before"]["mean_m"]


def test_bad_holdout_day_is_one_line_error(drift_bag: Path, capsys):
    assert main(["gap", str(drift_bag), "--holdout-days", "9"]) == 2
    err = capsys.readouterr().err
    assert "holdout" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("extra", "word"),
    [
        (["--imposed", "yesterday=-0.01"], "--imposed"),
        (["--imposed", "2022-03-14T12:00=-3,-3"], "SOUTH must be a finite number in (-1, 1), not -3.0"),
        (["--report", "FILE"], "--report"),
    ],
)
def test_bad_gap_arguments_are_one_line_errors(drift_bag: Path, tmp_path: Path, capsys, extra, word):
    if "FILE" in extra:
        (tmp_path / "f").write_text("not a directory")
        extra = [e.replace("FILE", str(tmp_path / "f")) for e in extra]
    assert main(["gap", str(drift_bag), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert word in err and "Traceback" not in err and len(err.splitlines()) == 1
