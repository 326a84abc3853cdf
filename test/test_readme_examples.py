"""Every command-line example of the README stays true: it parses, its inputs exist, cheap ones run.

The examples are read from the README's ``bash`` blocks (``$B`` is ``.venv/bin/bridge-shadow``).
Every ``bridge-shadow`` example is parsed by the real argument parser (a renamed or removed flag
fails here) and every input path it names must exist (a bag, a surrogate, the shared data). The
cheap ones run for real, as written (paths under ``/tmp`` go to a scratch directory). The others
are skipped with the reason in ``NOT_RUN``: minutes of work, files the repository commits, the
node that runs until it is stopped, installers; where the same command runs in another test, the
reason names it. ``make`` targets are checked with ``make -n`` (nothing runs).
"""

from __future__ import annotations

import contextlib
import glob
import io
import re
import shlex
import subprocess
from pathlib import Path

import pytest

from bridge_shadow.cli import build_parser, main

#: Examples that do not run here, and why (the command as written in the README -> reason).
NOT_RUN = {
    "$B replay bags/demo_3d --json --out /tmp/out_bag --plots /tmp/plots": (
        "the same flags on baseline_1d: test_replay.py::test_replay_json_outputs_and_plots"
    ),
    "$B replay bags/demo_3d --live --plots /tmp/live_plots": (
        "30 s through a node; --live --out --plots on baseline_1d: test_ros_node.py"
    ),
    "$B replay bags/demo_3d --live --rate 3600 --watch": (
        "72 s of pacing by design; --rate at two speeds: test_replay_rates.py"
    ),
    "$B replay bags/demo_3d --surrogate config/surrogate_fe.yaml": (
        "a second replay of the demo bag; replay --surrogate config/surrogate_fe.yaml: "
        "test_surrogate_choice.py::test_replay_uses_the_calibrated_surrogate_unless_told_otherwise"
    ),
    "$B gap bags/demo_3d --report /tmp/gap": "15-25 s; the gap on the demo bag: test_gap_shadow.py",
    "$B verify": "the verification suite: test_fe_verify.py",
    "$B surrogate --json": (
        "a default-mesh FE solve with sensitivities; surrogate --json: "
        "test_surrogate_fe.py::test_cli_json_overrides_vtk_with_deflected_shapes_and_png"
    ),
    "$B calibrate": "60-90 s of FE solves (minutes on a busy machine)",
    "$B synth --out /tmp/scour --days 3 --rate 0.1 --effect settlement_drift=2e-4": (
        "a 3-day twin bag; synth's command line and the bundled bags rebuilt from theirs: "
        "test_synth.py::test_readme_command_rebuilds_the_bag"
    ),
    "$B import-csv ../shared/data/munich-bridge-data/Settlements/*.zip --out /tmp/real": (
        "the real records imported the same way: test_replay.py::test_replay_on_the_real_records"
    ),
    "$B gap /tmp/real --imposed 2022-04-11T09:00=-0.01,-0.01": (
        "needs the import above; the same gap: test_gap_realdata.py"
    ),
    "$B synth --out /tmp/soft --days 3 --rate 0.1 --effect support_spring=2e7 --step 1.5:-0.01:-0.01": (
        "this twin (3 days, 0.1 Hz, support_spring 2e7, 10 mm down at day 1.5), simulated in "
        "test_gap_model_form.py::test_a_known_lowering_lets_the_diagnosis_name_the_support_spring"
    ),
    "$B calibrate --prior-sensitivity": "minutes of FE solves (every explanation under every prior set)",
    "$B calibrate --out config/surrogate.yaml --report docs --prior-sensitivity --force": (
        "rewrites committed files (make models does, with --force), and takes minutes"
    ),
    "$B calibrate --only support_springs --only connector_slip --json": "20-40 s of FE solves",
    "$B calibrate --check config/surrogate.yaml": "the same check: test_calibrate_check.py",
    "$B calibrate --check config/surrogate_fe.yaml": "the same check (exit 1): test_calibrate_check.py",
    "$B calibrate later_pairs.yaml --check config/surrogate.yaml": (
        "later_pairs.yaml is the reader's own file (the README says so)"
    ),
    "$B calibrate later_pairs.yaml --check config/surrogate.yaml --baseline-change sun": (
        "the reader's own file; --check --baseline-change sun on the real pair: "
        "test_calibrate_sun.py::test_cli_check_with_the_sun_on_the_real_pair"
    ),
    ".venv/bin/bridge_shadow_node --ros-args --params-file config/shadow.yaml": (
        "runs until stopped; started and stopped with these parameters: test_ros_node.py"
    ),
    "make demo": "runs `$B replay bags/demo_3d` (run here); `make -n demo` checks the target",
    "make test": "this suite",
    "make models": "rewrites committed files, minutes; `make -n models` checks it passes --force",
    "sudo apt-get install libblas3 liblapack3": "an installer: changes the machine",
    ".venv/bin/pip install -e '.[opensees]'": "an installer: changes the venv",
    "sudo apt-get install libsuitesparse-dev": "an installer: changes the machine",
    ".venv/bin/pip install -e '.[cholmod]'": "an installer: changes the venv (GPL extra)",
    "$B synth --archive /tmp/fleet --bridges 3 --days 7 --rate 1": (
        "about 100 s of twin generation; synth --archive: test_synth_stream.py::test_synth_archive_command"
    ),
    "$B archive /tmp/fleet": (
        "needs the archive above (minutes); the archive of a synth fleet: "
        "test_archive.py::test_a_synth_fleet_equals_serial_replay_per_bridge"
    ),
    "$B archive /tmp/fleet --scheduler tcp://127.0.0.1:8786 --out /tmp/fleet.out": (
        "needs the scheduler below; archive --scheduler on a running scheduler: "
        "test_archive.py::test_cli_reruns_from_the_cache_and_names_the_broken_bag"
    ),
    ".venv/bin/dask scheduler --host 127.0.0.1 --port 8786 --dashboard-address 127.0.0.1:0 &": (
        "a server that runs until stopped; a scheduler on loopback: "
        "test_archive.py::test_the_engine_listens_on_loopback_only"
    ),
    ".venv/bin/dask worker tcp://127.0.0.1:8786 --host 127.0.0.1 --nworkers 2 --nthreads 1 "
    "--dashboard-address 127.0.0.1:0 &": "workers of the scheduler above, until stopped",
    ".venv/bin/bridge_shadow_fleet fleet.yaml": (
        "fleet.yaml is the reader's own manifest, and the nodes run until stopped; a fleet of two: "
        "test_ros_fleet.py::test_a_fleet_runs_each_bridge_with_its_own_model"
    ),
    ".venv/bin/python benchmarks/archive_scale.py": "a benchmark: about 15 minutes with generation",
    ".venv/bin/python benchmarks/archive_scale.py --cases 1hz-365d": "a benchmark: hours",
    ".venv/bin/python benchmarks/archive_scale.py --cases 100hz-4d": "a benchmark: 8 GB of bags, 15 min",
    ".venv/bin/python benchmarks/archive_scale.py --cases 100hz-30d": "a benchmark: 58 GB of bags, an hour",
}
#: Examples that run here, for real (test_help_and_the_demo_replay_run).
RUN = {".venv/bin/bridge-shadow --help", "$B replay bags/demo_3d"}
#: Input paths of the examples that must exist (outputs and the reader's own files are exempt).
OUTPUT_FLAGS = {"--out", "--plots", "--report"}
NOT_INPUTS = {"later_pairs.yaml"}
#: Where the README's examples read the real records (``../shared`` beside the checkout).
SHARED_IN_README = "../shared/data/munich-bridge-data"


