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


@pytest.mark.parametrize("name", list(COMMANDS))
def test_an_unknown_option_is_named_by_its_command(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``bridge-shadow replay --nosuch BAG``: the command's usage and ``bridge-shadow replay: error``.

    The top level's usage (``bridge-shadow [-h] [--version] COMMAND ...``) says nothing of the
    options the command has.
    """
    from bridge_shadow.cli import main

    required = ["--out", "never_written"] if name in ("synth", "import-csv") else []
    with pytest.raises(SystemExit) as stop:
        main([name, *required, "--nosuch-option", "x", "y", "z"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert f"usage: bridge-shadow {name} " in err
    assert f"bridge-shadow {name}: error: unrecognized arguments: --nosuch-option" in err
