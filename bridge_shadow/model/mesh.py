"""Geometry and mesh of the test bridge as plain numpy arrays (no solver objects).

Axes: x along the bridge (0 at the west abutment), y towards north, z up; the south girder lies at
``y = -spacing / 2``. Parts (each a structured grid, merged by coordinates within a *family* so that
slab segments and connectors stay separate where springs join them):

- two HEB1000 girders: web and both flanges as shells at their mid-planes, vertical web stiffeners
  (both sides) at every bearing and brace;
- the segmented slab: one shell grid per segment at the slab mid-plane, springs across the joints;
- halved HEA340 connectors per segment and girder: a web shell strip from the connector flange up
  to the slab mid-plane (tied to the slab by "dowel" springs) and a beam for its flange, bolted to
  the girder's top flange by short vertical beams ("joints");
- HEB280 / HEB120 cross braces as beams between the webs at mid-height;
- bearings: springs from the flange nodes over each bearing to a ground node (the support that
  carries the reaction; for FRC-01/02 the load cell force). Each central bearing also has a
  foundation node (drawn ``FOUNDATION_DEPTH`` below it) for the support-system spring in series
  (``support_spring_south/north``; with ``.inf`` the ground node is the support and the foundation
  node is unused).

Slab joints over the hogging zone (``hogging_zone``) form their own spring part
(``slab_joint_hogging``) so that ``slab_joint_opening`` can soften them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.errors import ConfigError
from bridge_shadow.model.config import BridgeConfig

__all__ = [
    "CENTRAL_BEARINGS",
    "END_BEARINGS",
    "FOUNDATION_DEPTH",
    "BeamPart",
    "Bearing",
    "BridgeMesh",
    "ShellPart",
    "SpringPart",
    "build_mesh",
    "hogging_zone",
]

#: Central bearing names [south, north] (load cells FRC-01 and FRC-02).
CENTRAL_BEARINGS: tuple[str, str] = ("FRC-01", "FRC-02")
#: End bearing names: west south, west north, east south, east north.
END_BEARINGS: tuple[str, str, str, str] = ("end_W_S", "end_W_N", "end_E_S", "end_E_N")

#: Distance (m) below a central bearing's ground node at which its foundation node is drawn (the
#: support spring's stiffness does not depend on it).
FOUNDATION_DEPTH = 0.5

_STEEL_KEY, _SLAB_KEY, _CONN_KEY, _BRACE_KEY, _GROUND_KEY = 0, 1_000, 2_000, 5_000, 9_000
_FOUNDATION_KEY = 9_500


@dataclass
class ShellPart:
    """A set of 4-node shells: ``conn (n_el, 4)``, ``thickness (n_el,)`` m, ``girder (n_el,)``.

    ``girder`` is 0 (south), 1 (north) or -1 (deck, not part of a girder); ``material`` names an
    entry of the configuration's materials.
    """

    conn: np.ndarray
    thickness: np.ndarray
    girder: np.ndarray
    material: str


@dataclass
class BeamPart:
    """A set of 2-node beams with per-element section properties (SI) and ``girder (n_el,)``."""

    conn: np.ndarray
    props: dict[str, np.ndarray | float]
    orientation: tuple[float, float, float]
    girder: np.ndarray
    material: str


@dataclass
class SpringPart:
    """Springs ``node_i (n,)`` - ``node_j (n,)`` with stiffness ``k (n, 6)`` (N/m, N m/rad)."""

    node_i: np.ndarray
    node_j: np.ndarray
    k: np.ndarray


@dataclass
class Bearing:
    """A bearing: springs from bottom-flange nodes over it to its own ground node.

    Attributes:
        nodes: (3,) flange nodes: south tip, web junction, north tip.
        weights: (3,) fractions of the bearing stiffness carried by each spring (sum 1).
        ground: the ground node, at the web junction (a rigid support in the FE model, or the top
            of the support-system spring).
        foundation: the foundation node below a central bearing (bottom of the support-system
            spring), -1 for the end bearings.

    """

    nodes: np.ndarray
    weights: np.ndarray
    ground: int
    foundation: int = -1


@dataclass
class BridgeMesh:
    """Nodes, element parts and bearings of the bridge.

    Attributes:
        nodes: (n_nodes, 3) m.
        shells / beams / springs: tag -> part.
        bearings: name -> :class:`Bearing`, the two central ones (``CENTRAL_BEARINGS``) and the four
            end bearings (``END_BEARINGS``).
        links: (masters, slaves) rigid links of the brace ends to their end-plate patches.
        info: geometry summary (spans, z levels, ...), SI.

    """

    nodes: np.ndarray
    shells: dict[str, ShellPart] = field(default_factory=dict)
    beams: dict[str, BeamPart] = field(default_factory=dict)
    springs: dict[str, SpringPart] = field(default_factory=dict)
    bearings: dict[str, Bearing] = field(default_factory=dict)
    links: tuple[np.ndarray, np.ndarray] = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    info: dict[str, float] = field(default_factory=dict)

    def element_counts(self) -> dict[str, int]:
        """Return the number of elements per tag (shells, beams, springs)."""
        out = {t: len(p.conn) for t, p in self.shells.items()}
        out.update({t: len(p.conn) for t, p in self.beams.items()})
        out.update({t: len(p.node_i) for t, p in self.springs.items()})
        return out


class _Points:
    """Collects points with a family key; coincident points of one family merge at the end."""

    def __init__(self) -> None:
        self._pts: list[np.ndarray] = []
        self._keys: list[np.ndarray] = []
        self._n = 0

    def add(self, pts: np.ndarray, key: int) -> np.ndarray:
        """Add points ``(..., 3)``; return their provisional indices with shape ``(...)``."""
        pts = np.asarray(pts, float)
        flat = pts.reshape(-1, 3)
        idx = self._n + np.arange(len(flat))
        self._pts.append(flat)
        self._keys.append(np.full(len(flat), key, np.int64))
        self._n += len(flat)
        return idx.reshape(pts.shape[:-1])

    def merge(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the merged nodes ``(n, 3)``, their family keys and the map provisional -> node."""
        pts = np.concatenate(self._pts)
        keys = np.concatenate(self._keys)
        grid = np.round(pts / 1e-7).astype(np.int64)
        rows = np.column_stack([keys, grid])
        _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
        return pts[first], keys[first], inverse.ravel()


