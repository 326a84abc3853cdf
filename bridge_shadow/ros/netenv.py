"""DDS network hygiene: keep discovery on loopback, in a domain of our own.

Imports no rclpy, so it can run before rclpy reads the environment.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

__all__ = ["DOMAIN_ID_MAX", "check_domain_id", "confine_to_loopback", "unique_domain_id"]

#: The largest ROS domain id whose DDS ports fit (Fast DDS: 7400 + 250 id + 11 below 65536; the
#: ROS 2 documentation's "Domain ID" page gives 232 as the limit on Linux).
DOMAIN_ID_MAX = 232


def unique_domain_id(pid: int | None = None) -> int:
    """Return a ROS domain id in [20, 219] derived from a process id (valid for Fast DDS ports)."""
    return (os.getpid() if pid is None else pid) % 200 + 20


def check_domain_id(environ: MutableMapping[str, str] | None = None) -> None:
    """Refuse a ``ROS_DOMAIN_ID`` that is not an integer in [0, ``DOMAIN_ID_MAX``] (ConfigError).

    Must run before ``rclpy``: Fast DDS ends the process (exit 1, one RTPS line on stdout) when it
    creates a node in such a domain, so ``replay --live --json`` printed no JSON and no error line
    of its own.
    """
    from bridge_shadow.errors import ConfigError

    env = os.environ if environ is None else environ
    raw = env.get("ROS_DOMAIN_ID", "").strip()
    if not raw:
        return
    if not raw.isdigit() or int(raw) > DOMAIN_ID_MAX:
        raise ConfigError(
            f"ROS_DOMAIN_ID={raw}: a ROS domain id is an integer from 0 to {DOMAIN_ID_MAX} (DDS derives "
            "its ports from it); set another, or unset it for one of this process's own"
        )


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
