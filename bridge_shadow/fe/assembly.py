"""COO triplets of element matrices and vectors, turned into CSR / dense vectors in one call."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["COOData", "element_dofs", "scatter_vector"]


def element_dofs(conn: np.ndarray) -> np.ndarray:
    """Global DOF indices of each element: ``conn (n_el, m)`` -> ``(n_el, 6 m)`` int."""
    conn = np.asarray(conn, dtype=np.int64)
    return (6 * conn[:, :, None] + np.arange(6)).reshape(len(conn), -1)


@dataclass
class COOData:
    """Triplets ``(rows, cols, data)`` of a sparse matrix of ``shape``; add blocks, then ``tocsr``."""

    shape: tuple[int, int]
    rows: list[np.ndarray]
    cols: list[np.ndarray]
    data: list[np.ndarray]

    @classmethod
    def empty(cls, n: int) -> COOData:
        """Return empty triplets for an ``n x n`` matrix."""
        return cls((n, n), [], [], [])

    def add_elements(self, dofs: np.ndarray, ke: np.ndarray) -> None:
        """Add element matrices ``ke (n_el, m, m)`` at global ``dofs (n_el, m)``."""
        m = dofs.shape[1]
        self.rows.append(np.repeat(dofs, m, axis=1).ravel())
        self.cols.append(np.tile(dofs, (1, m)).ravel())
        self.data.append(np.asarray(ke, dtype=float).reshape(len(dofs), m * m).ravel())

    def add_diagonal(self, dofs: np.ndarray, values: np.ndarray) -> None:
        """Add ``values`` on the diagonal at ``dofs``."""
        self.rows.append(np.asarray(dofs, np.int64).ravel())
        self.cols.append(np.asarray(dofs, np.int64).ravel())
        self.data.append(np.asarray(values, float).ravel())

    def tocsr(self) -> sp.csr_matrix:
        """Sum duplicates into one CSR matrix."""
        if not self.rows:
            return sp.csr_matrix(self.shape)
        mat = sp.coo_matrix(
            (np.concatenate(self.data), (np.concatenate(self.rows), np.concatenate(self.cols))),
            shape=self.shape,
        )
        return mat.tocsr()


def scatter_vector(n: int, dofs: np.ndarray, fe: np.ndarray) -> np.ndarray:
    """Sum element vectors ``fe (n_el, m)`` at ``dofs (n_el, m)`` into a length-``n`` vector."""
    return np.bincount(np.asarray(dofs).ravel(), weights=np.asarray(fe, float).ravel(), minlength=n)
