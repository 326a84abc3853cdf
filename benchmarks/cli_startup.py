"""CLI start-up: wall time of ``bridge-shadow --help`` and of the imports each path pulls in.

Each line is the best of ``--repeat`` fresh interpreters (the venv's python, with its ``.pth``
hooks), printed against ``python -c pass`` in the same run. ``--help`` and ``replay --help`` must
stay near the bare interpreter: the subcommands import their work lazily, and nothing on the
``--help`` path imports scipy.stats, filterpy or rclpy (``test_replay_stream`` asserts that).
``replay`` itself needs the shadow, whose Kalman filter comes from filterpy (which imports
scipy.stats): that cost is printed on its own line. Usage::

    .venv/bin/python benchmarks/cli_startup.py [--repeat R]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

BIN = Path(sys.executable).parent / "bridge-shadow"
PY = sys.executable
CASES: list[tuple[str, list[str]]] = [
    ("python -c pass (baseline)", [PY, "-c", "pass"]),
    ("import bridge_shadow.cli", [PY, "-c", "import bridge_shadow.cli"]),
    ("bridge-shadow --help", [str(BIN), "--help"]),
    ("bridge-shadow replay --help", [str(BIN), "replay", "--help"]),
    ("import bridge_shadow.bagio.stream", [PY, "-c", "import bridge_shadow.bagio.stream"]),
    ("import filterpy.kalman", [PY, "-c", "import filterpy.kalman"]),
    ("import scipy.stats", [PY, "-c", "import scipy.stats"]),
    ("import bridge_shadow.estimate (replay's shadow)", [PY, "-c", "import bridge_shadow.estimate"]),
]


def wall(cmd: list[str], repeat: int) -> float:
    """Best wall time of ``repeat`` runs of ``cmd`` (output discarded)."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    """Print one line per case: seconds and ratio to the bare interpreter."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    base = wall(CASES[0][1], args.repeat)
    for name, cmd in CASES:
        t = base if cmd is CASES[0][1] else wall(cmd, args.repeat)
        print(f"{name:48s} {1e3 * t:8.0f} ms   x{t / base:5.1f} of python -c pass")


if __name__ == "__main__":
    main()
