"""Verification cases of the FE solver: published shell benchmarks, patch tests and closed forms.

Each case builds its model from scratch, solves it and returns a :class:`Case` with the computed
value, the reference, their ratio and the tolerance it must meet (``None``: reported only). Cases
whose reference is zero (patch tests, free thermal expansion) report a normalized error as
``computed``, ``reference = 0`` and an absolute tolerance. Nothing is tuned per case: every shell
uses the same element with the same drilling factor.

References (DESIGN section 7): Scordelis-Lo roof 0.3024; pinched cylinder 1.8248e-5; MacNeal-Harder
straight cantilever 0.1081 in-plane / 0.4321 out-of-plane; simply supported plate
``w = 0.0040624 q a^4 / D``; two equal spans: ``dR_mid = -6 EI delta / L^3`` (settlement delta
downward, so the middle reaction drops), ``dR_mid = -3 EI alpha dT / (h L)`` (top warmer),
``R_mid = 5 q L / 4``, and no reaction under uniform temperature with free sliding. The shell
I-girder is reported against those Euler-Bernoulli values and checked (1 %) against Timoshenko
beam theory with the web as shear area.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass

import numpy as np

from bridge_shadow.fe.meshes import fixities, grid, line, node_at
from bridge_shadow.fe.model import BeamLoad, BeamSet, LoadCase, Model, ShellSet, Support, Thermal
from bridge_shadow.fe.solve import LinearStaticSolver

__all__ = ["Case", "run_cases", "scordelis_lo_model", "suite"]


@dataclass
class Case:
    """One verification result (SI units, as the benchmark defines them)."""

    name: str
    computed: float
    reference: float
    ratio: float | None
    tolerance: float | None
    mesh: str
    dofs: int
    seconds: float
    passed: bool | None

    def as_dict(self) -> dict[str, object]:
        """Return the JSON form (keys in the contract's order)."""
        return asdict(self)


def _case(
    name: str, computed: float, reference: float, tol: float | None, mesh: str, dofs: int, seconds: float
) -> Case:
    """Check ``|computed / reference - 1| <= tol``, or ``|computed| <= tol`` when the reference is 0."""
    if reference == 0.0:
        ratio = None
        passed = None if tol is None else bool(abs(computed) <= tol)
    else:
        ratio = computed / reference
        passed = None if tol is None else bool(abs(ratio - 1.0) <= tol)
    return Case(name, float(computed), float(reference), ratio, tol, mesh, int(dofs), float(seconds), passed)


class _Timer:
    def __enter__(self) -> _Timer:
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> None:
        self.seconds = time.perf_counter() - self.t0


# ---------------------------------------------------------------------------------------------- shells


def scordelis_lo_model(n: int) -> tuple[Model, LoadCase, int]:
    """Scordelis-Lo roof quarter model ``n x n``: model, self-weight case, node of the free-edge midpoint."""
    R, L, t = 25.0, 50.0, 0.25
    st, conn = grid(n, n)
    x, th = st[:, 0] * L / 2, st[:, 1] * np.deg2rad(40.0)
    nodes = np.column_stack([x, R * np.sin(th), R * np.cos(th)])
    shell = ShellSet(conn, t, 4.32e8, 0.0, rho=90.0 / t, tag="roof")  # 90 per unit area
    eps = 1e-9
    sup = fixities(
        [
            (np.flatnonzero(np.abs(x) < eps), (1, 2)),  # rigid diaphragm
            (np.flatnonzero(np.abs(x - L / 2) < eps), (0, 4, 5)),  # symmetry x = L/2
            (np.flatnonzero(np.abs(th) < eps), (1, 3, 5)),  # symmetry at the crown
        ]
    )
    i = node_at(nodes, (L / 2, R * np.sin(np.deg2rad(40.0)), R * np.cos(np.deg2rad(40.0))))
    return Model(nodes, shells=[shell], supports=sup), LoadCase("self-weight", gravity=(0.0, 0.0, -1.0)), i


def scordelis_lo(n: int, tol: float | None = 0.01) -> Case:
    """Scordelis-Lo roof, quarter model ``n x n``, vertical displacement at the free-edge midpoint."""
    with _Timer() as tm:
        model, case, i = scordelis_lo_model(n)
        solver = LinearStaticSolver(model)
        w = -solver.solve(case).u[i, 2]
    return _case(f"scordelis_lo_{n}x{n}", w, 0.3024, tol, f"{n}x{n} quarter", solver.n_free, tm.seconds)


def pinched_cylinder(n: int, tol: float | None = 0.02) -> Case:
    """Pinched cylinder with end diaphragms, octant model ``n x n``, radial displacement under the load."""
    with _Timer() as tm:
        R, L, t = 300.0, 600.0, 3.0
        st, conn = grid(n, n)
        x, th = st[:, 0] * L / 2, st[:, 1] * np.pi / 2
        nodes = np.column_stack([x, R * np.sin(th), R * np.cos(th)])
        shell = ShellSet(conn, t, 3.0e6, 0.3, tag="cylinder")
        eps = 1e-9
        sup = fixities(
            [
                (np.flatnonzero(np.abs(x) < eps), (1, 2, 3)),  # rigid diaphragm
                (np.flatnonzero(np.abs(x - L / 2) < eps), (0, 4, 5)),  # symmetry x = L/2
                (np.flatnonzero(np.abs(th) < eps), (1, 3, 5)),  # symmetry plane y = 0
                (np.flatnonzero(np.abs(th - np.pi / 2) < eps), (2, 3, 4)),  # symmetry plane z = 0
            ]
        )
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=sup))
        i = node_at(nodes, (L / 2, 0.0, R))
        res = solver.solve(LoadCase("pinch", nodal=[(i, 2, -0.25)]))  # P = 1, a quarter on the octant
        w = -res.u[i, 2]
    return _case(f"pinched_cylinder_{n}x{n}", w, 1.8248e-5, tol, f"{n}x{n} octant", solver.n_free, tm.seconds)