def _quads(idx: np.ndarray) -> np.ndarray:
    """Quads of a structured ``(n1, n2)`` index grid: ``((n1-1)(n2-1), 4)``."""
    a, b = idx[:-1, :-1], idx[1:, :-1]
    c, d = idx[1:, 1:], idx[:-1, 1:]
    return np.stack([a, b, c, d], axis=-1).reshape(-1, 4)


def _tributary(coord: np.ndarray) -> np.ndarray:
    """Tributary length of each point of a sorted 1-D grid (half cells at the ends)."""
    d = np.diff(coord)
    w = np.zeros(len(coord))
    w[:-1] += d / 2
    w[1:] += d / 2
    return w


def hogging_zone(spans: np.ndarray | list[float]) -> tuple[float, float]:
    """Where a two-span continuous beam under a uniform load ``w`` hogs: ``(x_low, x_high)`` in m.

    The central moment is ``M_c = -w (L1^3 + L2^3) / (8 (L1 + L2))`` and the moment in span 1 is
    ``M(x) = R1 x - w x^2 / 2`` with ``R1 = w L1 / 2 + M_c / L1``, zero at ``x = 2 R1 / w``; the
    same from the other end. For two equal spans ``L`` the zone is ``L +- L / 4``.
    """
    l1, l2 = (float(v) for v in spans)
    m_c = -(l1**3 + l2**3) / (8.0 * (l1 + l2))  # per unit w
    x_low = 2.0 * (l1 / 2.0 + m_c / l1)
    x_high = l1 + l2 - 2.0 * (l2 / 2.0 + m_c / l2)
    return x_low, x_high


def _on_grid(values: list[float], grid: np.ndarray, what: str) -> np.ndarray:
    idx = np.searchsorted(grid, np.asarray(values) - 1e-9)
    idx = np.clip(idx, 0, len(grid) - 1)
    if not np.allclose(grid[idx], values, atol=1e-9):
        raise ConfigError(f"{what} {values} do not fall on the mesh grid (check mesh dx)")
    return idx


