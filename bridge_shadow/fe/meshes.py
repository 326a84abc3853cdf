"""Structured meshes for benchmarks and simple members: grids, cylinders, straight beams, I-girders."""

from __future__ import annotations

import numpy as np

__all__ = ["fixities", "grid", "line", "node_at"]


def grid(nx: int, ny: int) -> tuple[np.ndarray, np.ndarray]:
    """Return a unit-square grid: parameters ``st (n, 2)`` in [0, 1]^2, quads ``conn (nx*ny, 4)`` CCW.

    Node ``i + (nx + 1) j`` sits at ``(i / nx, j / ny)``.
    """
    s, t = np.meshgrid(np.linspace(0, 1, nx + 1), np.linspace(0, 1, ny + 1))
    st = np.column_stack([s.ravel(), t.ravel()])
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    n0 = (i + (nx + 1) * j).ravel()
    conn = np.column_stack([n0, n0 + 1, n0 + nx + 2, n0 + nx + 1])
    return st, conn


def line(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Return unit-line parameters ``s (n + 1,)`` and 2-node connectivity ``(n, 2)``."""
    return np.linspace(0.0, 1.0, n + 1), np.column_stack([np.arange(n), np.arange(1, n + 1)])


def node_at(nodes: np.ndarray, point: np.ndarray, tol: float = 1e-9) -> int:
    """Return the index of the node at ``point`` (3,), within ``tol`` times the model size."""
    d = np.linalg.norm(nodes - np.asarray(point, float), axis=1)
    i = int(np.argmin(d))
    scale = max(float(np.ptp(nodes, axis=0).max()), 1.0)
    if d[i] > tol * scale:
        raise ValueError(f"no node at {point}")
    return i


def fixities(conditions: list[tuple[np.ndarray, tuple[int, ...]]], prefix: str = "fix") -> list:
    """Merge overlapping zero-displacement conditions ``[(nodes, dofs), ...]`` into disjoint supports.

    Nodes with the same union of fixed DOFs share one rigid :class:`~bridge_shadow.fe.model.Support`
    named ``f"{prefix}_{dofs}"``, e.g. ``fix_012``.
    """
    from bridge_shadow.fe.model import Support

    fixed: dict[int, set[int]] = {}
    for nodes, dofs in conditions:
        for node in np.atleast_1d(np.asarray(nodes, np.int64)).tolist():
            fixed.setdefault(node, set()).update(int(d) for d in dofs)
    groups: dict[tuple[int, ...], list[int]] = {}
    for node, dofs in fixed.items():
        groups.setdefault(tuple(sorted(dofs)), []).append(node)
    return [
        Support(f"{prefix}_{''.join(map(str, d))}", np.array(sorted(n)), d) for d, n in sorted(groups.items())
    ]