def _cantilever_nodes(shape: str) -> np.ndarray:
    """MacNeal-Harder straight cantilever 6.0 x 0.2, 6 x 1 elements; bottom row then top row.

    rectangular: straight; trapezoidal: interior edges alternately inclined at +-45 degrees;
    parallelogram: every edge (ends included) inclined at 45 degrees.
    """
    xb = np.arange(7.0)
    if shape == "rectangular":
        xt = xb.copy()
    elif shape == "trapezoidal":
        xt = xb + 0.2 * np.array([0, 1, -1, 1, -1, 1, 0])
    else:
        xt = xb + 0.2
    return np.column_stack([np.concatenate([xb, xt]), np.repeat([0.0, 0.2], 7), np.zeros(14)])


def macneal_cantilever(shape: str, direction: str, tol: float | None) -> Case:
    """MacNeal-Harder straight cantilever, unit tip load in-plane (y) or out-of-plane (z)."""
    with _Timer() as tm:
        nodes = _cantilever_nodes(shape)
        n0 = np.arange(6)
        conn = np.column_stack([n0, n0 + 1, n0 + 8, n0 + 7])
        shell = ShellSet(conn, 0.1, 1.0e7, 0.3, tag="beam")
        model = Model(nodes, shells=[shell], supports=[Support("clamp", [0, 7], (0, 1, 2, 3, 4, 5))])
        solver = LinearStaticSolver(model)
        d = 1 if direction == "inplane" else 2
        res = solver.solve(LoadCase("tip", nodal=[(6, d, 0.5), (13, d, 0.5)]))
        w = 0.5 * (res.u[6, d] + res.u[13, d])
    ref = 0.1081 if direction == "inplane" else 0.4321
    return _case(f"macneal_{shape}_{direction}", w, ref, tol, "6x1", solver.n_free, tm.seconds)


