"""Files are written whole or not at all, and a failed write leaves the old file and nothing else."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import BagExistsError, BagOutputWriter, read_monitoring, write_monitoring
from bridge_shadow.errors import InputError
from bridge_shadow.fileio import atomic_write, atomic_write_text, check_output_dir, check_output_file
from bridge_shadow.series import MonitoringData


def _data(n: int = 50, level: float = 2.0e5) -> MonitoringData:
    t = 1_700_000_000 * 10**9 + np.arange(n, dtype=np.int64) * 10**9
    return MonitoringData.from_arrays(t, np.full((n, 2), level), t[::10], np.full(len(t[::10]), 8.0))


def _dead_pid() -> int:
    code = "import os; print(os.getpid())"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(done.stdout)


def test_a_failed_atomic_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "report.md"
    atomic_write_text(target, "old\n")
    with pytest.raises(RuntimeError), atomic_write(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["report.md"]


def test_path_checks_create_nothing(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="is a file, not a directory"):
        check_output_file(tmp_path / "f" / "out.yaml")
    with pytest.raises(InputError, match="exists and is not a directory"):
        check_output_dir(tmp_path / "f")
    with pytest.raises(InputError, match="is a directory"):
        check_output_file(tmp_path)
    assert check_output_dir(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_a_bag_appears_whole_or_not_at_all(tmp_path: Path) -> None:
    old = write_monitoring(tmp_path / "bag", _data(level=2.0e5))
    # a failure in the middle of an overwrite: the old bag stays, nothing else is left
    with pytest.raises(RuntimeError), BagOutputWriter(tmp_path / "bag", overwrite=True) as writer:
        writer.write_float64_array("/x", 1, [1.0, 2.0], ["support"])
        raise RuntimeError("interrupted")
    np.testing.assert_array_equal(read_monitoring(old).forces["frc_01"].force_n, 2.0e5)  # set, read back
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
    # a finished overwrite replaces it; a stage left by a killed writer is cleaned up
    orphan = tmp_path / f".bag.{_dead_pid()}.tmp"
    (orphan / "bag").mkdir(parents=True)
    extra = {"truth.yaml": "a: 1\n"}
    write_monitoring(tmp_path / "bag", _data(level=3.0e5), overwrite=True, extra_files=extra)
    np.testing.assert_array_equal(read_monitoring(old).forces["frc_01"].force_n, 3.0e5)  # written, read back
    assert (tmp_path / "bag" / "truth.yaml").read_text() == "a: 1\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
    with pytest.raises(BagExistsError):
        write_monitoring(tmp_path / "bag", _data())


def test_surrogate_out_never_replaces_a_file_that_is_not_a_surrogate(tmp_path: Path) -> None:
    from bridge_shadow.model.surrogate_file import placeholder_surrogate, save_surrogate

    notes = tmp_path / "notes.yaml"
    notes.write_text("bridge_shadow:\n  ros__parameters: {}\n")
    with pytest.raises(InputError, match="not a surrogate file; refusing to overwrite it"):
        save_surrogate(placeholder_surrogate(), notes)
    assert notes.read_text() == "bridge_shadow:\n  ros__parameters: {}\n"
    with pytest.raises(InputError, match="not a surrogate file; refusing to overwrite it"):
        save_surrogate(placeholder_surrogate(), notes, force=True)  # not even with --force
    path = save_surrogate(placeholder_surrogate(), tmp_path / "s.yaml")
    with pytest.raises(InputError, match="exists already; pass --force to replace it"):
        save_surrogate(placeholder_surrogate(), path)
    save_surrogate(placeholder_surrogate(), path, force=True)  # a surrogate may be rewritten, if asked
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.yaml", "s.yaml"]
