"""Lint as a test: ruff (pycodestyle, pyflakes, import order, pep257 docstrings) must be clean."""

import subprocess
import sys

from bridge_shadow.paths import repo_root


def test_ruff_clean() -> None:
    root = repo_root()
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "bridge_shadow", "test", "benchmarks", "tools"],
        cwd=root,
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