def twisted_beam(direction: str, tol: float | None = None) -> Case:
    """MacNeal-Harder twisted beam (90 degree twist, 12 x 2 warped quads): tip displacement along the load.

    Length 12, width 1.1, thickness 0.32, E = 29e6, nu = 0.22; the width turns from y at the root to
    z at the tip. Unit tip load in the plane of the tip, along z (``inplane``, reference 0.005424),
    or normal to it, along y (``outofplane``, 0.001754); both meshes' quads are warped.
    """
    with _Timer() as tm:
        st, conn = grid(12, 2)
        phi = st[:, 0] * np.pi / 2
        v = (st[:, 1] - 0.5) * 1.1
        nodes = np.column_stack([st[:, 0] * 12.0, v * np.cos(phi), v * np.sin(phi)])
        shell = ShellSet(conn, 0.32, 29.0e6, 0.22, tag="twisted")
        root = np.flatnonzero(st[:, 0] == 0.0)
        tip = np.flatnonzero(st[:, 0] == 1.0)  # ordered across the width
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=[Support("root", root, range(6))]))
        d = 2 if direction == "inplane" else 1
        res = solver.solve(
            LoadCase("tip", nodal=[(int(i), d, f) for i, f in zip(tip, (0.25, 0.5, 0.25), strict=True)])
        )
        w = res.u[tip[1], d]
    ref = 0.005424 if direction == "inplane" else 0.001754
    return _case(f"twisted_beam_{direction}", w, ref, tol, "12x2 warped", solver.n_free, tm.seconds)


def ss_plate(n: int, tol: float | None = 0.01) -> Case:
    """Simply supported square plate (hard support), uniform pressure, quarter model ``n x n``, centre."""
    with _Timer() as tm:
        a, t, E, nu, q = 1.0, 0.001, 2.0e11, 0.3, 1.0
        st, conn = grid(n, n)
        nodes = np.column_stack([st * a / 2, np.zeros(len(st))])
        x, y = nodes[:, 0], nodes[:, 1]
        eps = 1e-9
        sup = fixities(
            [
                (np.flatnonzero(np.abs(x - a / 2) < eps), (2, 3)),  # edge x = a/2: w, rx
                (np.flatnonzero(np.abs(y - a / 2) < eps), (2, 4)),  # edge y = a/2: w, ry
                (np.flatnonzero(np.abs(x) < eps), (0, 4)),  # symmetry
                (np.flatnonzero(np.abs(y) < eps), (1, 3)),  # symmetry
                (np.arange(len(nodes)), (5,)),  # flat plate: drilling stays at rest
            ]
        )
        shell = ShellSet(conn, t, E, nu, tag="plate")
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=sup))
        res = solver.solve(LoadCase("q", pressure={"plate": -q}))
        d = E * t**3 / (12 * (1 - nu**2))
        w = -res.u[node_at(nodes, (0.0, 0.0, 0.0)), 2] * d / (q * a**4)
    return _case(f"ss_plate_{n}x{n}", w, 0.0040624, tol, f"{n}x{n} quarter", solver.n_free, tm.seconds)


_PATCH_INNER = np.array([[0.04, 0.02], [0.18, 0.03], [0.16, 0.08], [0.08, 0.08]])


def _patch_mesh() -> tuple[np.ndarray, np.ndarray]:
    """MacNeal-Harder patch 0.24 x 0.12 with 4 distorted interior nodes: 8 nodes, 5 quads."""
    outer = np.array([[0.0, 0.0], [0.24, 0.0], [0.24, 0.12], [0.0, 0.12]])
    xy = np.vstack([outer, _PATCH_INNER])
    conn = np.array([[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7], [4, 5, 6, 7]])
    return np.column_stack([xy, np.zeros(8)]), conn


def patch_test(kind: str, inner: np.ndarray | None = None, tol: float | None = 1e-8) -> Case:
    """Membrane or bending patch test: boundary nodes follow an exact constant-strain field.

    ``computed`` is the largest error of the interior nodes' DOFs over the largest DOF value.
    ``inner`` (4, 2) replaces the interior node positions (property tests use random ones).
    """
    with _Timer() as tm:
        nodes, conn = _patch_mesh()
        if inner is not None:
            nodes[4:, :2] = inner
        x, y = nodes[:, 0], nodes[:, 1]
        exact = np.zeros((8, 6))
        if kind == "membrane":
            exact[:, 0] = 1e-3 * (x + y / 2)
            exact[:, 1] = 1e-3 * (y + x / 2)
            exact[:, 5] = 0.5 * (1e-3 / 2 - 1e-3 / 2)  # omega = (v,x - u,y) / 2 = 0
        else:
            w = 1e-3 * (x**2 + x * y + y**2) / 2
            exact[:, 2] = w
            exact[:, 3] = 1e-3 * (x / 2 + y)  # rx = w,y
            exact[:, 4] = -1e-3 * (x + y / 2)  # ry = -w,x
        shell = ShellSet(conn, 0.001, 1.0e6, 0.25, tag="patch")
        supports = [Support(f"b{i}", [i], (0, 1, 2, 3, 4, 5)) for i in range(4)]
        solver = LinearStaticSolver(Model(nodes, shells=[shell], supports=supports))
        res = solver.solve(LoadCase("patch", prescribed={f"b{i}": exact[i] for i in range(4)}))
        err = np.abs(res.u[4:] - exact[4:]).max() / np.abs(exact).max()
    return _case(f"patch_{kind}", err, 0.0, tol, "5 quads", solver.n_free, tm.seconds)


