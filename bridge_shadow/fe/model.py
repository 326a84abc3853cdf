"""Plain-array description of a linear static FE model: nodes, element sets, supports, load cases.

Everything is SI (N, m, Pa, kg/m^3, 1/K, K). Each node has 6 DOFs in global axes, in the order
``(ux, uy, uz, rx, ry, rz)``; global DOF index ``6 * node + dof``. Per-element properties accept a
scalar (same for the whole set) or an array of shape ``(n_el,)`` (or ``(n_el, 3)`` for vectors).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.fe.elements.shell import DRILL_FACTOR
from bridge_shadow.fe.errors import ModelError

__all__ = [
    "DOF_NAMES",
    "BeamLoad",
    "BeamSet",
    "LoadCase",
    "Model",
    "RigidLinks",
    "ShellSet",
    "SpringSet",
    "Support",
    "Thermal",
]

#: DOF order at every node (global axes).
DOF_NAMES: tuple[str, ...] = ("ux", "uy", "uz", "rx", "ry", "rz")


def per_element(value: Any, n_el: int, name: str, width: int | None = None) -> np.ndarray:
    """Broadcast a scalar (or one vector) property to ``(n_el,)`` (or ``(n_el, width)``) floats."""
    arr = np.asarray(value, dtype=float)
    shape = (n_el,) if width is None else (n_el, width)
    try:
        return np.broadcast_to(arr, shape).astype(float, copy=True)
    except ValueError as err:
        raise ModelError(f"{name}: cannot broadcast shape {arr.shape} to {shape}") from err


def _conn(conn: Any, nodes_per_el: int, name: str) -> np.ndarray:
    c = np.asarray(conn, dtype=np.int64)
    if c.ndim != 2 or c.shape[1] != nodes_per_el:
        raise ModelError(f"{name}: connectivity must have shape (n_el, {nodes_per_el}), got {c.shape}")
    return c


@dataclass
class ShellSet:
    """Flat 4-node shells (MITC4 bending + GCMQ drilling membrane), 6 DOF per node.

    Attributes:
        conn: (n_el, 4) int node indices, counter-clockwise about the element normal
            ``n = (x3 - x1) x (x4 - x2)`` (normalized); warped quads are projected to the mean plane.
        thickness: m, scalar or (n_el,).
        E: Pa; nu: Poisson's ratio; rho: kg/m^3; alpha: 1/K (scalars or (n_el,)).
        tag: name used by load cases to address the set.
        drill_factor: drilling penalty over the shear modulus (default
            :data:`~bridge_shadow.fe.elements.shell.DRILL_FACTOR`; ``verify`` sweeps it).

    """

    conn: np.ndarray
    thickness: Any
    E: Any
    nu: Any = 0.3
    rho: Any = 0.0
    alpha: Any = 1.2e-5
    tag: str = "shell"
    drill_factor: Any = None

    def __post_init__(self) -> None:
        self.conn = _conn(self.conn, 4, f"shell set {self.tag!r}")
        n = len(self.conn)
        if self.drill_factor is None:
            self.drill_factor = DRILL_FACTOR
        for name in ("thickness", "E", "nu", "rho", "alpha", "drill_factor"):
            setattr(self, name, per_element(getattr(self, name), n, f"{self.tag}.{name}"))

    @property
    def n_el(self) -> int:
        """Number of elements."""
        return len(self.conn)


@dataclass
class BeamSet:
    """Straight 2-node 3D beams, 12 DOF (Timoshenko when shear areas are given, else Euler-Bernoulli).

    Local axes: x from end i to end j (after offsets); z is ``orientation`` made orthogonal to x;
    y = z x x. ``Iz`` resists bending in the local x-y plane (deflection along y), ``Iy`` bending in
    the local x-z plane (deflection along z).

    Attributes:
        conn: (n_el, 2) int node indices.
        A: m^2; Iy, Iz: m^4; J: m^4 (torsion constant); E, G: Pa; rho: kg/m^3; alpha: 1/K.
        Asy, Asz: shear areas m^2 for shear along local y / z, or None for Euler-Bernoulli.
        depth_y, depth_z: m, section extent along local y / z (lever arm of thermal gradients).
        orientation: (3,) or (n_el, 3), a vector in the local x-z plane (not parallel to the axis).
        offset_i, offset_j: (3,) or (n_el, 3) m, rigid end offsets in global axes from the node to
            the beam end (the beam runs between ``x_i + offset_i`` and ``x_j + offset_j``).
        tag: name used by load cases.

    """

    conn: np.ndarray
    A: Any
    Iy: Any
    Iz: Any
    J: Any
    E: Any
    G: Any
    rho: Any = 0.0
    alpha: Any = 1.2e-5
    Asy: Any = None
    Asz: Any = None
    depth_y: Any = 1.0
    depth_z: Any = 1.0
    orientation: Any = (0.0, 0.0, 1.0)
    offset_i: Any = (0.0, 0.0, 0.0)
    offset_j: Any = (0.0, 0.0, 0.0)
    tag: str = "beam"

    def __post_init__(self) -> None:
        self.conn = _conn(self.conn, 2, f"beam set {self.tag!r}")
        n = len(self.conn)
        for name in ("A", "Iy", "Iz", "J", "E", "G", "rho", "alpha", "depth_y", "depth_z"):
            setattr(self, name, per_element(getattr(self, name), n, f"{self.tag}.{name}"))
        for name in ("Asy", "Asz"):
            value = getattr(self, name)
            setattr(self, name, None if value is None else per_element(value, n, f"{self.tag}.{name}"))
        for name in ("orientation", "offset_i", "offset_j"):
            setattr(self, name, per_element(getattr(self, name), n, f"{self.tag}.{name}", 3))

    @property
    def n_el(self) -> int:
        """Number of elements."""
        return len(self.conn)


@dataclass
class SpringSet:
    """Linear springs in global axes between two nodes, or from a node to the ground.

    Attributes:
        node_i: (n,) int; node_j: (n,) int, ``-1`` for ground.
        k: (6,) or (n, 6) stiffness per DOF ``(ux, uy, uz, rx, ry, rz)``: N/m and N m/rad.
        tag: name.

    """

    node_i: Any
    node_j: Any
    k: Any
    tag: str = "spring"

    def __post_init__(self) -> None:
        self.node_i = np.atleast_1d(np.asarray(self.node_i, dtype=np.int64))
        self.node_j = np.broadcast_to(np.asarray(self.node_j, dtype=np.int64), self.node_i.shape).copy()
        self.k = per_element(self.k, len(self.node_i), f"{self.tag}.k", 6)


@dataclass
class RigidLinks:
    """Rigid links: each slave node follows its master as a rigid body (all 6 DOFs eliminated).

    Attributes:
        master: (n,) int; slave: (n,) int. A slave cannot be a master, a support node or appear twice.

    """

    master: Any
    slave: Any
    tag: str = "links"

    def __post_init__(self) -> None:
        self.master = np.atleast_1d(np.asarray(self.master, dtype=np.int64))
        self.slave = np.broadcast_to(np.asarray(self.slave, dtype=np.int64), self.master.shape).copy()


@dataclass
class Support:
    """A named support (bearing): the same displacement imposed on ``dofs`` of every node in ``nodes``.

    With ``stiffness=None`` the DOFs are rigidly prescribed (0 unless a load case says otherwise);
    otherwise each node is tied to a ground point by springs ``stiffness`` (N/m or N m/rad, scalar or
    one per DOF), and a prescribed displacement moves that ground point.

    The reaction reported for a support is the force (moment) the support exerts on the structure,
    summed over its nodes, in global axes, one value per DOF in ``dofs``: a vertical bearing under
    compression reports a positive ``uz`` reaction (z up).

    Attributes:
        name: unique name. nodes: (n,) int. dofs: indices into ``DOF_NAMES``.

    """

    name: str
    nodes: Any
    dofs: tuple[int, ...] = (0, 1, 2)
    stiffness: Any = None

    def __post_init__(self) -> None:
        self.nodes = np.atleast_1d(np.asarray(self.nodes, dtype=np.int64))
        self.dofs = tuple(int(d) for d in self.dofs)
        if not self.dofs or min(self.dofs) < 0 or max(self.dofs) > 5 or len(set(self.dofs)) != len(self.dofs):
            raise ModelError(f"support {self.name!r}: dofs must be distinct indices 0..5, got {self.dofs}")
        if self.stiffness is not None:
            self.stiffness = per_element(self.stiffness, len(self.dofs), f"{self.name}.stiffness")

    @property
    def rigid(self) -> bool:
        """True when the DOFs are prescribed exactly (no support stiffness)."""
        return self.stiffness is None


@dataclass
class Thermal:
    """A temperature change on one element set (by tag), optionally restricted by a mask.

    Attributes:
        tag: element set tag (shell or beam).
        uniform: K, temperature change: a scalar, one value per element ``(n_el,)``, or for shells
            nodal values per element ``(n_el, 4)`` (interpolated bilinearly in the element).
        gradient: K, shells: temperature at the +normal face minus the -normal face (linear through
            the thickness); beams: difference across ``depth_z`` (the +z face minus the -z face).
        gradient_y: K, beams only: difference across ``depth_y`` (+y face minus -y face).
        mask: optional (n_el,) bool, elements of the set that get the load (default all).

    """

    tag: str
    uniform: Any = 0.0
    gradient: Any = 0.0
    gradient_y: float = 0.0
    mask: Any = None


@dataclass
class BeamLoad:
    """Uniformly distributed force per length on a beam set, global axes, N/m; consistent nodal loads."""

    tag: str
    w: Any
    mask: Any = None


@dataclass
class LoadCase:
    """One static load case.

    Attributes:
        name: label.
        nodal: (n, 8)-like rows or a list of ``(node, dof, value)`` triples: N or N m, global axes.
        pressure: shell tag -> Pa, traction along the element normal (positive along +n).
        gravity: (3,) m/s^2 acceleration for self-weight from ``rho`` (e.g. ``(0, 0, -9.81)``), or None.
        thermal: list of :class:`Thermal`.
        beam_loads: list of :class:`BeamLoad`.
        prescribed: support name -> displacement (scalar, or one value per support DOF), m or rad.

    """

    name: str = "case"
    nodal: Any = ()
    pressure: dict[str, float] = field(default_factory=dict)
    gravity: Any = None
    thermal: list[Thermal] = field(default_factory=list)
    beam_loads: list[BeamLoad] = field(default_factory=list)
    prescribed: dict[str, Any] = field(default_factory=dict)


@dataclass
class Model:
    """A complete linear static model.

    Attributes:
        nodes: (n_nodes, 3) m, global coordinates.
        shells, beams, springs, links: element sets.
        supports: named supports (rigid or elastic, with reactions).

    """

    nodes: np.ndarray
    shells: list[ShellSet] = field(default_factory=list)
    beams: list[BeamSet] = field(default_factory=list)
    springs: list[SpringSet] = field(default_factory=list)
    links: list[RigidLinks] = field(default_factory=list)
    supports: list[Support] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.nodes = np.asarray(self.nodes, dtype=float)
        if self.nodes.ndim != 2 or self.nodes.shape[1] != 3:
            raise ModelError(f"nodes must have shape (n, 3), got {self.nodes.shape}")

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return len(self.nodes)

    @property
    def n_dofs(self) -> int:
        """Number of DOFs before constraints (6 per node)."""
        return 6 * len(self.nodes)

    def support(self, name: str) -> Support:
        """Return the support called ``name``."""
        for s in self.supports:
            if s.name == name:
                return s
        raise ModelError(f"no support named {name!r} (have {[s.name for s in self.supports]})")

    def element_set(self, tag: str) -> ShellSet | BeamSet:
        """Return the shell or beam set with ``tag``."""
        for s in (*self.shells, *self.beams):
            if s.tag == tag:
                return s
        raise ModelError(f"no element set tagged {tag!r}")

    def validate(self) -> None:
        """Check indices, names and constraint topology; raise :class:`ModelError` on the first problem."""
        n = self.n_nodes
        for s in (*self.shells, *self.beams):
            if s.conn.size and (s.conn.min() < 0 or s.conn.max() >= n):
                raise ModelError(f"element set {s.tag!r} references a node outside 0..{n - 1}")
        for sp in self.springs:
            if sp.node_i.size and (sp.node_i.min() < 0 or sp.node_i.max() >= n or sp.node_j.max() >= n):
                raise ModelError(f"spring set {sp.tag!r} references a node outside 0..{n - 1}")
        names = [s.name for s in self.supports]
        if len(set(names)) != len(names):
            raise ModelError(f"support names must be unique, got {names}")
        slaves = np.concatenate([lk.slave for lk in self.links]) if self.links else np.zeros(0, np.int64)
        masters = np.concatenate([lk.master for lk in self.links]) if self.links else np.zeros(0, np.int64)
        if len(np.unique(slaves)) != len(slaves):
            raise ModelError("a node is the slave of more than one rigid link")
        if np.intersect1d(slaves, masters).size:
            raise ModelError("a rigid-link slave is also a master (chain links to one master instead)")
        for s in self.supports:
            if s.nodes.min() < 0 or s.nodes.max() >= n:
                raise ModelError(f"support {s.name!r} references a node outside 0..{n - 1}")
            if np.intersect1d(s.nodes, slaves).size:
                raise ModelError(f"support {s.name!r} sits on a rigid-link slave node; support the master")
