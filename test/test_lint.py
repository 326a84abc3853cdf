"""Lint as a test: ruff (pycodestyle, pyflakes, import order, pep257 docstrings) and its formatter."""

import subprocess
import sys

import pytest

from bridge_shadow.paths import repo_root

PATHS = ["bridge_shadow", "test", "benchmarks", "tools"]


@pytest.mark.parametrize("command", [["check"], ["format", "--check"]], ids=["check", "format"])
def test_ruff_clean(command: list[str]) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", *command, *PATHS],
        cwd=repo_root(),
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