def _examples(readme: str) -> list[str]:
    """Commands of the README's bash blocks, as written (comments and ``B=...`` dropped)."""
    out = []
    for block in re.findall(r"```bash\n(.*?)```", readme, re.S):
        for line in block.splitlines():
            command = line.split(" # ")[0].split("  #")[0].strip()
            if command and not command.startswith(("#", "B=")):
                out.append(command)
    return out


@pytest.fixture(scope="module")
def examples(root: Path) -> list[str]:
    found = _examples((root / "README.md").read_text(encoding="utf-8"))
    assert len(found) > 20
    return found


def _argv(command: str) -> list[str] | None:
    """``bridge-shadow`` arguments of an example (None for other programs); globs expanded."""
    words = shlex.split(command)
    if words[0] == "$B" or words[0].endswith("/bridge-shadow"):
        args = []
        for w in words[1:]:
            expanded = sorted(glob.glob(w)) if "*" in w else [w]
            args += expanded or [w]
        return args
    return None


def test_every_bridge_shadow_example_parses_and_its_inputs_exist(
    examples: list[str], root: Path, munich_data: Path
) -> None:
    """``munich_data``: the shared records must be there for the import example's glob."""
    parser = build_parser()
    checked = 0
    with contextlib.chdir(root):
        for command in examples:
            # the README names the shared records beside the checkout; a clone elsewhere finds
            # them where ``shared_data_dir`` does (the ``munich_data`` fixture)
            argv = _argv(command.replace(SHARED_IN_README, str(munich_data)))
            if argv is None:
                continue
            if argv == ["--help"]:
                continue  # runs below
            args = parser.parse_args(argv)  # SystemExit (test error) on a flag that is gone
            words = argv[1:]
            for i, w in enumerate(words):
                previous = words[i - 1] if i else ""
                if previous in OUTPUT_FLAGS or w.startswith("-") or w in NOT_INPUTS or "=" in w or "://" in w:
                    continue
                if "/" in w or w.endswith((".yaml", ".zip")):
                    if w.startswith("/tmp/"):
                        continue  # made by an earlier example (import-csv, synth)
                    assert Path(w).exists(), f"{command}: {w} does not exist"
            checked += 1
            assert args.command == argv[0]
    assert checked >= 18