def build_mesh(cfg: BridgeConfig, level: str = "default") -> BridgeMesh:
    """Generate the bridge mesh for ``level`` (coarse, default, fine) from ``cfg``."""
    geo, sec, par, m = cfg.data["geometry"], cfg.data["sections"], cfg.params, cfg.mesh(level)
    spans = np.asarray(geo["spans"], float)
    length = float(spans.sum())
    support_x = np.concatenate([[0.0], np.cumsum(spans)])
    if len(spans) != 2:
        raise ConfigError("the model supports exactly two spans")
    nx = round(length / m["dx"])
    xs = np.linspace(0.0, length, nx + 1)
    if not np.isclose(nx * m["dx"], length):
        raise ConfigError(f"mesh dx {m['dx']} does not divide the length {length}")
    n_web, n_hf = int(m["web"]), int(m["half_flange"])

    g, c = sec["heb1000"], sec["hea340_half"]
    h, b, tw, tf = g["h"], g["b"], g["tw"], g["tf"]
    spacing, width, t_slab = geo["girder_spacing"], geo["deck_width"], geo["slab_thickness"]
    y_g = np.array([-spacing / 2, spacing / 2])  # south, north
    z_bot, z_top = tf / 2, h - tf / 2
    z_slab = h + t_slab / 2
    z_cb = h + c["tf"] / 2
    # web levels: uniform-ish cells, with the brace connection plate edges on the grid
    d_conn = geo["brace_connection_depth"]
    z_mid = h / 2
    size = (z_top - z_bot) / n_web
    n_out = max(1, int(np.ceil((z_mid - d_conn / 2 - z_bot) / size - 1e-9)))
    n_in = max(1, int(np.ceil(d_conn / 2 / size - 1e-9)))
    lower = np.concatenate(
        [
            np.linspace(z_bot, z_mid - d_conn / 2, n_out + 1),
            np.linspace(z_mid - d_conn / 2, z_mid, n_in + 1)[1:],
        ]
    )
    z_web = np.concatenate([lower, (2 * z_mid - lower[::-1])[1:]])
    s_fl = np.linspace(-b / 2, b / 2, 2 * n_hf + 1)

    seg = geo["segment_length"]
    n_seg = round(length / seg)
    seg_x = np.linspace(0.0, length, n_seg + 1)
    if not np.isclose(n_seg * seg, length):
        raise ConfigError(f"segment_length {seg} does not divide the length {length}")
    seg_i = _on_grid(list(seg_x), xs, "segment joints")
    sup_i = _on_grid(list(support_x), xs, "supports")
    br280 = [float(v) for v in geo["braces_heb280_x"]]
    br120 = [float(v) for v in geo["braces_heb120_x"]]
    stiff_i = np.unique(np.concatenate([sup_i, _on_grid(br280 + br120, xs, "braces")]))

    pts = _Points()
    shells: dict[str, list[tuple[np.ndarray, float, int]]] = {
        k: [] for k in ("web", "flange", "stiffener", "slab", "connector_web")
    }

    # girders: web, flanges, stiffeners
    web_idx, bot_idx = [], []
    for gi, yg in enumerate(y_g):
        xx, zz = np.meshgrid(xs, z_web, indexing="ij")
        w = pts.add(np.stack([xx, np.full_like(xx, yg), zz], -1), _STEEL_KEY)
        web_idx.append(w)
        shells["web"].append((_quads(w), tw, gi))
        for zf in (z_bot, z_top):
            xx, ss = np.meshgrid(xs, s_fl, indexing="ij")
            f = pts.add(np.stack([xx, yg + ss, np.full_like(xx, zf)], -1), _STEEL_KEY)
            shells["flange"].append((_quads(f), tf, gi))
            if zf == z_bot:
                bot_idx.append(f)
        for i in stiff_i:
            for side in (-1.0, 1.0):
                ss, zz = np.meshgrid(side * s_fl[n_hf:], z_web, indexing="ij")
                st = pts.add(np.stack([np.full_like(ss, xs[i]), yg + ss, zz], -1), _STEEL_KEY)
                shells["stiffener"].append((_quads(st), geo["stiffener_thickness"], gi))

    # slab segments, connectors, joints, dowels
    n_c, n_b = int(m["cantilever"]), int(m["between"])
    y_slab = np.concatenate(
        [
            np.linspace(-width / 2, y_g[0], n_c + 1),
            np.linspace(y_g[0], y_g[1], n_b + 1)[1:],
            np.linspace(y_g[1], width / 2, n_c + 1)[1:],
        ]
    )
    yg_col = _on_grid(list(y_g), y_slab, "girder lines")
    z_conn = np.linspace(z_cb, z_slab, int(m["connector"]) + 1)
    slab_rows: list[np.ndarray] = []
    conn_web, conn_fl, joint_i, joint_j, joint_len, joint_g = [], [], [], [], [], []
    dowel_i, dowel_j, dowel_len = [], [], []
    for j in range(n_seg):
        xseg = xs[seg_i[j] : seg_i[j + 1] + 1]
        trib = _tributary(xseg)
        xx, yy = np.meshgrid(xseg, y_slab, indexing="ij")
        s = pts.add(np.stack([xx, yy, np.full_like(xx, z_slab)], -1), _SLAB_KEY + j)
        slab_rows.append(s)
        shells["slab"].append((_quads(s), t_slab, -1))
        for gi, yg in enumerate(y_g):
            xx, zz = np.meshgrid(xseg, z_conn, indexing="ij")
            cw = pts.add(np.stack([xx, np.full_like(xx, yg), zz], -1), _CONN_KEY + 2 * j + gi)
            conn_web.append((_quads(cw), gi))
            bottom = cw[:, 0]
            conn_fl.append((np.column_stack([bottom[:-1], bottom[1:]]), gi))
            girder_top = web_idx[gi][seg_i[j] : seg_i[j + 1] + 1, -1]
            joint_i.append(girder_top)
            joint_j.append(bottom)
            joint_len.append(trib)
            joint_g.append(np.full(len(trib), gi))
            dowel_i.append(cw[:, -1])
            dowel_j.append(s[:, yg_col[gi]])
            dowel_len.append(trib)
    for cw, gi in conn_web:
        shells["connector_web"].append((cw, c["tw"] * sec["connector_web_solid_fraction"], gi))

    # braces between the webs at mid-height; each end is a node of its own, rigidly linked to the
    # web and stiffener nodes of its end-plate patch (a point connection would be mesh-dependent)
    y_br = np.linspace(y_g[0], y_g[1], int(m["brace"]) + 1)
    braces: dict[str, np.ndarray] = {}
    brace_ends: list[tuple[int, float, float]] = []
    for tag, xb in (("brace_heb280", br280), ("brace_heb120", br120)):
        conns = []
        for x in xb:
            key = _BRACE_KEY + len(brace_ends)
            line = pts.add(np.column_stack([np.full_like(y_br, x), y_br, np.full_like(y_br, z_mid)]), key)
            conns.append(np.column_stack([line[:-1], line[1:]]))
            brace_ends += [(int(line[0]), x, y_g[0]), (int(line[-1]), x, y_g[1])]
        braces[tag] = np.concatenate(conns) if conns else np.zeros((0, 2), np.int64)

    # one ground node per bearing, coincident with the bottom flange centre over it
    bearing_at = {
        name: (sup_i[k], gi)
        for k, (w_e, w_n) in enumerate(
            ((END_BEARINGS[0], END_BEARINGS[1]), CENTRAL_BEARINGS, END_BEARINGS[2:])
        )
        for gi, name in enumerate((w_e, w_n))
    }
    ground = {
        name: int(pts.add(np.array([[xs[i], y_g[gi], z_bot]]), _GROUND_KEY + n)[0])
        for n, (name, (i, gi)) in enumerate(bearing_at.items())
    }
    foundation = {
        name: int(pts.add(np.array([[xs[i], y_g[gi], z_bot - FOUNDATION_DEPTH]]), _FOUNDATION_KEY + n)[0])
        for n, (name, (i, gi)) in enumerate(bearing_at.items())
        if name in CENTRAL_BEARINGS
    }

    nodes, keys, remap = pts.merge()
    masters, slaves = [], []
    for end, x, yg in brace_ends:
        patch = np.flatnonzero(
            (keys == _STEEL_KEY)
            & (np.abs(nodes[:, 0] - x) < 1e-7)
            & (np.abs(nodes[:, 1] - yg) <= b / 2 + 1e-7)
            & (np.abs(nodes[:, 2] - z_mid) <= d_conn / 2 + 1e-7)
        )
        masters.append(np.full(len(patch), remap[end]))
        slaves.append(patch)

    def shell_part(items: list[tuple[np.ndarray, float, int]], material: str) -> ShellPart:
        conn = remap[np.concatenate([q for q, _, _ in items])]
        thick = np.concatenate([np.full(len(q), t) for q, t, _ in items])
        gird = np.concatenate([np.full(len(q), gi) for q, _, gi in items])
        return ShellPart(conn, thick, gird, material)

    mesh = BridgeMesh(nodes)
    mesh.links = (np.concatenate(masters), np.concatenate(slaves))
    for tag in ("web", "flange", "stiffener", "connector_web"):
        mesh.shells[tag] = shell_part(shells[tag], "steel")
    mesh.shells["slab"] = shell_part(shells["slab"], "concrete")

    # beams
    fl_conn = remap[np.concatenate([q for q, _ in conn_fl])]
    fl_g = np.concatenate([np.full(len(q), gi) for q, gi in conn_fl])
    bc, tfc = c["b"], c["tf"]
    mesh.beams["connector_flange"] = BeamPart(
        fl_conn,
        {
            "A": bc * tfc,
            "Iy": bc * tfc**3 / 12,
            "Iz": tfc * bc**3 / 12,
            "J": bc * tfc**3 / 3,
            "depth_y": bc,
            "depth_z": tfc,
        },
        (0.0, 0.0, 1.0),
        fl_g,
        "steel",
    )
    for tag, conn in braces.items():
        p = sec[tag.split("_")[1]]
        mesh.beams[tag] = BeamPart(
            remap[conn],
            {"A": p["A"], "Iy": p["Iy"], "Iz": p["Iz"], "J": p["J"], "depth_y": p["b"], "depth_z": p["h"]},
            (0.0, 0.0, 1.0),
            np.full(len(conn), -1),
            "steel",
        )
    # bolted joints: Timoshenko beams whose shear flexibility gives connector_stiffness per metre
    steel = cfg.data["materials"]["steel"]
    e_s = steel["E"]
    g_s = e_s / (2 * (1 + steel["nu"]))
    lj = z_cb - z_top
    k_shear = par["connector_stiffness"] * np.concatenate(joint_len)
    k_axial = par["connector_axial_factor"] * k_shear
    inertia = 100.0 * k_shear * lj**3 / (12.0 * e_s)  # bending 100x stiffer than shear
    mesh.beams["joint"] = BeamPart(
        np.column_stack([remap[np.concatenate(joint_i)], remap[np.concatenate(joint_j)]]),
        {
            "A": k_axial * lj / e_s,
            "Iy": inertia,
            "Iz": inertia,
            "J": 2 * inertia * (1 + steel["nu"]),
            "Asy": k_shear * lj / g_s,
            "Asz": k_shear * lj / g_s,
            "depth_y": 1.0,
            "depth_z": 1.0,
        },
        (1.0, 0.0, 0.0),
        np.concatenate(joint_g),
        "joint",
    )

    # springs: dowels (connector web top <-> slab), slab joints
    trib = np.concatenate(dowel_len)
    kd, kr = par["dowel_stiffness"], par["dowel_rotational_stiffness"]
    per_m = np.array([par["composite_action"] * kd, kd, kd, kr, kr, kr])
    mesh.springs["dowel"] = SpringPart(
        remap[np.concatenate(dowel_i)], remap[np.concatenate(dowel_j)], trib[:, None] * per_m
    )
    ty = _tributary(y_slab)
    kn, ks = par["slab_joint_normal_stiffness"], par["slab_joint_shear_stiffness"]
    krot = par["slab_joint_rotational_stiffness"]
    per_m = np.array([kn, ks, ks, krot, krot, krot])
    # joints over the hogging zone keep the fraction slab_joint_opening of their normal and
    # rotational stiffness (an opening joint still transfers shear by interlock and friction)
    x_low, x_high = hogging_zone(spans)
    opening = par["slab_joint_opening"]
    kept = {False: np.ones(6), True: np.array([opening, 1.0, 1.0, opening, opening, opening])}
    for tag, in_zone in (("slab_joint", False), ("slab_joint_hogging", True)):
        joints = [j for j in range(n_seg - 1) if (x_low - 1e-9 <= seg_x[j + 1] <= x_high + 1e-9) == in_zone]
        if not joints:
            continue
        k = per_m * kept[in_zone]
        mesh.springs[tag] = SpringPart(
            np.concatenate([remap[slab_rows[j][-1]] for j in joints]),
            np.concatenate([remap[slab_rows[j + 1][0]] for j in joints]),
            np.tile(ty[:, None] * k, (len(joints), 1)),
        )

    # bearings: springs at the flange centre and both tips with Simpson weights (1/6, 2/3, 1/6):
    # vertical stiffness k, twist stiffness k b^2 / 12 (a uniform bearing pressure over the flange
    # width b), the same on every mesh level
    cols = [0, n_hf, 2 * n_hf]
    for name, (i, gi) in bearing_at.items():
        nodes3 = remap[bot_idx[gi][i, cols]]
        mesh.bearings[name] = Bearing(
            nodes3,
            np.array([1.0, 4.0, 1.0]) / 6.0,
            int(remap[ground[name]]),
            int(remap[foundation[name]]) if name in foundation else -1,
        )

    mesh.info = {
        "length": length,
        "span": float(spans[0]),
        "girder_depth": h,
        "z_girder_mid": h / 2,
        "z_slab": z_slab,
        "y_south": float(y_g[0]),
        "y_north": float(y_g[1]),
        "n_segments": float(n_seg),
        "hogging_zone_x_low": x_low,
        "hogging_zone_x_high": x_high,
    }
    return mesh
