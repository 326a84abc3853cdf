"""Every writer, interrupted (Ctrl-C, SIGTERM) in the middle of its work, leaves nothing; a rerun works.

The interrupt is a real signal sent to this process at a chosen point of the writer's work (the
first window batch of a streamed bag, the rename that would publish a finished file), so the
signal handler runs where a user's Ctrl-C or a service manager's SIGTERM could land: Python's own
SIGINT handler raises KeyboardInterrupt, ``cli.main`` turns SIGTERM into ``cli.Terminated``.
Asserted for each: the exit code (130, 143), no temporary file or stage directory, no partial
file at the final path (an old one there is untouched), then the same command without the
interrupt succeeds and writes a readable result. One more runs the command line as its own
process and stops it with SIGTERM from outside while it writes.

Writers and where they are covered: the bag writer (``bagio.BagOutputWriter``: replay --out,
streamed and replacing with --force; import-csv and synth through ``write_monitoring``; the live
replay's --out uses the same staged writer), the surrogate writer (surrogate --out; calibrate
--out calls the same ``save_surrogate``), reports and plots (``fileio.atomic_write``: a
calibration figure here; replay --plots and gap --report write each file through the same
helper), checkpoints (``estimate.state.checkpoint.save_state``: replay --checkpoint; the node's SIGTERM
checkpoint in ``test_ros_node.py``).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from bridge_shadow.cli import EXIT_TERMINATED, main

FE_COARSE = ["--mesh", "coarse", "--no-sensitivities"]
TINY_CSV = "Time (-),FRC-01 (kN),FRC-02 (kN)\n" + "".join(
    f"2022-03-07 16:35:{s:02d}.000,260.{s % 7},221.{s % 5}\n" for s in range(30)
)


def _leftovers(directory: Path) -> list[str]:
    """Temporary files and stage directories of this package's writers (``.NAME.<pid>.tmp``)."""
    return sorted(p.name for p in directory.rglob(".*.tmp"))


def _signal_on_first(
    monkeypatch: pytest.MonkeyPatch, owner: Any, name: str, sig: int, when: Callable[..., bool]
) -> list:
    """Wrap ``owner.name``: on its first call for which ``when(*args)`` holds, send ``sig`` to us."""
    real = getattr(owner, name)
    fired: list[bool] = []

    def hooked(*args: Any, **kwargs: Any) -> Any:
        if not fired and when(*args):
            fired.append(True)
            os.kill(os.getpid(), sig)  # the handler runs before the next line: mid-write
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, hooked)
    return fired


def _on_publish(monkeypatch: pytest.MonkeyPatch, target: Path, sig: int) -> list:
    """Signal when a finished file or bag would be renamed to ``target`` (its temporary exists)."""
    return _signal_on_first(monkeypatch, os, "replace", sig, lambda src, dst: Path(dst) == target)


@pytest.fixture(scope="module")
def small_bag(synth_bag) -> str:
    """Three hours of a twin bag (forces every 10 s): a replay of it takes a fraction of a second."""
    return str(synth_bag(days=0.125, rate_hz=0.1, seed=5))


def _interrupted(monkeypatch: pytest.MonkeyPatch, argv: list[str], fired: list, code: int) -> None:
    assert main(argv) == code
    assert fired, "the interrupt never came: the test hooked the wrong place"
    monkeypatch.undo()


def test_replay_out_interrupted_mid_stream(small_bag: str, tmp_path: Path, monkeypatch) -> None:
    from bridge_shadow.bagio import read_raw_topics
    from bridge_shadow.contract import FLOAT_ARRAY_TYPE, MEAN_TOPIC
    from bridge_shadow.replay.outputs import OutputBag

    out = tmp_path / "out"
    argv = ["replay", small_bag, "--out", str(out), "--json"]
    fired = _signal_on_first(monkeypatch, OutputBag, "write", signal.SIGTERM, lambda *a: True)
    _interrupted(monkeypatch, argv, fired, EXIT_TERMINATED)
    assert not out.exists() and _leftovers(tmp_path) == []  # a partial bag used to block the rerun
    assert main(argv) == 0
    assert len(read_raw_topics(out, {MEAN_TOPIC: FLOAT_ARRAY_TYPE})[MEAN_TOPIC][1]) > 100


