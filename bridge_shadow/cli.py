"""``bridge-shadow``: one entry point, one subcommand per job.

Parsing and printing only; the work lives in the functional core. Each subcommand is a module in
``bridge_shadow.commands`` with ``HELP``, ``DESCRIPTION``, ``add_arguments(parser)`` and
``run(args) -> int``; modules keep heavy imports inside ``run`` so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from typing import NoReturn

from bridge_shadow import __version__
from bridge_shadow.errors import BridgeShadowError

__all__ = ["COMMANDS", "EXIT_BROKEN_PIPE", "EXIT_TERMINATED", "Terminated", "build_parser", "main"]

#: Subcommand name -> module implementing it, in the order ``--help`` lists them.
COMMANDS: dict[str, str] = {
    "replay": "bridge_shadow.commands.replay",
    "synth": "bridge_shadow.commands.synth",
    "import-csv": "bridge_shadow.commands.import_csv",
    "surrogate": "bridge_shadow.commands.surrogate",
    "calibrate": "bridge_shadow.commands.calibrate",
    "verify": "bridge_shadow.commands.verify",
    "gap": "bridge_shadow.commands.gap",
    "archive": "bridge_shadow.commands.archive",
}


class _Parser(argparse.ArgumentParser):
    """``argparse``'s parser that keeps its last usage error's text (for ``--json``'s error object)."""

    last_error: str = ""

    def error(self, message: str) -> NoReturn:
        """Keep the message, then report it as argparse does (usage on stderr, exit 2)."""
        _Parser.last_error = f"{self.prog}: error: {message}"
        super().error(message)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every subcommand."""
    parser = _Parser(
        prog="bridge-shadow",
        description=(
            "Digital shadow of the UniBw Munich two-span test bridge: temperature-compensated "
            "Bayesian (Kalman) estimate of the two central-support settlements from the FRC-01/02 "
            "load cells, over a surrogate from the bundled FE solver, with sim-to-real gap "
            "diagnosis. Machine output (--json) is SI: N, m, s, C; with --json a failed command "
            'prints {"error": TEXT, "exit_code": CODE} on stdout too.'
        ),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module_name in COMMANDS.items():
        module = importlib.import_module(module_name)
        cmd = sub.add_parser(
            name,
            help=module.HELP,
            description=getattr(module, "DESCRIPTION", module.HELP),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run, _parser=cmd)
    return parser


#: Exit code after the reader of stdout went away (``replay BAG | head -1``): 128 + SIGPIPE, what
#: the shell reports for a tool that the same pipe ended, so ``set -o pipefail`` scripts see it.
EXIT_BROKEN_PIPE = 128 + 13


#: Exit code after SIGTERM: 128 + 15, what a shell reports for a process the signal ended.
EXIT_TERMINATED = 128 + signal.SIGTERM


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is, so that it unwinds as after Ctrl-C.

    A KeyboardInterrupt, so every writer's cleanup (``fileio.atomic_write``, the staged bag
    writer, a node process) runs as it does on Ctrl-C: temporary files are removed and nothing
    half-written is left at a final path. Python's default for SIGTERM ends the process at once,
    without any of that.
    """


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated


@contextlib.contextmanager
def _sigterm_unwinds() -> Iterator[None]:
    """Turn SIGTERM into ``Terminated`` while the command runs (main thread only), then restore."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _quiet_broken_pipe() -> int:
    """Point stdout at /dev/null (so the interpreter's last flush cannot fail) and exit 141."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # stdout without a file descriptor
        pass
    return EXIT_BROKEN_PIPE


def _json_error(wanted: bool, text: str, code: int) -> None:
    """With ``--json``, say a failure on stdout too: the one JSON object a caller parses there.

    The contract's "with --json, exactly one JSON object on stdout" held only for success: a
    caller's ``json.loads`` of stdout met an empty string on every error.
    """
    if wanted:
        print(json.dumps({"error": text, "exit_code": code}))
        sys.stdout.flush()


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit code.

    Errors a user can cause print one line and exit 2; a closed stdout pipe ends quietly with
    ``EXIT_BROKEN_PIPE`` (141), Ctrl-C with 130 and SIGTERM with ``EXIT_TERMINATED`` (143), each
    after the interrupted writers removed their temporary files.
    """
    started = time.perf_counter()  # end-to-end rates count from here (replay's messages_per_s)
    words = list(sys.argv[1:] if argv is None else argv)
    wants_json = "--json" in words[: words.index("--") if "--" in words else len(words)]
    try:
        parser = build_parser()
        try:
            args, extra = parser.parse_known_args(argv)
            if extra:  # said by the command's parser: its usage, not the top level's
                args._parser.error(f"unrecognized arguments: {' '.join(extra)}")
        except SystemExit as stop:  # --help, --version, a usage error: their text must reach the pipe now
            if stop.code not in (0, None):
                _json_error(wants_json, _Parser.last_error or "usage error", int(stop.code))
            sys.stdout.flush()
            raise
        args.started = started
        try:
            with _sigterm_unwinds():
                code = int(args._run(args) or 0)
                sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
            return code
        except BridgeShadowError as err:
            text = " ".join(str(err).split())  # one line, whatever a library put in the message
            print(f"bridge-shadow {args.command}: error: {text}", file=sys.stderr)
            _json_error(wants_json, text, 2)
            return 2
        except Terminated:
            print(f"bridge-shadow {args.command}: terminated (SIGTERM)", file=sys.stderr)
            _json_error(wants_json, "terminated (SIGTERM)", EXIT_TERMINATED)
            return EXIT_TERMINATED
        except KeyboardInterrupt:
            print(f"bridge-shadow {args.command}: interrupted", file=sys.stderr)
            _json_error(wants_json, "interrupted", 130)
            return 130
    except BrokenPipeError:
        return _quiet_broken_pipe()


if __name__ == "__main__":
    sys.exit(main())
