"""The bad-input matrix: every case a user can cause ends with one line on stderr and a non-zero exit.

Each case runs through the command line (``bridge_shadow.cli.main``) or the node
(``bridge_shadow.ros.main.main``; three cases through the installed ``bridge_shadow_node``
process itself) in a scratch directory holding the inputs (a file, a directory, random bytes, a
bag, a checkpoint, parameter files, broken surrogates, a calibration file, a bridge model).
Asserted for every case: a non-zero exit, exactly one non-empty line on stderr (no traceback),
and no input or state file changed or added: every file of the scratch directory, the bundled
bag and ``config/`` hash the same before and after, and no file (a stray ``.tmp``, a
half-written bag, an empty plot directory) was left behind. Where it matters which parameter or
problem the line names (``window_s: 1e12`` must not blame ``drift_block_s``), ``EXPECT`` says what
the line must hold.

The cases of issue 22 are marked ``# 22`` below; its other points are tested where they live:
interrupted writers (``test_interrupted_writers.py``), ``| head -1`` exiting 141
(``test_replay_stream.py``), a resumed replay's counts (``test_output_text.py``), ``--live``'s
discovery and rates (``test_replay_rates.py``, ``test_interrupted_writers.py``).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import threading
from pathlib import Path

import numpy as np
import pytest
import yaml

from bridge_shadow.cli import main

FE_CASES_MESH = ["--mesh", "coarse", "--no-sensitivities"]


def _tree(*roots: Path) -> dict[str, str]:
    """Every file (and directory) under ``roots``: path -> sha256 (directories: 'dir')."""
    out: dict[str, str] = {}
    for root in roots:
        for dirpath, dirnames, filenames in os.walk(root):
            for d in dirnames:
                out[os.path.join(dirpath, d)] = "dir"
            for f in filenames:
                path = os.path.join(dirpath, f)
                out[path] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return out


def _without_forces(bag: Path, out: Path) -> None:
    """Write ``bag``'s air temperature to ``out`` with the load cells' topics and no message on them."""
    from bridge_shadow.bagio import read_monitoring, write_monitoring
    from bridge_shadow.series import MonitoringData

    data = read_monitoring(bag)
    forces = data.select(lambda stamps: np.zeros(len(stamps), bool)).forces
    write_monitoring(out, MonitoringData(forces, data.temperature))


def _params(path: Path, **values: object) -> str:
    path.write_text(yaml.safe_dump({"bridge_shadow": {"ros__parameters": values}}))
    return str(path)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory, root: Path) -> Path:
    """The inputs of the matrix (made once; every case must leave them as they are)."""
    from bridge_shadow.estimate import Shadow, load_config

    w = tmp_path_factory.mktemp("matrix")
    (w / "afile").write_text("hello\n")
    (w / "adir").mkdir()
    (w / "random.bin").write_bytes(np.random.default_rng(1).bytes(2048))
    (w / "empty.zip").write_bytes(b"PK\x05\x06" + bytes(18))  # a zip with no file in it
    (w / "empty.npz").write_bytes(b"")
    shutil.copytree(root / "bags" / "baseline_1d", w / "bag")
    _without_forces(w / "bag", w / "noforce")
    (w / "tiny.csv").write_text("Time (-),FRC-01 (kN),FRC-02 (kN)\n2022-03-07 16:35:00.000,260.1,221.2\n")
    _params(w / "inf.yaml", window_s=float("inf"))
    _params(w / "true.yaml", window_s=True)
    _params(w / "frac.yaml", window_min_samples=2.7)
    _params(w / "unknown.yaml", windw_s=60.0)
    _params(w / "nosurrogate.yaml", surrogate_path=str(w / "missing.yaml"))
    (w / "broken.yaml").write_text("bridge_shadow:\n  ros__parameters:\n    window_s: [\n")
    # a checkpoint of the default parameters, then a params file it does not fit
    Shadow(load_config()).save_checkpoint(w / "state.npz")
    _params(w / "w30.yaml", window_s=30.0, checkpoint_path=str(w / "state.npz"))
    (w / "truncated.npz").write_bytes((w / "state.npz").read_bytes()[:500])
    # surrogates that must be refused where they are loaded (22): A singular, NaN, inf, asymmetric
    good = yaml.safe_load((root / "config" / "surrogate_fe.yaml").read_text())
    base = {"A": good["A"], "u0": good["u0"], "thermal": good["thermal"]}
    a11 = good["A"][0][0]
    for name, a in {
        "singular": [[a11, a11], [a11, a11]],
        "nan": [[float("nan"), 0.0], [0.0, a11]],
        "inf": [[float("inf"), 0.0], [0.0, a11]],
        "asymmetric": [[a11, -0.5 * a11], [-0.6 * a11, a11]],
    }.items():
        (w / f"{name}.yaml").write_text(yaml.safe_dump({**base, "A": a}))
    (w / "surrogate_typo.yaml").write_text(yaml.safe_dump({**base, "thermal_cases": base["thermal"]}))
    _params(w / "singular_params.yaml", surrogate_path=str(w / "singular.yaml"))
    _params(w / "prior_1e300.yaml", prior_sigma_m=[1e300, 1e300])
    _params(w / "prior_1e150.yaml", prior_sigma_m=[1e150, 1e150])
    _params(w / "window_1e12.yaml", window_s=1e12)
    pair = {
        "name": "p",
        "before": "Settlements/UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
        "after": "Settlements/UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
        "imposed_m": [-0.01, -0.01],
        "imposed_sd_m": [5e-4, 5e-4],
    }
    (w / "cal_window.yaml").write_text(yaml.safe_dump({"window_s": -10, "pairs": [pair]}))
    (w / "cal_typo.yaml").write_text(yaml.safe_dump({"windw_s": 10, "pairs": [pair]}))
    (w / "cal_pair_typo.yaml").write_text(yaml.safe_dump({"pairs": [{**pair, "imposed_mm": [-10, -10]}]}))
    model = (root / "config" / "bridge.yaml").read_text()
    (w / "bridge_typo.yaml").write_text(model.replace("  bearing_stiffness:", "  bearing_stifness:", 1))
    # an existing surrogate: --out must not replace it without --force (22)
    (w / "existing.yaml").write_text((root / "config" / "surrogate_fe.yaml").read_text())
    return w


#: The broken surrogate files of the scratch directory: case -> (file stem, what the error says).
BAD_SURROGATES = {
    "singular A": ("singular", "A must be positive definite"),
    "NaN in A": ("nan", "A must be finite"),
    "inf in A": ("inf", "A must be finite"),
    "asymmetric A": ("asymmetric", "A must be symmetric"),
    "unknown key": ("surrogate_typo", "unknown key 'thermal_cases' (did you mean thermal?)"),
}

CLI_CASES = {
    # replay: inputs
    "replay missing bag": ["replay", "{w}/missing"],
    "replay bag is a file": ["replay", "{w}/afile"],
    "replay bag is an empty dir": ["replay", "{w}/adir"],
    "replay params .inf": ["replay", "{w}/bag", "--params", "{w}/inf.yaml"],
    "replay params true for a real": ["replay", "{w}/bag", "--params", "{w}/true.yaml"],
    "replay params 2.7 for an integer": ["replay", "{w}/bag", "--params", "{w}/frac.yaml"],
    "replay params unknown name": ["replay", "{w}/bag", "--params", "{w}/unknown.yaml"],
    "replay params broken YAML": ["replay", "{w}/bag", "--params", "{w}/broken.yaml"],
    "replay params random bytes": ["replay", "{w}/bag", "--params", "{w}/random.bin"],
    "replay params a directory": ["replay", "{w}/bag", "--params", "{w}/adir"],
    "replay params missing": ["replay", "{w}/bag", "--params", "{w}/missing.yaml"],
    "replay surrogate missing": ["replay", "{w}/bag", "--params", "{w}/nosurrogate.yaml"],
    # replay: outputs and state
    "replay --out existing dir": ["replay", "{w}/bag", "--out", "{w}/adir"],
    "replay --out existing bag": ["replay", "{w}/bag", "--out", "{w}/bag"],
    "replay --out under a file": ["replay", "{w}/bag", "--out", "{w}/afile/out"],
    "replay --plots a file": ["replay", "{w}/bag", "--plots", "{w}/afile"],
    "replay --plots under a file": ["replay", "{w}/bag", "--plots", "{w}/afile/plots"],
    "replay --checkpoint random bytes": ["replay", "{w}/bag", "--checkpoint", "{w}/random.bin"],
    "replay --live --checkpoint random bytes": [
        "replay",
        "{w}/bag",
        "--live",
        "--checkpoint",
        "{w}/random.bin",
    ],
    "replay --checkpoint empty": ["replay", "{w}/bag", "--checkpoint", "{w}/empty.npz"],
    "replay --checkpoint truncated": ["replay", "{w}/bag", "--checkpoint", "{w}/truncated.npz"],
    "replay --checkpoint a directory": ["replay", "{w}/bag", "--checkpoint", "{w}/adir"],
    "replay --checkpoint other params": [
        "replay",
        "{w}/bag",
        "--params",
        "{w}/w30.yaml",
        "--checkpoint",
        "{w}/state.npz",
    ],
    "replay --rate without --live": ["replay", "{w}/bag", "--rate", "2"],
    "replay --live --rate 0": ["replay", "{w}/bag", "--live", "--rate", "0"],
    "replay --live --rate 1e-9": ["replay", "{w}/bag", "--live", "--rate", "1e-9"],
    "replay --watch without --live": ["replay", "{w}/bag", "--watch"],
    # gap
    "gap missing bag": ["gap", "{w}/missing"],
    "gap bag without a load cell message": ["gap", "{w}/noforce"],
    "gap --report a file": ["gap", "{w}/bag", "--report", "{w}/afile"],
    "gap --report under a file": ["gap", "{w}/bag", "--report", "{w}/afile/report"],
    "gap --surrogate random bytes": ["gap", "{w}/bag", "--surrogate", "{w}/random.bin"],
    "gap --surrogate a directory": ["gap", "{w}/bag", "--surrogate", "{w}/adir"],
    "gap --window nan": ["gap", "{w}/bag", "--window", "nan"],
    "gap --holdout-days outside": ["gap", "{w}/bag", "--holdout-days", "9"],
    "gap --imposed-sd 0": ["gap", "{w}/bag", "--imposed-sd", "0"],
    "gap --imposed-sd nan": ["gap", "{w}/bag", "--imposed-sd", "nan"],
    "gap --out-surrogate a directory": ["gap", "{w}/bag", "--out-surrogate", "{w}/adir"],
    "gap --out-surrogate a user file": ["gap", "{w}/bag", "--out-surrogate", "{w}/afile"],
    # synth
    "synth --out existing dir": ["synth", "--out", "{w}/adir", "--days", "0.01"],
    "synth --out under a file": ["synth", "--out", "{w}/afile/bag", "--days", "0.01"],
    "synth --overwrite a non-bag": ["synth", "--out", "{w}", "--days", "0.01", "--overwrite"],
    "synth --days -1": ["synth", "--out", "{w}/new", "--days", "-1"],
    "synth --seed -1": ["synth", "--out", "{w}/new", "--days", "0.01", "--seed", "-1"],
    "synth --step nan": ["synth", "--out", "{w}/new", "--days", "0.01", "--step", "nan:0:0"],
    "synth --effect unknown": ["synth", "--out", "{w}/new", "--days", "0.01", "--effect", "bogus=1"],
    # import-csv
    "import-csv missing file": ["import-csv", "{w}/missing.csv", "--out", "{w}/new"],
    "import-csv a directory": ["import-csv", "{w}/adir", "--out", "{w}/new"],
    "import-csv random bytes": ["import-csv", "{w}/random.bin", "--out", "{w}/new"],
    "import-csv empty zip": ["import-csv", "{w}/empty.zip", "--out", "{w}/new"],
    "import-csv foreign CSV": ["import-csv", "{w}/afile", "--out", "{w}/new"],
    "import-csv --out existing dir": ["import-csv", "{w}/tiny.csv", "--out", "{w}/adir"],
    "import-csv --out under a file": ["import-csv", "{w}/tiny.csv", "--out", "{w}/afile/bag"],
    # surrogate (every path is checked before the FE solves)
    "surrogate --out a directory": ["surrogate", *FE_CASES_MESH, "--out", "{w}/adir"],
    "surrogate --out a user file": ["surrogate", *FE_CASES_MESH, "--out", "{w}/afile"],
    "surrogate --out a params file": ["surrogate", *FE_CASES_MESH, "--out", "{w}/inf.yaml"],
    "surrogate --out under a file": ["surrogate", *FE_CASES_MESH, "--out", "{w}/afile/s.yaml"],
    "surrogate --png a directory": ["surrogate", *FE_CASES_MESH, "--out", "{w}/s.yaml", "--png", "{w}/adir"],
    "surrogate --vtk a file": ["surrogate", *FE_CASES_MESH, "--out", "{w}/s.yaml", "--vtk", "{w}/afile"],
    "surrogate --model random bytes": [
        "surrogate",
        *FE_CASES_MESH,
        "--model",
        "{w}/random.bin",
        "--out",
        "{w}/s.yaml",
    ],
    "surrogate --model a directory": [
        "surrogate",
        *FE_CASES_MESH,
        "--model",
        "{w}/adir",
        "--out",
        "{w}/s.yaml",
    ],
    "surrogate --set unknown": ["surrogate", *FE_CASES_MESH, "--set", "bogus=1", "--out", "{w}/s.yaml"],
    "calibrate --check random bytes": ["calibrate", "--check", "{w}/random.bin"],
    "calibrate --check a directory": ["calibrate", "--check", "{w}/adir"],
    "calibrate --check with --out": ["calibrate", "--check", "{w}/random.bin", "--out", "{w}/s.yaml"],
    "calibrate --priors unknown": ["calibrate", "--priors", "optimistic"],
    "calibrate --choose unknown": ["calibrate", "--choose", "nothing"],
    # 22: a surrogate is checked where it is loaded, by every command
    **{
        f"replay --surrogate {what}": ["replay", "{w}/bag", "--surrogate", f"{{w}}/{file}.yaml"]
        for what, (file, _) in BAD_SURROGATES.items()
    },
    "replay params surrogate singular": ["replay", "{w}/bag", "--params", "{w}/singular_params.yaml"],
    "replay --live --surrogate singular": ["replay", "{w}/bag", "--live", "--surrogate", "{w}/singular.yaml"],
    "calibrate --check singular A": ["calibrate", "--check", "{w}/singular.yaml"],
    "calibrate --check NaN in A": ["calibrate", "--check", "{w}/nan.yaml"],
    "gap --surrogate singular A": ["gap", "{w}/bag", "--surrogate", "{w}/singular.yaml"],
    "gap --surrogate asymmetric A": ["gap", "{w}/bag", "--surrogate", "{w}/asymmetric.yaml"],
    "synth --reality-surrogate singular": [
        "synth",
        "--out",
        "{w}/new",
        "--days",
        "0.01",
        "--reality-surrogate",
        "{w}/singular.yaml",
    ],
    # 22: every parameter has a physical range, named in the message
    "replay params prior_sigma_m 1e300": ["replay", "{w}/bag", "--params", "{w}/prior_1e300.yaml"],
    "replay params prior_sigma_m 1e150": ["replay", "{w}/bag", "--params", "{w}/prior_1e150.yaml"],
    "replay params window_s 1e12": ["replay", "{w}/bag", "--params", "{w}/window_1e12.yaml"],
    "calibrate file window_s -10": ["calibrate", "{w}/cal_window.yaml"],
    "calibrate --check file window_s -10": [
        "calibrate",
        "{w}/cal_window.yaml",
        "--check",
        "{w}/existing.yaml",
    ],
    "calibrate file unknown key": ["calibrate", "{w}/cal_typo.yaml"],
    "calibrate file unknown pair key": ["calibrate", "{w}/cal_pair_typo.yaml"],
    "surrogate --model unknown key": ["surrogate", *FE_CASES_MESH, "--model", "{w}/bridge_typo.yaml"],
    "surrogate --set in MPa": ["surrogate", *FE_CASES_MESH, "--set", "E_concrete=34000"],
    "surrogate --set typo": ["surrogate", *FE_CASES_MESH, "--set", "bearing_stifness=2e9"],
    "gap --window a year": ["gap", "{w}/bag", "--window", "3.2e7"],
    "replay --live --rate 1e12": ["replay", "{w}/bag", "--live", "--rate", "1e12"],
    "synth --days 1e6": ["synth", "--out", "{w}/new", "--days", "1e6"],
    "synth --step in mm": ["synth", "--out", "{w}/new", "--days", "0.01", "--step", "0.5:-10:-10"],
    # 22: --out never replaces a file without --force
    "surrogate --out existing surrogate": ["surrogate", *FE_CASES_MESH, "--out", "{w}/existing.yaml"],
    "calibrate --out existing surrogate": ["calibrate", "--out", "{w}/existing.yaml"],
    "import-csv --out existing bag": [
        "import-csv",
        "{w}/tiny.csv",
        "--date",
        "2022-03-07",
        "--out",
        "{w}/bag",
    ],
    # 22: import-csv refuses a date it cannot settle; gap --imposed outside the record
    "import-csv ambiguous date": ["import-csv", "{w}/tiny.csv", "--out", "{w}/new"],
    "gap --imposed before the record": ["gap", "{w}/bag", "--imposed", "2020-01-01T00:00=-0.01,-0.01"],
    "gap --imposed after the record": ["gap", "{w}/bag", "--imposed", "+30=-0.01,-0.01"],
    "gap --imposed nan": ["gap", "{w}/bag", "--imposed", "+0.5=nan,-0.01"],
    "gap --imposed in mm": ["gap", "{w}/bag", "--imposed", "+0.5=-0.01,-10"],
}

#: What the one line must say, where it matters which parameter or problem it names.
EXPECT = {
    **{f"replay --surrogate {what}": message for what, (_, message) in BAD_SURROGATES.items()},
    "replay params surrogate singular": "A must be positive definite",
    "replay --live --surrogate singular": "A must be positive definite",
    "calibrate --check singular A": "A must be positive definite",
    "calibrate --check NaN in A": "A must be finite",
    "gap --surrogate singular A": "A must be positive definite",
    "gap --surrogate asymmetric A": "A must be symmetric",
    "synth --reality-surrogate singular": "A must be positive definite",
    "replay params prior_sigma_m 1e300": "prior_sigma_m must be two finite numbers [south, north], each in",
    "replay params prior_sigma_m 1e150": "prior_sigma_m must be",
    "replay params window_s 1e12": "window_s must be a finite number in (0, 86400], not 1000000000000.0",
    "calibrate file window_s -10": "window_s must be a finite number in [0.1, 600], not -10",
    "calibrate --check file window_s -10": "window_s must be a finite number in [0.1, 600], not -10",
    "calibrate file unknown key": "unknown key 'windw_s' (did you mean window_s?)",
    "calibrate file unknown pair key": "unknown key 'imposed_mm' (did you mean imposed_m?)",
    "surrogate --model unknown key": "unknown key 'bearing_stifness' (did you mean bearing_stiffness?)",
    "surrogate --set in MPa": "E_concrete must lie in",
    "surrogate --set typo": "did you mean bearing_stiffness?",
    "gap --window a year": "--window must be a finite number in (0, 86400]",
    "replay --live --rate 1e12": "--rate must be",
    "replay --live --rate 1e-9": "--rate must be a finite number in [0.001, 10000000], not 1e-09",
    "synth --days 1e6": "--days must be",
    "synth --step in mm": "(-1, 1), not -10.0 (metres, positive upward: -10 mm is -0.01)",
    "surrogate --out existing surrogate": "pass --force to replace it",
    "calibrate --out existing surrogate": "pass --force to replace it",
    "import-csv --out existing bag": "pass --force to replace it",
    "import-csv empty zip": "empty.zip: an empty zip (no file in it)",
    "replay --checkpoint random bytes": "(checkpoint_unusable: fresh sets it aside",
    "replay --live --checkpoint random bytes": "(checkpoint_unusable: fresh sets it aside",  # offline's
    "import-csv ambiguous date": "could also be 2022-07-03",
    "gap --imposed before the record": "outside the record",
    "gap --imposed after the record": "outside the record",
    "gap --imposed nan": "SOUTH must be a finite number in (-1, 1), not nan",  # 'a metre or more' before
    "gap --imposed in mm": "NORTH must be a finite number in (-1, 1), not -10.0 (metres, positive",
}


def _check(
    code: int, err: str, before: dict[str, str], after: dict[str, str], expect: str | None = None
) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code != 0
    assert len(lines) == 1, err
    assert "Traceback" not in err
    if expect is not None:
        assert expect in lines[0], lines[0]
    assert after == before, sorted(set(after.items()) ^ set(before.items()))


@pytest.mark.parametrize("case", list(CLI_CASES))
def test_cli_case_gives_one_line_and_changes_nothing(case: str, scratch: Path, root: Path, capfd) -> None:
    argv = [a.format(w=scratch) for a in CLI_CASES[case]]
    watched = (scratch, root / "bags", root / "config")
    before = _tree(*watched)
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse refuses an argument with its usage and one error line
        code = int(exit_.code or 0)
    out = capfd.readouterr()
    err = out.err
    if code == 2 and err.startswith("usage:"):  # argparse: usage lines, then the one error line
        err = err.splitlines()[-1]
    _check(code, err, before, _tree(*watched), EXPECT.get(case))


NODE_CASES = {
    "broken YAML": ["--params-file", "{w}/broken.yaml"],
    "params file of random bytes": ["--params-file", "{w}/random.bin"],
    "params file missing": ["--params-file", "{w}/missing.yaml"],
    "window_s .inf": ["--params-file", "{w}/inf.yaml"],
    "window_s true": ["--params-file", "{w}/true.yaml"],
    "2.7 for an integer": ["-p", "window_min_samples:=2.7"],
    "unknown name": ["-p", "windw_s:=60.0"],
    "diagnostics_period_s -1": ["-p", "diagnostics_period_s:=-1.0"],
    "diagnostics_period_s 0": ["-p", "diagnostics_period_s:=0.0"],
    "a rule rcl cannot parse": ["-p", "window_s:=[1, true]"],
    "surrogate missing": ["-p", "surrogate_path:={w}/missing.yaml"],
    "checkpoint random bytes": ["-p", "checkpoint_path:={w}/random.bin"],
    "checkpoint empty": ["-p", "checkpoint_path:={w}/empty.npz"],
    "checkpoint truncated": ["-p", "checkpoint_path:={w}/truncated.npz"],
    "checkpoint a directory": ["-p", "checkpoint_path:={w}/adir"],
    "checkpoint under a file": ["-p", "checkpoint_path:={w}/afile/state.npz"],
    "checkpoint of other parameters": ["--params-file", "{w}/w30.yaml"],
    # 22
    "surrogate singular": ["-p", "surrogate_path:={w}/singular.yaml"],
    "surrogate NaN in A": ["-p", "surrogate_path:={w}/nan.yaml"],
    "prior_sigma_m 1e300": ["-p", "prior_sigma_m:=[1.0e300, 1.0e300]"],
    "window_s 1e12": ["-p", "window_s:=1.0e12"],
}
NODE_EXPECT = {
    "surrogate singular": "A must be positive definite",
    "surrogate NaN in A": "A must be finite",
    "prior_sigma_m 1e300": "prior_sigma_m must be",
    "window_s 1e12": "window_s must be a finite number in (0, 86400]",
}


@pytest.mark.ros
@pytest.mark.parametrize("case", list(NODE_CASES))
def test_node_case_gives_one_line_and_changes_nothing(case: str, scratch: Path, root: Path, capfd) -> None:
    """The node's main() in this process (the entry point's code, without a process start each)."""
    pytest.importorskip("rclpy")
    from bridge_shadow.ros.main import main as node_main

    argv = ["--ros-args", *(a.format(w=scratch) for a in NODE_CASES[case])]
    watched = (scratch, root / "bags", root / "config")
    before = _tree(*watched)
    # a case the node wrongly accepts would spin until stopped: stop it (exit 0 fails the test)
    watchdog = threading.Timer(20.0, os.kill, (os.getpid(), signal.SIGINT))
    watchdog.start()
    try:
        code = node_main(argv)
    finally:
        watchdog.cancel()
    _check(code, capfd.readouterr().err, before, _tree(*watched), NODE_EXPECT.get(case))


@pytest.mark.ros
@pytest.mark.parametrize("case", ["broken YAML", "diagnostics_period_s 0", "checkpoint random bytes"])
def test_node_process_case(case: str, scratch: Path, root: Path) -> None:
    """The same through the installed process (diagnostics_period_s 0 used to spin a core forever)."""
    from bridge_shadow.ros.launcher import NodeProcess

    watched = (scratch, root / "bags", root / "config")
    before = _tree(*watched)
    with NodeProcess(["--ros-args", *(a.format(w=scratch) for a in NODE_CASES[case])]) as node:
        assert node.proc is not None
        code = node.proc.wait(30)
        err = node.output()
    _check(code, err, before, _tree(*watched))
