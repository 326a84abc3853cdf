"""Export a model and its results to VTK unstructured grid (``.vtu``) with meshio."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bridge_shadow.fe.model import Model
from bridge_shadow.fe.solve import Result

__all__ = ["write_vtu"]


def write_vtu(path: str | Path, model: Model, results: Result | Sequence[Result] = ()) -> Path:
    """Write the mesh (shells as quads, beams as lines) and results to ``path``; return the path.

    Per result: point data ``<case>:displacement`` (m) and ``<case>:rotation`` (rad); cell data
    ``set`` is the index of each element's set (shells first, then beams).
    """
    import meshio

    res = [results] if isinstance(results, Result) else list(results)
    cells, set_ids = [], []
    for k, s in enumerate(model.shells):
        cells.append(("quad", s.conn))
        set_ids.append(np.full(s.n_el, k))
    for k, b in enumerate(model.beams):
        cells.append(("line", b.conn))
        set_ids.append(np.full(b.n_el, len(model.shells) + k))
    point_data = {}
    for r in res:
        point_data[f"{r.case}:displacement"] = r.u[:, :3]
        point_data[f"{r.case}:rotation"] = r.u[:, 3:]
    mesh = meshio.Mesh(model.nodes, cells, point_data=point_data, cell_data={"set": set_ids})
    from bridge_shadow.fileio import atomic_write

    path = Path(path)
    with atomic_write(path, "VTK file") as tmp:
        mesh.write(tmp, file_format="vtu")
    return path
