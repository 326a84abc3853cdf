"""DDS network hygiene: keep discovery on loopback, in a domain of our own.

Imports no rclpy, so it can run before rclpy reads the environment.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

__all__ = ["confine_to_loopback", "unique_domain_id"]


def unique_domain_id(pid: int | None = None) -> int:
    """Return a ROS domain id in [20, 219] derived from a process id (valid for Fast DDS ports)."""
    return (os.getpid() if pid is None else pid) % 200 + 20


def confine_to_loopback(
    environ: MutableMapping[str, str] | None = None, *, new_domain: bool = False
) -> MutableMapping[str, str]:
    """Set ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ``ROS_DOMAIN_ID``; return the env.

    The domain id is kept if already set, unless ``new_domain`` asks for one from this pid.
    Must run before ``rclpy.init``.
    """
    env = os.environ if environ is None else environ
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if new_domain or not env.get("ROS_DOMAIN_ID"):
        env["ROS_DOMAIN_ID"] = str(unique_domain_id())
    return env
