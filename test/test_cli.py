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


@pytest.mark.parametrize("name", list(COMMANDS))
def test_with_json_a_usage_error_is_one_json_object_on_stdout(
    name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """With ``--json`` stdout holds exactly one JSON object, also when the command fails to start.

    A caller's ``json.loads(stdout)`` met an empty string on every error before.
    """
    import json

    from bridge_shadow.cli import main

    required = ["--out", "never_written"] if name in ("synth", "import-csv") else []
    with pytest.raises(SystemExit) as stop:
        main([name, *required, "--json", "--nosuch-option"])
    captured = capsys.readouterr()
    got = json.loads(captured.out)
    assert stop.value.code == 2 and got["exit_code"] == 2 and set(got) == {"error", "exit_code"}
    # argparse's own line (a command with a positional argument names that one first)
    assert got["error"].startswith(f"bridge-shadow {name}: error: ") and got["error"] in captured.err


@pytest.mark.parametrize(
    "args",
    [
        ["replay", "no/such/bag", "--json"],
        ["gap", "no/such/bag", "--json"],
        ["archive", "no/such/folder", "--json"],
        ["surrogate", "--mesh", "zzz", "--json"],
        ["import-csv", "no/such.csv", "--out", "never_written", "--json"],
    ],
)
def test_with_json_a_failed_command_says_so_in_one_json_object(
    args: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """The error line on stderr, and on stdout ``{"error": TEXT, "exit_code": 2}``, nothing else."""
    import json

    from bridge_shadow.cli import main

    code = main(args)
    captured = capsys.readouterr()
    assert code == 2
    got = json.loads(captured.out)
    assert set(got) == {"error", "exit_code"} and got["exit_code"] == 2
    assert got["error"] and got["error"] in captured.err  # the same text as the error line


def test_without_json_an_error_leaves_stdout_to_people(capsys: pytest.CaptureFixture[str]) -> None:
    from bridge_shadow.cli import main

    assert main(["replay", "no/such/bag"]) == 2
    assert "{" not in capsys.readouterr().out
