"""The bridge's settlement stiffness A against the shell's drilling penalty and the mesh level.

Part 1 re-solves the default-mesh bridge with every shell's ``drill_factor`` set over six decades
and prints A (common and differential mode) as a ratio of A at the default, with the seconds of
each re-solve as a ratio of the first. Part 2 prints A, u0 and the thermal terms at the coarse,
default and fine mesh levels, to set the element's effect beside the mesh's.

Run: ``.venv/bin/python benchmarks/surrogate_drilling.py [LEVEL ...]`` (default: coarse default fine).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bridge_shadow.fe import LinearStaticSolver
from bridge_shadow.fe.elements.shell import DRILL_FACTOR
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.mesh import CENTRAL_BEARINGS
from bridge_shadow.model.solution import solve_bridge

FACTORS = (1e-6, 1e-4, 1e-2, 1e-1, 1.0, 10.0)


def modes(a: np.ndarray) -> tuple[float, float]:
    """Return the common (A11 + A12) and differential (A11 - A12) settlement stiffness, N/m."""
    return float(a[0, 0] + a[0, 1]), float(a[0, 0] - a[0, 1])


def drilling(cfg: object) -> None:
    """Part 1: A of the default mesh for each drilling factor."""
    sol = solve_bridge(cfg, "default")  # type: ignore[arg-type]
    model = sol.model
    rows = []
    for f in FACTORS:
        for shells in model.shells:
            shells.drill_factor[:] = f
        t0 = time.perf_counter()
        a = LinearStaticSolver(model).support_stiffness(list(CENTRAL_BEARINGS), "uz")
        rows.append((f, a, time.perf_counter() - t0))
    ref = dict((f, a) for f, a, _ in rows)[DRILL_FACTOR]
    common0, diff0 = modes(ref)
    print(f"1. default mesh, A against DRILL_FACTOR (ratio to the default {DRILL_FACTOR:g})")
    head = f"{'factor':>8s} {'A11 kN/mm':>10s} {'A12 kN/mm':>10s} {'common':>8s} {'diff':>8s} {'s/first':>8s}"
    print(f"   {head}")
    for f, a, sec in rows:
        common, diff = modes(a)
        print(
            f"   {f:8g} {a[0, 0] / 1e6:10.4f} {a[0, 1] / 1e6:10.4f} {common / common0:8.5f} "
            f"{diff / diff0:8.5f} {sec / rows[0][2]:8.2f}"
        )


def levels(cfg: object, names: list[str]) -> None:
    """Part 2: the surrogate at each mesh level."""
    print("\n2. mesh levels (default drilling factor)")
    print(f"   {'level':8s} {'DOFs':>7s} {'s':>6s} {'A11':>8s} {'A12':>8s} {'common':>7s} {'diff':>7s} "
          f"{'u0 kN':>8s} {'unif N/K':>9s} {'vert N/K':>9s} {'trans N/K':>9s}")  # fmt: skip
    for name in names:
        sol = solve_bridge(cfg, name)  # type: ignore[arg-type]
        common, diff = modes(sol.A)
        th = sol.thermal
        print(
            f"   {name:8s} {sol.n_free:7d} {sol.seconds:6.1f} {sol.A[0, 0] / 1e6:8.3f} "
            f"{sol.A[0, 1] / 1e6:8.3f} "
            f"{common / 1e6:7.3f} {diff / 1e6:7.3f} {sol.u0[0] / 1e3:8.2f} {th['uniform'][0]:9.2f} "
            f"{th['vertical_gradient'][0]:9.1f} {th['transverse_gradient'][0]:9.1f}"
        )


def main(argv: list[str]) -> int:
    """Run both parts."""
    cfg = load_bridge_config()
    drilling(cfg)
    levels(cfg, argv or ["coarse", "default", "fine"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
