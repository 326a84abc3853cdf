"""Two equal 15 m spans, as beams and as a shell I-girder: settlement, gradient, load, uniform temperature.

References are the closed forms of DESIGN section 7 (force method) and, for the shell girder, which
deforms in shear too, Timoshenko beam theory with the web as shear area.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from bridge_shadow.fe.meshes import line, node_at
from bridge_shadow.fe.model import BeamLoad, BeamSet, LoadCase, Model, ShellSet, Support, Thermal
from bridge_shadow.fe.solve import LinearStaticSolver
from bridge_shadow.fe.verify.case import Case, Timer, make_case

__all__ = ["girder_mid_reactions", "i_girder", "two_span_cases"]

_EB = (
    "Euler-Bernoulli reference omits shear deformation, which makes this girder about 1.3 % softer; "
    "the Timoshenko case below is toleranced"
)
_FREE = "normalized: |reaction| over the force a full restraint would take"
_SETTLE, _DT, _Q = 0.01, 10.0, 25.0e3

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


def i_girder(n: int, drill: float | None = None) -> tuple[Model, float, float, dict[str, np.ndarray]]:
    """Two 15 m spans of a shell I-girder (web 1.0 m x 19 mm, flanges 0.3 m x 36 mm, mid-surfaces).

    ``n`` elements per span along x; 6 across the web height, 4 across each flange; ``drill``: the
    drilling penalty over G (None: the default). Bearings
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
        ShellSet(np.array(web), tw, _E, _NU, alpha=_ALPHA, tag="web", drill_factor=drill),
        ShellSet(np.array(top), tf, _E, _NU, alpha=_ALPHA, tag="top", drill_factor=drill),
        ShellSet(np.array(bot), tf, _E, _NU, alpha=_ALPHA, tag="bottom", drill_factor=drill),
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


def girder_mid_reactions(n: int, drill: float | None = None) -> tuple[list[float], float, float, int, float]:
    """Shell I-girder on two spans: mid-support reactions (N) under settlement, gradient, load, uniform.

    Returns the four reactions, EI, depth, DOFs and seconds per case.
    """
    settle, dT, q = _SETTLE, _DT, _Q
    with Timer() as tm:
        model, ei, h, zn = i_girder(n, drill)
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
    rm = [r.reaction("mid", "uz") for r in res]  # type: ignore[union-attr]
    return rm, ei, h, solver.n_free, tm.seconds / 4


def two_span_cases(n_beam: int, n_shell: int) -> Iterator[Case]:
    """Settlement, gradient, uniform load and uniform temperature on two equal spans, beam and shell."""
    L, settle, dT, q = _SPAN, _SETTLE, _DT, _Q  # settlement 10 mm downward: uz = -settle
    with Timer() as tm:
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
    yield make_case(
        "two_span_beam_settlement", rm[0], -6 * ei * settle / L**3, 0.005, mesh, dofs, sec, "2SPAN"
    )
    yield make_case(
        "two_span_beam_gradient", rm[1], -3 * ei * _ALPHA * dT / (h * L), 0.005, mesh, dofs, sec, "2SPAN"
    )
    yield make_case("two_span_beam_uniform_load", rm[2], 5 * q * L / 4, 0.005, mesh, dofs, sec, "2SPAN")
    yield make_case(
        "two_span_beam_uniform_temperature", abs(rm[3]) / ea, 0.0, 1e-8, mesh, dofs, sec, "2SPAN", _FREE
    )

    rm, ei, h, dofs, sec = girder_mid_reactions(n_shell)
    mesh = f"{2 * n_shell}x(6+4+4) shells"
    area = 1.0 * 0.019 + 2 * 0.3 * 0.036
    ea = _E * area * _ALPHA * dT
    yield make_case(
        "two_span_shell_settlement", rm[0], -6 * ei * settle / L**3, None, mesh, dofs, sec, "2SPAN", _EB
    )
    yield make_case(
        "two_span_shell_gradient", rm[1], -3 * ei * _ALPHA * dT / (h * L), None, mesh, dofs, sec, "2SPAN", _EB
    )
    yield make_case("two_span_shell_uniform_load", rm[2], 5 * q * L / 4, None, mesh, dofs, sec, "2SPAN", _EB)
    yield make_case(
        "two_span_shell_uniform_temperature", abs(rm[3]) / ea, 0.0, 1e-8, mesh, dofs, sec, "2SPAN", _FREE
    )
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
        yield make_case(f"two_span_shell_{kind}_timoshenko", rm[k], ref, 0.01, mesh, dofs, sec, "TIMO")
