"""Bridge surrogate cost per mesh level: mesh, assembly + factorization, solves, Schur check.

Times, in one run, the base solve of the bridge (mesh generation, model, factorization, the six
load cases) and the independent Schur-complement check at each level, and prints each as a ratio
of the coarse level's total measured in the same run (the sensitivities are adjoint: no more solves).

Run: ``.venv/bin/python benchmarks/surrogate_levels.py [LEVEL ...]`` (default: coarse default fine).
"""

from __future__ import annotations

import sys
import time

from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.solution import solve_bridge
from bridge_shadow.model.surrogate import schur_A


def main(levels: list[str]) -> None:
    """Print one row per mesh level."""
    cfg = load_bridge_config()
    rows = []
    for level in levels:
        t0 = time.perf_counter()
        sol = solve_bridge(cfg, level)
        t1 = time.perf_counter()
        schur_A(cfg, sol.mesh)
        t2 = time.perf_counter()
        rows.append((level, sol.model.n_dofs, t1 - t0, t2 - t1, sol.A[0, 0]))
    base = rows[0][2] + rows[0][3]
    print(f"{'level':<8} {'DOFs':>8} {'solve s':>8} {'schur s':>8} {'total/coarse':>13} {'A11 kN/mm':>10}")
    for level, dofs, ts, tc, a11 in rows:
        print(f"{level:<8} {dofs:>8} {ts:>8.2f} {tc:>8.2f} {(ts + tc) / base:>13.1f} {a11 / 1e6:>10.3f}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["coarse", "default", "fine"])
