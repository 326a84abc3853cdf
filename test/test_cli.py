"""The command line: every subcommand is listed and has --help."""

import subprocess
import sys

import pytest

from bridge_shadow.cli import COMMANDS


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "bridge_shadow.cli", *args], capture_output=True, text=True, check=False
    )


def test_help_lists_every_subcommand() -> None:
    proc = _cli("--help")
    assert proc.returncode == 0
    for name in COMMANDS:
        assert name in proc.stdout


@pytest.mark.parametrize("name", list(COMMANDS))
def test_subcommand_help(name: str) -> None:
    proc = _cli(name, "--help")
    assert proc.returncode == 0, proc.stderr
    assert "usage: bridge-shadow " + name in proc.stdout
