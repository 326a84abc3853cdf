"""Rigid links and prescribed DOFs by elimination: ``u = C_f q + C_p u_p``.

``q`` are the independent free DOFs, ``u_p`` the rigidly prescribed support DOFs. A slave node of a
rigid link follows its master: ``u_s = u_m + r_m x (x_s - x_m)`` and ``r_s = r_m``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from bridge_shadow.fe.errors import ModelError
from bridge_shadow.fe.model import Model

__all__ = ["Constraints", "build_constraints"]


@dataclass
class Constraints:
    """Elimination of slave and prescribed DOFs.

    Attributes:
        cf: (n_dofs, n_free) sparse, free columns. cp: (n_dofs, n_presc) sparse, prescribed columns.
        free: (n_free,) global DOF of each free column. presc: (n_presc,) global DOF of each
            prescribed column.
        presc_index: support name -> (n_nodes_of_support, n_support_dofs) column indices into ``presc``.

    """

    cf: sp.csr_matrix
    cp: sp.csr_matrix
    free: np.ndarray
    presc: np.ndarray
    presc_index: dict[str, np.ndarray]


def build_constraints(model: Model) -> Constraints:
    """Build the elimination matrices of a validated model."""
    n = model.n_dofs
    presc_index: dict[str, np.ndarray] = {}
    presc_list: list[np.ndarray] = []
    count = 0
    for s in model.supports:
        if not s.rigid:
            continue
        dofs = 6 * s.nodes[:, None] + np.array(s.dofs)[None, :]
        presc_list.append(dofs.ravel())
        presc_index[s.name] = count + np.arange(dofs.size).reshape(dofs.shape)
        count += dofs.size
    presc = np.concatenate(presc_list) if presc_list else np.zeros(0, np.int64)
    if len(np.unique(presc)) != len(presc):
        raise ModelError("a DOF is prescribed by more than one rigid support")
    slave_nodes = np.concatenate([lk.slave for lk in model.links]) if model.links else np.zeros(0, np.int64)
    master_nodes = np.concatenate([lk.master for lk in model.links]) if model.links else np.zeros(0, np.int64)
    slave_dofs = (6 * slave_nodes[:, None] + np.arange(6)).ravel()
    is_dep = np.zeros(n, bool)
    is_dep[presc] = True
    is_dep[slave_dofs] = True
    free = np.flatnonzero(~is_dep)

    # column of each independent DOF: free -> [0, n_free), prescribed -> n_free + index
    col = np.full(n, -1, np.int64)
    col[free] = np.arange(len(free))
    col[presc] = len(free) + np.arange(len(presc))
    rows = [free, presc]
    cols = [col[free], col[presc]]
    vals = [np.ones(len(free)), np.ones(len(presc))]
    if len(slave_nodes):
        r = model.nodes[slave_nodes] - model.nodes[master_nodes]  # (m, 3)
        # u_s = u_m - skew(r) r_m ; r_s = r_m
        ms = 6 * master_nodes
        ss = 6 * slave_nodes
        link_rows, link_cols, link_vals = [], [], []
        for d in range(6):
            link_rows.append(ss + d)
            link_cols.append(ms + d)
            link_vals.append(np.ones(len(ss)))
        skew = {
            (0, 1): -r[:, 2],
            (0, 2): r[:, 1],
            (1, 0): r[:, 2],
            (1, 2): -r[:, 0],
            (2, 0): -r[:, 1],
            (2, 1): r[:, 0],
        }
        for (i, j), v in skew.items():
            link_rows.append(ss + i)
            link_cols.append(ms + 3 + j)
            link_vals.append(-v)
        lr, lc, lv = (np.concatenate(x) for x in (link_rows, link_cols, link_vals))
        if np.any(col[lc] < 0):
            raise ModelError("rigid-link master DOF is itself dependent")
        rows.append(lr)
        cols.append(col[lc])
        vals.append(lv)
    c = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n, len(free) + len(presc)),
    )
    c.eliminate_zeros()
    c = c.tocsc()
    cf = c[:, : len(free)].tocsr()
    cp = c[:, len(free) :].tocsr()
    return Constraints(cf=cf, cp=cp, free=free, presc=presc, presc_index=presc_index)
