"""Bridge mesh + configuration -> FE model (``bridge_shadow.fe``) and the surrogate's load cases.

Bearings: every bearing is three springs from the bottom flange (both tips and the web junction,
weights 1/6, 2/3, 1/6) to its own ground node, which is a rigid support. So a bearing is free to
rotate about y (girder bending) but restrains the girder's twist like a uniform bearing pressure
over the flange width (``k b^2 / 12``; at FRC-01/02 times ``central_bearing_twist_restraint``, the
fraction of the Simpson share the tip springs keep). Vertically the springs carry
``bearing_stiffness`` (central) or ``end_bearing_stiffness`` (ends); horizontally
``fixed_bearing_stiffness`` holds x at both central bearings and y at FRC-01 only; the end
bearings slide. So the deck expands freely from the central support. The ground point's vertical
displacement is the settlement ``x`` (positive up) and its reaction the load cell force (positive
in compression).

Support system (``support_spring_south/north``, N/m): with a finite value, a central bearing's
ground node keeps its horizontal and rotational restraints (support ``"<name> bearing"``) but rests
vertically on a spring down to the bearing's foundation node, which is the support named after the
bearing: the settlement is prescribed there, and its reaction (the force through the spring and
the bearing) is the load cell force. With ``.inf`` (as built) the ground node is the support and
the foundation node is held in all DOFs, unused. See ``settlement_node``.

Thermal load cases (1 K each):

- ``uniform``: every element +1 K;
- ``vertical_gradient``: the linear field ``T = (z - h/2) / h`` (1 K over the girder depth h, top
  warmer), applied to every element (elements get the field's value at their centroid, shells also
  its difference through their thickness);
- ``transverse_gradient``: the south girder's steel (web, flanges, stiffeners) +0.5 K, the north
  girder's -0.5 K; slab, connectors (embedded in concrete) and braces unchanged: the sun-lit south
  girder warms relative to the deck and the shaded north girder.
"""

from __future__ import annotations

import numpy as np

from bridge_shadow.fe import BeamSet, LoadCase, Model, RigidLinks, ShellSet, SpringSet, Support, Thermal
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.mesh import CENTRAL_BEARINGS, END_BEARINGS, BridgeMesh

__all__ = [
    "SUPPORT_SPRINGS",
    "THERMAL_CASE_NAMES",
    "build_model",
    "dead_load_case",
    "has_support_springs",
    "settlement_cases",
    "settlement_node",
    "thermal_cases",
]

THERMAL_CASE_NAMES: tuple[str, str, str] = ("uniform", "vertical_gradient", "transverse_gradient")
#: Central bearing -> the parameter naming the stiffness of its support system (N/m, .inf = rigid).
SUPPORT_SPRINGS: dict[str, str] = dict(
    zip(CENTRAL_BEARINGS, ("support_spring_south", "support_spring_north"), strict=True)
)

_GIRDER_STEEL = ("web", "flange", "stiffener")


def _material(cfg: BridgeConfig, name: str) -> dict[str, float]:
    """E, nu, rho, alpha, G of a material name (``steel``, ``concrete``, ``joint``)."""
    mats, par = cfg.data["materials"], cfg.params
    if name == "concrete":
        c = mats["concrete"]
        out = {"E": par["E_concrete"], "nu": c["nu"], "rho": c["rho"], "alpha": par["alpha_concrete"]}
    else:
        s = mats["steel"]
        out = {"E": s["E"], "nu": s["nu"], "rho": s["rho"], "alpha": s["alpha"]}
        if name == "joint":  # fictitious bolted-joint beams: no mass, no thermal strain
            out.update(rho=0.0, alpha=0.0)
    out["G"] = out["E"] / (2.0 * (1.0 + out["nu"]))
    return out


def has_support_springs(cfg: BridgeConfig) -> bool:
    """Whether any central bearing has a finite support-system spring."""
    return any(np.isfinite(cfg.params[p]) for p in SUPPORT_SPRINGS.values())


def settlement_node(cfg: BridgeConfig, mesh: BridgeMesh, name: str) -> int:
    """Node whose vertical displacement is the settlement of central bearing ``name``.

    The foundation node when the bearing has a finite support spring, else its ground node.
    """
    bearing = mesh.bearings[name]
    return bearing.foundation if np.isfinite(cfg.params[SUPPORT_SPRINGS[name]]) else bearing.ground


