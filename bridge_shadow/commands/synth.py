"""``bridge-shadow synth``: not implemented yet (placeholder until its issue lands)."""

from __future__ import annotations

import argparse

from bridge_shadow.errors import BridgeShadowError

HELP = "(not implemented yet)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Accept anything until the real subcommand lands."""
    parser.add_argument("rest", nargs=argparse.REMAINDER)


def run(args: argparse.Namespace) -> int:
    """Fail with a clear message."""
    raise BridgeShadowError("'synth' is not implemented yet")
