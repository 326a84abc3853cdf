"""Static condensation: the Schur complement of a stiffness matrix on a set of DOFs."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from bridge_shadow.fe.solve import Factorization

__all__ = ["schur_complement"]


def schur_complement(
    k: sp.spmatrix, keep: np.ndarray, backend: str = "auto", groups: np.ndarray | None = None
) -> np.ndarray:
    """Return ``S = K_bb - K_bo K_oo^-1 K_ob`` (dense ``(m, m)``) for the DOFs ``keep`` (m,).

    ``S`` is the stiffness seen at the kept DOFs when all others are free and unloaded: imposing
    ``u_b`` gives the forces ``S u_b`` there. ``K_oo`` must be non-singular (the other DOFs supported).
    ``groups (n,)``, the node of each row of ``k``, enables the nested-dissection ordering.
    """
    k = sp.csr_matrix(k)
    n = k.shape[0]
    keep = np.asarray(keep, np.int64)
    other = np.setdiff1d(np.arange(n), keep)
    kbb = k[keep][:, keep].toarray()
    kbo = k[keep][:, other]
    koo = k[other][:, other]
    x = Factorization(koo, backend, groups=None if groups is None else np.asarray(groups)[other]).solve(
        kbo.T.toarray()
    )
    s = kbb - kbo @ x
    return 0.5 * (s + s.T)
