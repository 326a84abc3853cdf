"""A PNG view of the bridge model (matplotlib 3D; for the README and reports)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.model.mesh import CENTRAL_BEARINGS, END_BEARINGS, BridgeMesh

__all__ = ["plot_model"]

_COLORS = {
    "web": "#4a6fa5",
    "flange": "#2e4a7a",
    "stiffener": "#c9a227",
    "connector_web": "#b5523b",
    "slab": "#9a9a9a",
}


def plot_model(mesh: BridgeMesh, path: str | Path, solution: Any = None) -> Path:
    """Draw the mesh in 3D (slab translucent) and the mid-support cross-section; return the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    nodes = mesh.nodes
    fig = plt.figure(figsize=(13, 8))
    ax = fig.add_axes((0.0, 0.33, 1.0, 0.67), projection="3d")
    for tag, part in mesh.shells.items():
        alpha = 0.18 if tag == "slab" else 0.85
        poly = Poly3DCollection(nodes[part.conn], alpha=alpha, linewidths=0.15, edgecolors="k")
        poly.set_facecolor(_COLORS.get(tag, "#888888"))
        ax.add_collection3d(poly)
    for tag, part in mesh.beams.items():
        if tag == "joint":
            continue
        color = "#2a9d3f" if tag.startswith("brace") else "#b5523b"
        ax.add_collection3d(Line3DCollection(nodes[part.conn], colors=color, linewidths=1.5))
    for name in CENTRAL_BEARINGS:
        p = nodes[mesh.bearings[name].ground]
        ax.scatter(*p, color="red", s=40, depthshade=False)
        ax.text(p[0], p[1], p[2] - 0.45, name, color="red", fontsize=9)
    for name in END_BEARINGS:
        ax.scatter(*nodes[mesh.bearings[name].ground], color="black", marker="^", s=25, depthshade=False)
    length = mesh.info["length"]
    ax.set_xlim(0, length)
    ax.set_ylim(-1.6, 1.6)
    ax.set_zlim(-0.2, 1.3)
    ax.set_box_aspect((length, 6.4, 3.0), zoom=1.25)
    ax.set_yticks([-1.0, 0.0, 1.0])
    ax.set_zticks([0.0, 1.0])
    ax.view_init(elev=-20, azim=-58)
    ax.set_proj_type("ortho")
    for pane in (ax.xaxis.pane, ax.yaxis.pane, ax.zaxis.pane):
        pane.set_alpha(0.0)
    ax.set_xlabel("x (m, west -> east)")
    ax.set_ylabel("y (m, north +)")
    ax.set_zlabel("z (m)")
    ax.set_title(
        f"UniBw test bridge FE model: {len(nodes)} nodes, "
        f"{sum(len(p.conn) for p in mesh.shells.values())} shells, "
        f"{sum(len(p.conn) for p in mesh.beams.values())} beams"
    )

    # cross-section at the central support
    ax2 = fig.add_axes((0.3, 0.05, 0.4, 0.28))
    x_mid = nodes[mesh.bearings[CENTRAL_BEARINGS[0]].ground, 0]
    for tag, part in mesh.shells.items():
        xyz = nodes[part.conn]
        at = np.all(np.abs(xyz[:, :, 0] - x_mid) < 1e-6, axis=1) | np.any(
            np.abs(xyz[:, :, 0] - x_mid) < 1e-6, axis=1
        )
        for quad in xyz[at]:
            yz = quad[:, 1:]
            ax2.plot(yz[[0, 1, 2, 3, 0], 0], yz[[0, 1, 2, 3, 0], 1], color=_COLORS.get(tag, "k"), lw=1.2)
    for tag, part in mesh.beams.items():
        xyz = nodes[part.conn]
        at = np.all(np.abs(xyz[:, :, 0] - x_mid) < 1e-6, axis=1)
        for seg in xyz[at]:
            ax2.plot(seg[:, 1], seg[:, 2], color="#2a9d3f" if tag.startswith("brace") else "#b5523b", lw=2)
    for name in CENTRAL_BEARINGS:
        p = nodes[mesh.bearings[name].ground]
        ax2.plot(p[1], p[2] - 0.05, "r^", ms=10)
        ax2.annotate(name, (p[1], p[2] - 0.2), color="red", ha="center", fontsize=9)
    ax2.set_aspect("equal")
    ax2.set_xlabel("y (m): south <- -> north")
    ax2.set_ylabel("z (m)")
    ax2.set_title(f"section at x = {x_mid:.1f} m (central support)")
    if solution is not None:
        a = np.asarray(solution.A) / 1e6
        ax2.text(
            0.02,
            0.02,
            f"A = [[{a[0, 0]:.2f}, {a[0, 1]:.2f}], [{a[1, 0]:.2f}, {a[1, 1]:.2f}]] kN/mm\n"
            f"u0 = {solution.u0[0] / 1e3:.1f} / {solution.u0[1] / 1e3:.1f} kN",
            transform=ax2.transAxes,
            fontsize=8,
        )
    from bridge_shadow.fileio import atomic_write

    out = Path(path)
    try:
        with atomic_write(out, "model picture") as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)
    return out