def test_replay_out_force_interrupted_keeps_the_old_bag(small_bag: str, tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "out"
    argv = ["replay", small_bag, "--out", str(out), "--json"]
    assert main(argv) == 0
    old = {p.name: p.read_bytes() for p in out.iterdir()}
    fired = _on_publish(monkeypatch, out, signal.SIGTERM)
    _interrupted(monkeypatch, [*argv, "--force"], fired, EXIT_TERMINATED)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == old and _leftovers(tmp_path) == []
    assert main([*argv, "--force"]) == 0


def test_import_csv_and_synth_interrupted(tmp_path: Path, monkeypatch) -> None:
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.twin.truth import read_truth

    csv = tmp_path / "force.csv"
    csv.write_text(TINY_CSV)
    bag = tmp_path / "imported"
    argv = ["import-csv", str(csv), "--date", "2022-03-07", "--out", str(bag), "--json"]
    _interrupted(monkeypatch, argv, _on_publish(monkeypatch, bag, signal.SIGTERM), EXIT_TERMINATED)
    assert not bag.exists() and _leftovers(tmp_path) == []
    assert main(argv) == 0 and len(read_monitoring(bag, required=False).forces["frc_01"]) == 30

    twin = tmp_path / "twin"
    argv = ["synth", "--out", str(twin), "--days", "0.02", "--rate", "0.1", "--json"]
    _interrupted(monkeypatch, argv, _on_publish(monkeypatch, twin, signal.SIGINT), 130)
    assert not twin.exists() and _leftovers(tmp_path) == []
    assert main(argv) == 0 and read_truth(twin)["days"] == pytest.approx(0.02)  # the truth came with it


def test_surrogate_out_interrupted(tmp_path: Path, monkeypatch) -> None:
    from bridge_shadow.model.surrogate_file import load_surrogate

    out = tmp_path / "s.yaml"
    argv = ["surrogate", *FE_COARSE, "--out", str(out), "--json", "--no-sweeps"]
    _interrupted(monkeypatch, argv, _on_publish(monkeypatch, out, signal.SIGTERM), EXIT_TERMINATED)
    assert not out.exists() and _leftovers(tmp_path) == []
    assert main(argv) == 0 and load_surrogate(out).condition_number < 10


def test_replay_checkpoint_interrupted(small_bag: str, tmp_path: Path, monkeypatch) -> None:
    from bridge_shadow.estimate.state.checkpoint import load_state

    state = tmp_path / "state.npz"
    argv = ["replay", small_bag, "--checkpoint", str(state), "--json"]
    _interrupted(monkeypatch, argv, _on_publish(monkeypatch, state, signal.SIGTERM), EXIT_TERMINATED)
    assert not state.exists() and _leftovers(tmp_path) == []
    assert main(argv) == 0 and load_state(state)


def test_a_chains_replay_stopped_after_its_feed_leaves_the_checkpoint_as_it_was(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """A bag whose air runs past its forces, replayed with --checkpoint and --out, stopped at --out's end.

    The checkpoint (the state after the last force, the air past it held) was written before that
    air was fed for the bag's own result and before --out was finished: a run stopped there exited
    130 with the bag taken whole, and its rerun rejected every message (exit 1, "no window updated
    the estimate"). Now it is written once the run is complete: the stopped run leaves its last
    periodic one (every ``checkpoint_period_s`` of data, mid-bag), and the rerun goes on from it
    to where an uninterrupted run ends, checkpoint and all.
    """
    import json

    import numpy as np
    from test_air_tail import _record

    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.estimate import Shadow

    bag = write_monitoring(tmp_path / "one", _record(0, 30, np.array([2e-4, -1e-4]), 6.0, 1))
    ck, out = tmp_path / "ck.npz", tmp_path / "out"
    argv = ["replay", str(bag), "--checkpoint", str(ck), "--out", str(out), "--json"]
    _interrupted(monkeypatch, argv, _on_publish(monkeypatch, out, signal.SIGTERM), EXIT_TERMINATED)
    assert not out.exists() and _leftovers(tmp_path) == []
    capsys.readouterr()
    assert main(argv) == 0
    rerun = json.loads(capsys.readouterr().out)
    whole = tmp_path / "whole.npz"
    assert main(["replay", str(bag), "--checkpoint", str(whole), "--json"]) == 0
    once = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(rerun["posterior"]["mean_m"], once["posterior"]["mean_m"], rtol=1e-12)
    held, held_once = Shadow.resume(ck).held_air, Shadow.resume(whole).held_air
    assert held is not None and held_once is not None and len(held) == len(held_once) > 200


def test_a_figure_interrupted(tmp_path: Path, monkeypatch) -> None:
    """A figure of calibrate --report (and of replay --plots, gap --report: the same atomic write)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bridge_shadow.calibrate.report import _save

    path = tmp_path / "calibration_records.png"
    fired = _on_publish(monkeypatch, path, signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        _save(plt.figure(), path)
    assert fired and not path.exists() and _leftovers(tmp_path) == []
    monkeypatch.undo()
    assert _save(plt.figure(), path).stat().st_size > 0


def test_sigterm_from_outside_while_a_bag_is_written(root: Path, tmp_path: Path) -> None:
    """The command line as its own process: SIGTERM while the streamed --out bag is open."""
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "bridge_shadow.cli", "replay", "bags/demo_3d", "--out", str(out), "--json"],
        cwd=root,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60.0
    while not _leftovers(tmp_path):  # the stage of the bag: the writer is at work
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        assert time.monotonic() < deadline, "the replay never opened its --out bag"
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(60) == EXIT_TERMINATED
    assert proc.stderr is not None
    assert proc.stderr.read().strip() == "bridge-shadow replay: terminated (SIGTERM)"
    assert not out.exists() and _leftovers(tmp_path) == []