def thermal_strip(n: int, tol: float | None = 1e-6) -> Case:
    """Shell strip L x b under a through-thickness gradient, held at one root node: tip deflection.

    A free plate bends into ``kappa = alpha dT / h`` in both directions without stress; the root's
    middle node is clamped (statically determinate), the tip deflection along the axis is
    ``alpha dT L^2 / (2 h)`` downward when the +z face is warmer.
    """
    with _Timer() as tm:
        L, b, h, alpha, dT = 1.0, 0.1, 0.01, 1.2e-5, 10.0
        st, conn = grid(n, 2)
        nodes = np.column_stack([st[:, 0] * L, (st[:, 1] - 0.5) * b, np.zeros(len(st))])
        root = node_at(nodes, (0.0, 0.0, 0.0))
        tip = node_at(nodes, (L, 0.0, 0.0))
        shell = ShellSet(conn, h, 2.1e11, 0.3, alpha=alpha, tag="strip")
        model = Model(nodes, shells=[shell], supports=[Support("root", [root], (0, 1, 2, 3, 4, 5))])
        solver = LinearStaticSolver(model)
        res = solver.solve(LoadCase("gradient", thermal=[Thermal("strip", gradient=dT)]))
        w = -res.u[tip, 2]
    return _case(
        "thermal_strip_gradient", w, alpha * dT * L**2 / (2 * h), tol, f"{n}x2", solver.n_free, tm.seconds
    )


# ----------------------------------------------------------------------------------- two equal spans

_SPAN = 15.0
_E, _NU, _ALPHA = 2.1e11, 0.3, 1.2e-5


def _two_span_beam(n: int) -> tuple[Model, float, float]:
    """Two 15 m spans of an HEB1000-like beam (EI about the strong axis); returns model, EI, depth."""
    h, Iy = 1.0, 6.447e-3
    s, conn = line(2 * n)
    nodes = np.column_stack([s * 2 * _SPAN, np.zeros_like(s), np.zeros_like(s)])
    beam = BeamSet(
        conn,
        A=0.04,
        Iy=Iy,
        Iz=1.6e-4,
        J=1.2e-5,
        E=_E,
        G=_E / (2 * (1 + _NU)),
        alpha=_ALPHA,
        depth_z=h,
        tag="girder",
    )
    supports = [
        Support("west", [0], (0, 1, 2, 3)),
        Support("mid", [n], (1, 2)),
        Support("east", [2 * n], (1, 2)),
    ]
    return Model(nodes, beams=[beam], supports=supports), _E * Iy, h