def test_every_example_runs_or_says_why_not(examples: list[str]) -> None:
    assert set(examples) == RUN | set(NOT_RUN), sorted(set(examples) ^ (RUN | set(NOT_RUN)))
    assert not RUN & set(NOT_RUN)


def test_the_tests_named_as_covering_an_example_exist(root: Path) -> None:
    """A reason that names another test names one that is there (it cannot rot unseen)."""
    named = 0
    for reason in NOT_RUN.values():
        for file, test in re.findall(r"(test_[a-z_]+\.py)(?:::(test_[a-z0-9_]+))?", reason):
            text = (root / "test" / file).read_text(encoding="utf-8")
            assert not test or f"def {test}(" in text, f"{file}::{test}"
            named += 1
    assert named >= 10


@pytest.mark.parametrize("target", ["demo", "test", "models"])
def test_make_targets_exist(root: Path, target: str) -> None:
    """``make -n`` prints what a target would run and runs nothing; models replaces with --force."""
    out = subprocess.run(["make", "-n", target], cwd=root, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    if target == "models":
        assert out.stdout.count("--force") == 2  # the two committed surrogates are replaced on purpose


def test_help_and_the_demo_replay_run(root: Path) -> None:
    """``bridge-shadow --help`` and ``$B replay bags/demo_3d`` (what ``make demo`` runs), for real."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as done:
        main(["--help"])
    assert done.value.code == 0 and "replay" in out.getvalue()
    out = io.StringIO()
    with contextlib.chdir(root), contextlib.redirect_stdout(out):
        assert main(["replay", "bags/demo_3d"]) == 0
    text = out.getvalue()
    assert text.startswith("replay bags/demo_3d: surrogate ") and "posterior settlement" in text
