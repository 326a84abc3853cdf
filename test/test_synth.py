"""``bridge-shadow synth`` and the bundled bags: round trips, truth.yaml, errors, README commands."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import read_monitoring
from bridge_shadow.cli import main
from bridge_shadow.contract import CHANNELS
from bridge_shadow.effects import EFFECT_NAMES
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.simulate import simulate
from bridge_shadow.twin.truth import read_truth

BAGS = ("demo_3d", "baseline_1d", "scour_3d")


#: Rebuilding a bag on another machine (other CPU, numpy or BLAS) may change float results in the
#: last bits: 87 of 25601 forces differed by 1 ulp on one machine. Stamps are integers and must be
#: identical; forces and temperatures agree to this relative tolerance (about 10^4 ulp, far below
#: any physical resolution: 1e-12 of 240 kN is 0.24 uN).
RTOL_ACROSS_MACHINES = 1e-12


def _assert_same(a, b, forces: bool = True) -> None:
    close = {"rtol": RTOL_ACROSS_MACHINES, "atol": 0.0, "equal_nan": True}
    for ch in CHANNELS:
        np.testing.assert_array_equal(a.forces[ch].stamp_ns, b.forces[ch].stamp_ns)  # integer ns
        if forces:
            np.testing.assert_allclose(a.forces[ch].force_n, b.forces[ch].force_n, **close)
        assert set(a.forces[ch].frame_id) == {ch}
    np.testing.assert_array_equal(a.temperature.stamp_ns, b.temperature.stamp_ns)  # integer ns
    np.testing.assert_allclose(a.temperature.temp_c, b.temperature.temp_c, **close)
    np.testing.assert_allclose(a.temperature.variance, b.temperature.variance, **close)


@pytest.mark.parametrize(("storage", "compress"), [("sqlite3", False), ("mcap", False), ("mcap", True)])
def test_cli_writes_bag_and_truth_that_read_back(
    tmp_path: Path, capsys, storage: str, compress: bool
) -> None:
    out = tmp_path / "bag"
    argv = ["synth", "--out", str(out), "--days", "0.5", "--rate", "0.2", "--seed", "9"]
    argv += [
        "--effect",
        "settlement_offset=7e-4",
        "--effect",
        "traffic=2.5e4",
        "--storage",
        storage,
        "--json",
    ]
    argv += ["--compress"] if compress else []
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)  # exactly one JSON object
    assert summary["storage"] == storage and summary["compressed"] is compress
    assert summary["duration_s"] == pytest.approx(0.5 * 86400.0, rel=1e-12) and "days" not in summary  # SI
    expected, _ = simulate(
        days=0.5, rate_hz=0.2, seed=9, effects={"settlement_offset": 7e-4, "traffic": 2.5e4}
    )
    back = read_monitoring(out)
    _assert_same(back, expected)
    assert summary["messages"]["/bridge/frc_01/force"] == len(back.forces["frc_01"])
    assert summary["bytes"] == sum(f.stat().st_size for f in out.iterdir())
    truth = read_truth(out)
    assert truth["seed"] == 9
    assert truth["effects"] == {"settlement_offset": 7e-4, "traffic": 2.5e4}
    assert truth["settlement"]["mean_m"] == pytest.approx([7e-4, -7e-4])
    assert truth["settlement"]["start_m"] == pytest.approx([7e-4, -7e-4])
    assert truth["config"]["noise_sd_n"] == [60.4, 82.7]
    assert "series" not in truth


def test_fixture_bags_are_cached_and_deterministic(synth_bag) -> None:
    a = synth_bag(
        days=0.25, rate_hz=0.1, seed=4, effects={"sensor_drift": 300.0}, storage="mcap", compress=True
    )
    b = synth_bag(
        days=0.25, rate_hz=0.1, seed=4, effects={"sensor_drift": 300.0}, storage="mcap", compress=True
    )
    c = synth_bag(days=0.25, rate_hz=0.1, seed=4, effects={"sensor_drift": 300.0})
    assert a == b and a != c
    assert any(p.suffix == ".mcap" for p in a.iterdir()) and any(p.suffix == ".db3" for p in c.iterdir())
    _assert_same(read_monitoring(a), read_monitoring(c))
    assert read_truth(c)["surrogate"]["provenance"]["solver"] == "closed-form placeholder"


def test_settlement_drift_summary_in_truth(synth_bag) -> None:
    truth = read_truth(synth_bag(days=2, rate_hz=0.01, seed=1, effects={"settlement_drift": 2e-4}))
    s = truth["settlement"]
    assert s["start_m"] == [0.0, 0.0]
    assert s["end_m"][0] == pytest.approx(-4e-4, rel=1e-3)
    assert s["mean_m"][0] == pytest.approx(-2e-4, rel=1e-3)
    assert s["mean_m"][1] == 0.0  # exact: the north bearing has no drift, a mean of zeros


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--effect", "scour=1"], "unknown effect scour; valid effects: " + ", ".join(EFFECT_NAMES)),
        (["--effect", "traffic"], "expected NAME=VALUE"),
        (["--days", "0"], "--days must be a finite number in (0, 366], not 0.0"),
        (["--days", "1e6"], "--days must be a finite number in (0, 366]"),  # the twin holds it in memory
        (["--rate", "-1"], "--rate must be a finite number in (0, 1000], not -1.0"),
        (["--step", "1:-2:0"], "SOUTH must be a finite number in (-1, 1), not -2.0"),  # m, not mm
        (["--step", "1:2"], "expected DAY:SOUTH:NORTH"),
        (["--compress"], "mcap storage only"),
        (["--start", "yesterday"], "not an ISO 8601"),
        # options that did nothing, exit 0: a step after the record, archive shapes without one
        (["--step", "5:-0.01:-0.01"], "--step 5:-0.01:-0.01: day 5 lies outside the record of --days 0.1"),
        (["--bridges", "3"], "--bridges and --bag-days shape an --archive"),
        (["--bag-days", "0.5"], "--bridges and --bag-days shape an --archive"),
        (["--reality-mesh", "coarse"], "--reality-mesh is the mesh of a --reality-set solve"),
    ],
)
def test_cli_errors_are_one_line(tmp_path: Path, capsys, extra: list[str], message: str) -> None:
    assert main(["synth", "--out", str(tmp_path / "x"), "--days", "0.1", *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_existing_bag_needs_force(tmp_path: Path, capsys) -> None:
    out = str(tmp_path / "bag")
    base = ["synth", "--out", out, "--days", "0.05", "--rate", "0.1"]
    assert main(base) == 0
    assert main([*base, "--seed", "1"]) == 2
    assert "pass --force to replace it" in capsys.readouterr().err
    assert main([*base, "--seed", "1", "--force"]) == 0
    assert read_truth(out)["seed"] == 1
    assert main([*base, "--seed", "2", "--overwrite"]) == 0  # the older name of --force
    assert read_truth(out)["seed"] == 2


def test_force_replaces_the_whole_archive(tmp_path: Path) -> None:
    """An archive of two bridges rewritten with one kept the old bridge_01, which `archive` then read."""
    folder = tmp_path / "fleet"
    base = ["synth", "--archive", str(folder), "--days", "0.02", "--rate", "0.1", "--bag-days", "0.01"]
    assert main([*base, "--bridges", "2"]) == 0
    (folder / "notes").mkdir()  # not the archive's: left alone
    assert main([*base, "--bridges", "1", "--force"]) == 0
    assert sorted(p.name for p in folder.iterdir() if p.is_dir()) == ["bridge_00", "notes"]


def test_help_lists_the_effects(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["synth", "--help"])
    text = capsys.readouterr().out
    for name in EFFECT_NAMES:
        assert name in text


# --- bundled bags ------------------------------------------------------------------------------------


def _readme_commands(root: Path) -> dict[str, list[str]]:
    text = (root / "bags" / "README.md").read_text()
    cmds = {}
    for line in re.findall(r"`(bridge-shadow synth [^`]+)`", text):
        argv = shlex.split(line)[1:]
        cmds[Path(argv[argv.index("--out") + 1]).name] = argv
    return cmds


def test_bundled_bags_are_small_documented_and_readable(root: Path) -> None:
    cmds = _readme_commands(root)
    assert set(BAGS) <= set(cmds)
    for name in BAGS:
        bag = root / "bags" / name
        size = sum(f.stat().st_size for f in bag.iterdir())
        assert size < 2_000_000, f"{name}: {size} bytes"
        data = read_monitoring(bag)
        truth = read_truth(bag)
        assert len(data.forces["frc_01"]) == truth["counts"]["force_messages"]["frc_01"]
        assert len(data.temperature) == truth["counts"]["temperature_messages"]
    demo = read_truth(root / "bags" / "demo_3d")
    assert demo["days"] == 3 and demo["effects"]["settlement_offset"] == 7e-4
    assert {"vertical_gradient", "transverse_gradient", "traffic"} <= set(demo["effects"])


@pytest.mark.slow
@pytest.mark.parametrize("name", BAGS)
def test_readme_command_rebuilds_the_bag(root: Path, tmp_path: Path, capsys, name: str) -> None:
    argv = _readme_commands(root)[name]
    argv[argv.index("--out") + 1] = str(tmp_path / name)
    assert main(argv) == 0
    capsys.readouterr()
    bundled = root / "bags" / name
    # Forces depend on config/surrogate.yaml: compare them when the bag was made with the current one.
    same_surrogate = np.allclose(
        read_truth(bundled)["base_surrogate"]["A"], load_surrogate().A
    ) and np.allclose(read_truth(bundled)["base_surrogate"]["u0"], load_surrogate().u0)
    _assert_same(read_monitoring(tmp_path / name), read_monitoring(bundled), forces=same_surrogate)
