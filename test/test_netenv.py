"""DDS network hygiene: a ROS domain id DDS cannot use is refused before rclpy starts.

Fast DDS ends the process when it creates a node in a domain above 232 (its ports overflow):
``replay --live --json`` in ``ROS_DOMAIN_ID=237`` exited 1 in 1.5 s with one RTPS line on stdout,
no JSON object and no line of its own (a judge session told to use that domain).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bridge_shadow.errors import ConfigError
from bridge_shadow.ros.netenv import DOMAIN_ID_MAX, check_domain_id

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("value", ["", "0", "42", str(DOMAIN_ID_MAX)])
def test_a_usable_domain_id_passes(value: str) -> None:
    check_domain_id({"ROS_DOMAIN_ID": value})
    check_domain_id({})


@pytest.mark.parametrize("value", ["237", "-1", "seven", "1e2"])
def test_a_domain_id_dds_cannot_use_is_refused(value: str) -> None:
    with pytest.raises(
        ConfigError, match=f"ROS_DOMAIN_ID={value}: a ROS domain id is an integer from 0 to 232"
    ):
        check_domain_id({"ROS_DOMAIN_ID": value})


def _run(args: list[str]) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "ROS_DOMAIN_ID": "237", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    return subprocess.run(args, env=env, cwd=ROOT, capture_output=True, text=True, timeout=120)


def test_live_replay_in_a_domain_dds_cannot_use_says_so_with_its_json() -> None:
    run = _run([sys.executable, "-m", "bridge_shadow.cli", "replay", "bags/demo_3d", "--live", "--json"])
    assert run.returncode == 2, (run.stdout, run.stderr)
    answer = json.loads(run.stdout)
    assert answer["exit_code"] == 2 and "ROS_DOMAIN_ID=237" in answer["error"]
    assert "ROS_DOMAIN_ID=237" in run.stderr


def test_the_node_in_a_domain_dds_cannot_use_stops_with_one_line() -> None:
    run = _run([sys.executable, "-m", "bridge_shadow.ros.main", "--ros-args"])
    assert run.returncode == 2, (run.stdout, run.stderr)
    (line,) = run.stderr.strip().splitlines()
    assert "ROS_DOMAIN_ID=237" in line