def _i_girder(n: int) -> tuple[Model, float, float, dict[str, np.ndarray]]:
    """Two 15 m spans of a shell I-girder (web 1.0 m x 19 mm, flanges 0.3 m x 36 mm, mid-surfaces).

    ``n`` elements per span along x; 6 across the web height, 4 across each flange. Bearings
    support the bottom flange across its width; the web is held laterally at the three bearings
    (fork supports); ``west`` also holds the bottom-flange centre longitudinally.
    """
    h, bf, tw, tf = 1.0, 0.3, 0.019, 0.036
    nx, nw, nf = 2 * n, 6, 4
    xs = np.linspace(0.0, 2 * _SPAN, nx + 1)
    nodes_list, index = [], {}

    def node(ix: int, y: float, z: float) -> int:
        key = (ix, round(y, 9), round(z, 9))
        if key not in index:
            index[key] = len(nodes_list)
            nodes_list.append((xs[ix], y, z))
        return index[key]

    ys = np.linspace(-bf / 2, bf / 2, nf + 1)
    zs = np.linspace(0.0, h, nw + 1)
    web, top, bot = [], [], []
    for ix in range(nx):
        for k in range(nw):
            web.append(
                [
                    node(ix, 0, zs[k]),
                    node(ix + 1, 0, zs[k]),
                    node(ix + 1, 0, zs[k + 1]),
                    node(ix, 0, zs[k + 1]),
                ]
            )
        for k in range(nf):
            # counter-clockwise seen from +z: normals point up
            top.append(
                [
                    node(ix, ys[k], h),
                    node(ix + 1, ys[k], h),
                    node(ix + 1, ys[k + 1], h),
                    node(ix, ys[k + 1], h),
                ]
            )
            bot.append(
                [
                    node(ix, ys[k], 0),
                    node(ix + 1, ys[k], 0),
                    node(ix + 1, ys[k + 1], 0),
                    node(ix, ys[k + 1], 0),
                ]
            )
    nodes = np.array(nodes_list)
    shells = [
        ShellSet(np.array(web), tw, _E, _NU, alpha=_ALPHA, tag="web"),
        ShellSet(np.array(top), tf, _E, _NU, alpha=_ALPHA, tag="top"),
        ShellSet(np.array(bot), tf, _E, _NU, alpha=_ALPHA, tag="bottom"),
    ]
    x, y, z = nodes.T
    eps = 1e-9

    def at(xv: float, mask: np.ndarray) -> np.ndarray:
        return np.flatnonzero((np.abs(x - xv) < eps) & mask)

    bottom = np.abs(z) < eps
    on_web = np.abs(y) < eps
    supports = [
        Support("west", at(0.0, bottom), (2,)),
        Support("mid", at(_SPAN, bottom), (2,)),
        Support("east", at(2 * _SPAN, bottom), (2,)),
        Support("fork_west", at(0.0, on_web), (1,)),
        Support("fork_mid", at(_SPAN, on_web), (1,)),
        Support("fork_east", at(2 * _SPAN, on_web), (1,)),
        Support("fix_x", [node_at(nodes, (0.0, 0.0, 0.0))], (0,)),
    ]
    inertia = tw * h**3 / 12 + 2 * (bf * tf**3 / 12 + bf * tf * (h / 2) ** 2)
    model = Model(nodes, shells=shells, supports=supports)
    z_mid = {s.tag: nodes[s.conn][:, :, 2] for s in shells}
    return model, _E * inertia, h, z_mid


