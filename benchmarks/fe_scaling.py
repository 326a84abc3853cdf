"""FE solver scaling on the Scordelis-Lo roof: assembly, factorization and solve times vs DOFs.

Prints one row per mesh, the growth exponents (log-log slope of time over DOFs), every time as a
ratio of the smallest mesh's total measured in the same run, and, if ``openseespy`` imports, our
total time as a ratio of OpenSeesPy's ASDShellQ4 on the same mesh (skipped when absent).

Run: ``.venv/bin/python benchmarks/fe_scaling.py [N ...]`` (default meshes 32 64 132; 132 -> ~105k DOF).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bridge_shadow.fe import LinearStaticSolver
from bridge_shadow.fe.verify import scordelis_lo_model


def ours(n: int) -> dict[str, float]:
    """Time our solver on an n x n quarter roof."""
    model, case, i = scordelis_lo_model(n)
    c0 = time.process_time()
    t0 = time.perf_counter()
    solver = LinearStaticSolver(model)
    t1 = time.perf_counter()
    w = -solver.solve(case).u[i, 2]
    t2 = time.perf_counter()
    cpu = time.process_time() - c0
    return {
        "n": n,
        "dofs": solver.n_free,
        "assembly": solver.timings["assembly"],
        "factorization": solver.timings["factorization"],
        "solve": t2 - t1,
        "total": t2 - t0,
        "cpu": cpu,
        "w": w,
        "backend": solver.backend,
    }


def opensees(n: int) -> dict[str, float] | None:
    """OpenSeesPy ASDShellQ4 (linear static, UmfPack) on the same mesh: seconds and w, or None if absent."""
    try:
        import openseespy.opensees as ops  # type: ignore[import-not-found]
    except Exception:
        return None
    model, _, i = scordelis_lo_model(n)
    shell = model.shells[0]
    t0 = time.perf_counter()
    ops.wipe()
    ops.model("basic", "-ndm", 3, "-ndf", 6)
    for k, (x, y, z) in enumerate(model.nodes):
        ops.node(k + 1, float(x), float(y), float(z))
    for s in model.supports:
        for node in s.nodes:
            ops.fix(int(node) + 1, *[1 if d in s.dofs else 0 for d in range(6)])
    ops.section("ElasticMembranePlateSection", 1, 4.32e8, 0.0, 0.25, 0.0)
    for k, c in enumerate(shell.conn):
        ops.element("ASDShellQ4", k + 1, *[int(v) + 1 for v in c], 1)
    ops.timeSeries("Constant", 1)
    ops.pattern("Plain", 1, 1)
    area = np.zeros(len(model.nodes))
    from bridge_shadow.fe.elements.shell import shell_kinematics, shell_nodal_areas

    np.add.at(area, shell.conn, shell_nodal_areas(shell_kinematics(model.nodes[shell.conn])))
    for k, a in enumerate(area):
        ops.load(k + 1, 0.0, 0.0, -90.0 * a, 0.0, 0.0, 0.0)
    t1 = time.perf_counter()
    ops.system("UmfPack")
    ops.numberer("RCM")
    ops.constraints("Plain")
    ops.integrator("LoadControl", 1.0)
    ops.algorithm("Linear")
    ops.analysis("Static")
    ops.analyze(1)
    w = -ops.nodeDisp(i + 1, 3)
    t2 = time.perf_counter()
    ops.wipe()
    return {"build": t1 - t0, "analyze": t2 - t1, "total": t2 - t0, "w": w}


def main(argv: list[str]) -> int:
    """Run the scaling study."""
    sizes = [int(a) for a in argv] or [32, 64, 132]
    rows = [ours(n) for n in sizes]
    base = rows[0]["total"]
    print("wall-clock seconds per phase; cpu = process CPU seconds of the whole build + solve")
    print(f"Scordelis-Lo quarter roof, backend {rows[0]['backend']}; times in s and as ratios of the "
          f"{sizes[0]}x{sizes[0]} total ({base:.3f} s)")  # fmt: skip
    cols = ("assembly", "factor", "solve", "total", "cpu")
    print(
        f"{'mesh':>8s} {'dofs':>8s} "
        + " ".join(f"{c:>9s}" for c in cols)
        + f" {'ratio':>8s} {'w/0.3024':>9s}"
    )
    for r in rows:
        print(
            f"{r['n']:>4d}x{r['n']:<3d} {r['dofs']:8d} {r['assembly']:9.3f} {r['factorization']:9.3f} "
            f"{r['solve']:9.3f} {r['total']:9.3f} {r['cpu']:9.3f} {r['total'] / base:8.1f} "
            f"{r['w'] / 0.3024:9.5f}"
        )
    dofs = np.log([r["dofs"] for r in rows])
    for key in ("assembly", "factorization", "solve", "total", "cpu"):
        slope = np.polyfit(dofs, np.log([max(r[key], 1e-6) for r in rows]), 1)[0]
        print(f"growth exponent {key:>13s}: {slope:.2f}")
    print("OpenSeesPy ASDShellQ4 on the same meshes (build = model input, analyze = assemble + solve):")
    for r in rows:
        theirs = opensees(r["n"])
        if theirs is None:
            print("  openseespy not importable: comparison skipped")
            break
        print(
            f"  {r['n']}x{r['n']}: theirs build {theirs['build']:.2f} s + analyze {theirs['analyze']:.2f} s; "
            f"ours/theirs total {r['total'] / theirs['total']:.2f}, ours/theirs analyze "
            f"{r['total'] / theirs['analyze']:.2f}; w ours/theirs {r['w'] / theirs['w']:.6f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