def build_model(cfg: BridgeConfig, mesh: BridgeMesh, *, free_central_uz: bool = False) -> Model:
    """Return the FE model of ``mesh``; ``free_central_uz`` leaves the ground nodes' uz unsupported.

    With ``free_central_uz`` the model is only stable together with a condensation on those two DOFs
    (the Schur complement route to ``A``).
    """
    par = cfg.params
    shells = []
    for tag, part in mesh.shells.items():
        mat = _material(cfg, part.material)
        shells.append(
            ShellSet(part.conn, part.thickness, mat["E"], mat["nu"], mat["rho"], mat["alpha"], tag=tag)
        )
    beams = []
    for tag, part in mesh.beams.items():
        mat = _material(cfg, part.material)
        p = part.props
        beams.append(
            BeamSet(
                part.conn,
                p["A"],
                p["Iy"],
                p["Iz"],
                p["J"],
                mat["E"],
                mat["G"],
                rho=mat["rho"],
                alpha=mat["alpha"],
                Asy=p.get("Asy"),
                Asz=p.get("Asz"),
                depth_y=p["depth_y"],
                depth_z=p["depth_z"],
                orientation=part.orientation,
                tag=tag,
            )
        )
    springs = [SpringSet(s.node_i, s.node_j, s.k, tag=t) for t, s in mesh.springs.items()]
    supports = []
    kf, kb, ke = par["fixed_bearing_stiffness"], par["bearing_stiffness"], par["end_bearing_stiffness"]
    per_bearing = {
        CENTRAL_BEARINGS[0]: (kf, kf, kb),  # fixed point: x and y held
        CENTRAL_BEARINGS[1]: (kf, 0.0, kb),  # x held, slides transversely
        **dict.fromkeys(END_BEARINGS, (0.0, 0.0, ke)),  # slide in x and y
    }
    twist = par["central_bearing_twist_restraint"]
    for name, bearing in mesh.bearings.items():
        k = np.array([*per_bearing[name], 0.0, 0.0, 0.0])
        w = bearing.weights.copy()
        if name in CENTRAL_BEARINGS:  # scale the tip share: twist stiffness twist * k b^2 / 12
            w[[0, 2]] *= twist
            w[1] = 1.0 - w[0] - w[2]
        springs.append(
            SpringSet(
                bearing.nodes,
                np.full(len(bearing.nodes), bearing.ground),
                w[:, None] * k[None, :],
                tag=f"bearing_{name}",
            )
        )
        free = free_central_uz and name in CENTRAL_BEARINGS
        settle_dofs = (0, 1, 3, 4, 5) if free else tuple(range(6))
        k_support = par[SUPPORT_SPRINGS[name]] if name in CENTRAL_BEARINGS else np.inf
        if np.isfinite(k_support):  # ground node on a vertical spring to the foundation node
            supports.append(Support(f"{name} bearing", [bearing.ground], dofs=(0, 1, 3, 4, 5)))
            springs.append(
                SpringSet(
                    bearing.ground,
                    bearing.foundation,
                    [0.0, 0.0, k_support, 0.0, 0.0, 0.0],
                    tag=f"support_{name}",
                )
            )
            supports.append(Support(name, [bearing.foundation], dofs=settle_dofs))
            continue
        supports.append(Support(name, [bearing.ground], dofs=settle_dofs))
        if bearing.foundation >= 0:  # unused foundation node of a rigid support
            supports.append(Support(f"{name} foundation", [bearing.foundation], dofs=tuple(range(6))))
    links = [RigidLinks(mesh.links[0], mesh.links[1], tag="brace_ends")] if len(mesh.links[0]) else []
    return Model(mesh.nodes, shells=shells, beams=beams, springs=springs, links=links, supports=supports)


def settlement_cases() -> list[LoadCase]:
    """Return unit (1 m, upward) displacements of each central bearing's ground point, the other at rest."""
    unit = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    return [LoadCase(name=f"settle {n}", prescribed={n: unit}) for n in CENTRAL_BEARINGS]


def dead_load_case(cfg: BridgeConfig) -> LoadCase:
    """Self-weight of every part plus the superimposed load on the slab, zero settlement."""
    loads = cfg.data["loads"]
    return LoadCase(
        name="dead",
        gravity=(0.0, 0.0, -float(loads["gravity"])),
        pressure={"slab": -float(loads["superimposed_pa"])},  # slab normals point up (+z)
    )


def _shell_normals(nodes: np.ndarray, conn: np.ndarray) -> np.ndarray:
    x = nodes[conn]
    n = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    return n / np.linalg.norm(n, axis=1)[:, None]


def _beam_axes(nodes: np.ndarray, conn: np.ndarray, orientation: tuple[float, ...]) -> tuple:
    ex = nodes[conn[:, 1]] - nodes[conn[:, 0]]
    ex /= np.linalg.norm(ex, axis=1)[:, None]
    o = np.asarray(orientation, float)[None, :]
    ez = o - (ex @ o.T) * ex
    ez /= np.linalg.norm(ez, axis=1)[:, None]
    return np.cross(ez, ex), ez


def thermal_cases(mesh: BridgeMesh) -> list[LoadCase]:
    """Return the three 1 K thermal load cases (see the module docstring), in ``THERMAL_CASE_NAMES`` order."""
    nodes = mesh.nodes
    h, zc = mesh.info["girder_depth"], mesh.info["z_girder_mid"]
    uniform, vertical, transverse = [], [], []
    for tag, part in mesh.shells.items():
        n_el = len(part.conn)
        uniform.append(Thermal(tag, uniform=np.ones(n_el)))  # type: ignore[arg-type]
        zc_el = nodes[part.conn][:, :, 2].mean(axis=1)
        grad = _shell_normals(nodes, part.conn)[:, 2] / h * part.thickness
        vertical.append(Thermal(tag, uniform=(zc_el - zc) / h, gradient=grad))  # type: ignore[arg-type]
        if tag in _GIRDER_STEEL:
            t = np.where(part.girder == 0, 0.5, np.where(part.girder == 1, -0.5, 0.0))
            transverse.append(Thermal(tag, uniform=t))  # type: ignore[arg-type]
    for tag, part in mesh.beams.items():
        n_el = len(part.conn)
        uniform.append(Thermal(tag, uniform=np.ones(n_el)))  # type: ignore[arg-type]
        zc_el = nodes[part.conn][:, :, 2].mean(axis=1)
        ey, ez = _beam_axes(nodes, part.conn, part.orientation)
        vertical.append(
            Thermal(
                tag,
                uniform=(zc_el - zc) / h,  # type: ignore[arg-type]
                gradient=ez[:, 2] / h * np.broadcast_to(part.props["depth_z"], (n_el,)),  # type: ignore[arg-type]
                gradient_y=ey[:, 2] / h * np.broadcast_to(part.props["depth_y"], (n_el,)),  # type: ignore[arg-type]
            )
        )
    return [
        LoadCase(name="uniform", thermal=uniform),
        LoadCase(name="vertical_gradient", thermal=vertical),
        LoadCase(name="transverse_gradient", thermal=transverse),
    ]
