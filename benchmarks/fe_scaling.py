"""FE solver speed and accuracy against OpenSeesPy, interleaved in one run.

1. Scordelis-Lo quarter roof on growing meshes. Each round times our solver (assembly, factorization,
   solve) and then, if it imports, OpenSeesPy's ASDShellQ4 on the same mesh and loads (model input
   through its Python API, then analyze = assemble + UmfPack solve); rounds alternate so that the
   other helpers' load on the machine hits both alike. Medians over the rounds; every time is also
   printed as a ratio of our smallest mesh's total, and ours as a ratio of theirs.
2. Our factorization backends on the largest mesh, interleaved: SuperLU with its own ordering
   (splu-mmd), SuperLU on a METIS order (splu-nd, needs pymetis), CHOLMOD (needs scikit-sparse).
3. MacNeal-Harder straight cantilevers on their standard meshes: our element and ASDShellQ4, ratio
   to the beam-theory reference (the in-plane trapezoid is where membranes lock).

Run: ``.venv/bin/python benchmarks/fe_scaling.py [N ...]`` (default meshes 32 64 132; 132 -> ~105k DOF).
OpenSeesPy is optional (``pip install -e '.[opensees]'``) and its shared library needs the Debian
packages libblas3 and liblapack3; without them this prints what to install and skips its columns.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from bridge_shadow.fe import LinearStaticSolver, SolverError
from bridge_shadow.fe.elements.shell import shell_kinematics, shell_nodal_areas
from bridge_shadow.fe.model import Model
from bridge_shadow.fe.verify.shells import macneal_cantilever, macneal_nodes, scordelis_lo_model

ROUNDS = 3
OPENSEES_HINT = (
    "install it with `.venv/bin/pip install -e '.[opensees]'` (or `pip install openseespy`); its shared "
    "library needs the Debian packages libblas3 and liblapack3: `sudo apt-get install libblas3 liblapack3`"
)


def load_opensees() -> tuple[object | None, str]:
    """Import ``openseespy.opensees``; return the module (or None) and why it did not import."""
    try:
        import openseespy.opensees as ops  # type: ignore[import-not-found]
    except ModuleNotFoundError:
        return None, f"openseespy is not installed: {OPENSEES_HINT}"
    except (ImportError, OSError) as err:  # the wheel is there but its shared library cannot load
        return None, f"openseespy does not load ({err}): {OPENSEES_HINT}"
    return ops, ""


def ours(n: int, backend: str = "auto") -> dict[str, float | str]:
    """Time our solver on an n x n quarter roof."""
    model, case, i = scordelis_lo_model(n)
    c0 = time.process_time()
    t0 = time.perf_counter()
    solver = LinearStaticSolver(model, backend=backend)
    t1 = time.perf_counter()
    w = -solver.solve(case).u[i, 2]
    t2 = time.perf_counter()
    return {
        "dofs": solver.n_free,
        "assembly": solver.timings["assembly"],
        "factorization": solver.timings["factorization"],
        "solve": t2 - t1,
        "total": t2 - t0,
        "cpu": time.process_time() - c0,
        "w": w,
        "backend": solver.backend,
    }


def _opensees_model(ops: object, model: Model, section: tuple[float, float, float]) -> None:
    """Nodes, fixities, an elastic plate section and ASDShellQ4 elements for a one-set shell model."""
    ops.wipe()  # type: ignore[attr-defined]
    ops.model("basic", "-ndm", 3, "-ndf", 6)  # type: ignore[attr-defined]
    for k, (x, y, z) in enumerate(model.nodes):
        ops.node(k + 1, float(x), float(y), float(z))  # type: ignore[attr-defined]
    fixed: dict[int, set[int]] = {}
    for s in model.supports:
        for node in s.nodes:
            fixed.setdefault(int(node), set()).update(s.dofs)
    for node, dofs in fixed.items():
        ops.fix(node + 1, *[1 if d in dofs else 0 for d in range(6)])  # type: ignore[attr-defined]
    E, nu, h = section
    ops.section("ElasticMembranePlateSection", 1, E, nu, h, 0.0)  # type: ignore[attr-defined]
    for k, c in enumerate(model.shells[0].conn):
        ops.element("ASDShellQ4", k + 1, *[int(v) + 1 for v in c], 1)  # type: ignore[attr-defined]
    ops.timeSeries("Constant", 1)  # type: ignore[attr-defined]
    ops.pattern("Plain", 1, 1)  # type: ignore[attr-defined]


def _opensees_analyze(ops: object) -> None:
    for args in (("system", "UmfPack"), ("numberer", "RCM"), ("constraints", "Plain")):
        getattr(ops, args[0])(*args[1:])
    ops.integrator("LoadControl", 1.0)  # type: ignore[attr-defined]
    ops.algorithm("Linear")  # type: ignore[attr-defined]
    ops.analysis("Static")  # type: ignore[attr-defined]
    ops.analyze(1)  # type: ignore[attr-defined]


def theirs(ops: object, n: int) -> dict[str, float]:
    """OpenSeesPy ASDShellQ4 (linear static, UmfPack) on the same roof: seconds and w."""
    model, _, i = scordelis_lo_model(n)
    shell = model.shells[0]
    t0 = time.perf_counter()
    _opensees_model(ops, model, (4.32e8, 0.0, 0.25))
    area = np.zeros(len(model.nodes))
    np.add.at(area, shell.conn, shell_nodal_areas(shell_kinematics(model.nodes[shell.conn])))
    for k, a in enumerate(area):
        ops.load(k + 1, 0.0, 0.0, -90.0 * a, 0.0, 0.0, 0.0)  # type: ignore[attr-defined]
    t1 = time.perf_counter()
    _opensees_analyze(ops)
    w = -ops.nodeDisp(i + 1, 3)  # type: ignore[attr-defined]
    t2 = time.perf_counter()
    ops.wipe()  # type: ignore[attr-defined]
    return {"build": t1 - t0, "analyze": t2 - t1, "total": t2 - t0, "w": w}


def theirs_macneal(ops: object, shape: str, direction: str) -> float:
    """ASDShellQ4 tip deflection of the MacNeal-Harder cantilever (unit tip shear)."""
    from bridge_shadow.fe.model import ShellSet, Support

    nodes = macneal_nodes(shape)
    n0 = np.arange(6)
    conn = np.column_stack([n0, n0 + 1, n0 + 8, n0 + 7])
    clamp = Support("clamp", [0, 7], range(6))
    model = Model(nodes, shells=[ShellSet(conn, 0.1, 1e7, 0.3)], supports=[clamp])
    _opensees_model(ops, model, (1.0e7, 0.3, 0.1))
    d = 2 if direction == "inplane" else 3
    for node in (7, 14):
        ops.load(node, *[0.5 if k == d - 1 else 0.0 for k in range(6)])  # type: ignore[attr-defined]
    _opensees_analyze(ops)
    w = 0.5 * (ops.nodeDisp(7, d) + ops.nodeDisp(14, d))  # type: ignore[attr-defined]
    ops.wipe()  # type: ignore[attr-defined]
    return w


def _median(runs: list[dict], key: str) -> float:
    return statistics.median(float(r[key]) for r in runs)


def scaling(sizes: list[int], ops: object | None) -> None:
    """Part 1: our solver and OpenSeesPy, interleaved per round."""
    mine: dict[int, list[dict]] = {n: [] for n in sizes}
    other: dict[int, list[dict]] = {n: [] for n in sizes}
    for _ in range(ROUNDS):
        for n in sizes:
            mine[n].append(ours(n))
            if ops is not None:
                other[n].append(theirs(ops, n))
    base = _median(mine[sizes[0]], "total")
    print(f"1. Scordelis-Lo quarter roof, median of {ROUNDS} interleaved rounds, wall-clock seconds")
    print(f"   ours: backend {mine[sizes[0]][0]['backend']}; ratio = total / our {sizes[0]}x{sizes[0]} total")
    print(
        f"{'mesh':>9s} {'dofs':>7s} {'assembly':>9s} {'factor':>8s} {'solve':>7s} {'total':>7s} {'cpu':>7s} "
        f"{'ratio':>6s} {'w/0.3024':>9s} | {'OSP build':>9s} {'analyze':>8s} {'total':>7s} {'ours/OSP':>8s} "
        f"{'w/OSP':>9s}"
    )
    for n in sizes:
        m = mine[n]
        row = (
            f"{n:>4d}x{n:<4d} {int(m[0]['dofs']):7d} {_median(m, 'assembly'):9.3f} "
            f"{_median(m, 'factorization'):8.3f} {_median(m, 'solve'):7.3f} {_median(m, 'total'):7.3f} "
            f"{_median(m, 'cpu'):7.3f} {_median(m, 'total') / base:6.1f} {float(m[0]['w']) / 0.3024:9.5f} |"
        )
        if other[n]:
            t = other[n]
            row += (
                f" {_median(t, 'build'):9.3f} {_median(t, 'analyze'):8.3f} {_median(t, 'total'):7.3f} "
                f"{_median(m, 'total') / _median(t, 'total'):8.2f} {float(m[0]['w']) / t[0]['w']:9.5f}"
            )
        else:
            row += "  (OpenSeesPy skipped)"
        print(row)
    dofs = np.log([float(mine[n][0]["dofs"]) for n in sizes])
    if len(sizes) > 1:
        for key in ("assembly", "factorization", "solve", "total"):
            slope = np.polyfit(dofs, np.log([max(_median(mine[n], key), 1e-6) for n in sizes]), 1)[0]
            print(f"   growth exponent of our {key}: {slope:.2f}")


def backends(n: int) -> None:
    """Part 2: every available factorization backend on one mesh, interleaved."""
    names = ["splu-mmd", "splu-nd", "cholmod"]
    runs: dict[str, list[dict]] = {b: [] for b in names}
    missing: dict[str, str] = {}
    for _ in range(ROUNDS):
        for b in names:
            if b in missing:
                continue
            try:
                runs[b].append(ours(n, b))
            except SolverError as err:  # an optional backend that is absent
                missing[b] = str(err)
    print(f"\n2. our factorization backends, {n}x{n} roof, median of {ROUNDS} interleaved rounds")
    base = None
    for b in names:
        if b in missing:
            print(f"   {b:9s} skipped: {missing[b]}")
            continue
        total = _median(runs[b], "total")
        base = base or total
        print(
            f"   {b:9s} factorization {_median(runs[b], 'factorization'):7.3f} s, total {total:7.3f} s "
            f"({total / base:.2f} x splu-mmd)"
        )


def accuracy(ops: object | None) -> None:
    """Part 3: MacNeal-Harder cantilevers, ours and ASDShellQ4."""
    print("\n3. MacNeal-Harder straight cantilever, standard meshes: tip deflection / beam theory")
    print(f"   {'mesh':14s} {'load':10s} {'ours':>7s} {'ASDShellQ4':>10s}")
    for shape in ("rectangular", "trapezoidal", "parallelogram"):
        for direction, ref in (("inplane", 0.1081), ("outofplane", 0.4321)):
            mine = macneal_cantilever(shape, direction).value / ref
            other = "skipped" if ops is None else f"{theirs_macneal(ops, shape, direction) / ref:10.4f}"
            print(f"   {shape:14s} {direction:10s} {mine:7.4f} {other:>10s}")


def main(argv: list[str]) -> int:
    """Run the three parts."""
    sizes = [int(a) for a in argv] or [32, 64, 132]
    ops, why = load_opensees()
    if ops is None:
        print(f"OpenSeesPy comparison skipped: {why}\n")
    scaling(sizes, ops)
    backends(sizes[-1])
    accuracy(ops)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
