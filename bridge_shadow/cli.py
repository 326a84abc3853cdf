"""``bridge-shadow``: one entry point, one subcommand per job.

Parsing and printing only; the work lives in the functional core. Each subcommand is a module in
``bridge_shadow.commands`` with ``HELP``, ``DESCRIPTION``, ``add_arguments(parser)`` and
``run(args) -> int``; modules keep heavy imports inside ``run`` so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from bridge_shadow import __version__
from bridge_shadow.errors import BridgeShadowError

__all__ = ["COMMANDS", "build_parser", "main"]

#: Subcommand name -> module implementing it, in the order ``--help`` lists them.
COMMANDS: dict[str, str] = {
    "replay": "bridge_shadow.commands.replay",
    "synth": "bridge_shadow.commands.synth",
    "import-csv": "bridge_shadow.commands.import_csv",
    "surrogate": "bridge_shadow.commands.surrogate",
    "calibrate": "bridge_shadow.commands.calibrate",
    "verify": "bridge_shadow.commands.verify",
    "gap": "bridge_shadow.commands.gap",
}


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="bridge-shadow",
        description=(
            "Digital shadow of the UniBw Munich two-span test bridge: temperature-compensated "
            "Bayesian (Kalman) estimate of the two central-support settlements from the FRC-01/02 "
            "load cells, over a surrogate from the bundled FE solver, with sim-to-real gap "
            "diagnosis. Machine output (--json) is SI: N, m, s, C."
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
        cmd.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except BridgeShadowError as err:
        text = " ".join(str(err).split())  # one line, whatever a library put in the message
        print(f"bridge-shadow {args.command}: error: {text}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bridge-shadow {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
