"""``bridge_shadow_node``: placeholder until the online-shadow issue lands its rclpy node."""

from __future__ import annotations

import sys


def main(args: list[str] | None = None) -> int:
    """Exit with a clear message."""
    print("bridge_shadow_node: the live node is not implemented yet", file=sys.stderr)
    return 1