def two_span_cases(n_beam: int, n_shell: int) -> Iterator[Case]:
    """Settlement, gradient, uniform load and uniform temperature on two equal spans, beam and shell."""
    L, settle, dT, q = _SPAN, 0.01, 10.0, 25.0e3  # settlement 10 mm downward: uz = -settle
    with _Timer() as tm:
        model, ei, h = _two_span_beam(n_beam)
        solver = LinearStaticSolver(model)
        res = solver.solve(
            [
                LoadCase("settle", prescribed={"mid": [0.0, -settle]}),
                LoadCase("gradient", thermal=[Thermal("girder", gradient=dT)]),
                LoadCase("load", beam_loads=[BeamLoad("girder", (0.0, 0.0, -q))]),
                LoadCase("uniform", thermal=[Thermal("girder", uniform=dT)]),
            ]
        )
    sec = tm.seconds / 4
    mesh, dofs = f"{2 * n_beam} beams", solver.n_free
    rm = [r.reaction("mid", "uz") for r in res]  # type: ignore[union-attr]
    ea = _E * 0.04 * _ALPHA * dT  # restrained thermal force, the scale of a free-sliding error
    yield _case("two_span_beam_settlement", rm[0], -6 * ei * settle / L**3, 0.005, mesh, dofs, sec)
    yield _case("two_span_beam_gradient", rm[1], -3 * ei * _ALPHA * dT / (h * L), 0.005, mesh, dofs, sec)
    yield _case("two_span_beam_uniform_load", rm[2], 5 * q * L / 4, 0.005, mesh, dofs, sec)
    yield _case("two_span_beam_uniform_temperature", abs(rm[3]) / ea, 0.0, 1e-8, mesh, dofs, sec)

    with _Timer() as tm:
        model, ei, h, zn = _i_girder(n_shell)
        solver = LinearStaticSolver(model)
        # T linear over the depth: nodal values in the web, and across each flange's thickness too
        tf = 0.036
        grad = [
            Thermal(tag, uniform=dT * (zn[tag] / h - 0.5), gradient=0.0 if tag == "web" else dT * tf / h)
            for tag in ("web", "top", "bottom")
        ]
        bf = 0.3
        res = solver.solve(
            [
                LoadCase("settle", prescribed={"mid": -settle}),
                LoadCase("gradient", thermal=grad),
                LoadCase("load", pressure={"top": -q / bf}),
                LoadCase("uniform", thermal=[Thermal(tag, uniform=dT) for tag in ("web", "top", "bottom")]),
            ]
        )
    sec = tm.seconds / 4
    mesh, dofs = f"{2 * n_shell}x(6+4+4) shells", solver.n_free
    rm = [r.reaction("mid", "uz") for r in res]  # type: ignore[union-attr]
    area = 1.0 * 0.019 + 2 * 0.3 * 0.036
    ea = _E * area * _ALPHA * dT
    yield _case("two_span_shell_settlement", rm[0], -6 * ei * settle / L**3, None, mesh, dofs, sec)
    yield _case("two_span_shell_gradient", rm[1], -3 * ei * _ALPHA * dT / (h * L), None, mesh, dofs, sec)
    yield _case("two_span_shell_uniform_load", rm[2], 5 * q * L / 4, None, mesh, dofs, sec)
    yield _case("two_span_shell_uniform_temperature", abs(rm[3]) / ea, 0.0, 1e-8, mesh, dofs, sec)
    # Timoshenko beam theory (shear area = web h tw): two spans = a 2L simple beam pushed back at mid-span,
    # flexibility L^3 / (6 EI) + L / (2 G As) under a mid-span force.
    g_as = _E / (2 * (1 + _NU)) * 1.0 * 0.019
    flex = L**3 / (6 * ei) + L / (2 * g_as)
    load_defl = 5 * q * L**4 / (24 * ei) + q * L**2 / (2 * g_as)  # mid-span deflection of the 2L beam under q
    tim = {
        "settlement": -settle / flex,
        "gradient": -(_ALPHA * dT / h) * L**2 / 2 / flex,
        "uniform_load": load_defl / flex,
    }
    for k, (kind, ref) in enumerate(tim.items()):
        yield _case(f"two_span_shell_{kind}_timoshenko", rm[k], ref, 0.01, mesh, dofs, sec)


# ------------------------------------------------------------------------------------------- suite


def suite(quick: bool = False) -> list[Callable[[], Case | list[Case]]]:
    """Return the verification cases as thunks; ``quick`` uses coarser meshes (tolerances still hold)."""
    sl_meshes = (4, 8, 16) if quick else (8, 16, 32)
    cases: list[Callable[[], Case | list[Case]]] = []
    for n in sl_meshes:
        cases.append(lambda n=n: scordelis_lo(n, tol=0.01 if n >= 16 else None))
    cases.append(lambda: pinched_cylinder(16, tol=None))
    cases.append(lambda: pinched_cylinder(32, tol=0.02))
    for shape in ("rectangular", "trapezoidal", "parallelogram"):
        for direction in ("inplane", "outofplane"):
            tol = 0.02 if shape == "rectangular" else None
            cases.append(lambda s=shape, d=direction, t=tol: macneal_cantilever(s, d, t))
    cases.append(lambda: twisted_beam("inplane", tol=0.02))
    cases.append(lambda: twisted_beam("outofplane", tol=0.02))
    cases.append(lambda: ss_plate(8))
    cases.append(lambda: patch_test("membrane"))
    cases.append(lambda: patch_test("bending"))
    cases.append(lambda: thermal_strip(10))
    cases.append(lambda: list(two_span_cases(n_beam=10, n_shell=15 if quick else 30)))
    return cases


def run_cases(quick: bool = False, progress: Callable[[float, str], None] | None = None) -> list[Case]:
    """Run the whole suite and return every case, in order."""
    out: list[Case] = []
    thunks = suite(quick)
    for k, thunk in enumerate(thunks):
        got = thunk()
        out.extend(got if isinstance(got, list) else [got])
        if progress is not None:
            progress((k + 1) / len(thunks), "verify")
    return out
