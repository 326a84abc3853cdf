"""Linear static solver: assemble once, factorize once, solve many load cases; reactions by support name."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from bridge_shadow.fe.assembly import COOData, element_dofs
from bridge_shadow.fe.constraints import Constraints, build_constraints
from bridge_shadow.fe.elements.beam import BeamGeometry, beam_geometry, beam_stiffness
from bridge_shadow.fe.elements.shell import ShellKinematics, shell_kinematics, shell_stiffness
from bridge_shadow.fe.elements.spring import spring_stiffness
from bridge_shadow.fe.errors import ModelError, SolverError
from bridge_shadow.fe.loads import load_vector
from bridge_shadow.fe.model import DOF_NAMES, LoadCase, Model

__all__ = ["Factorization", "LinearStaticSolver", "Result", "assemble_stiffness", "nested_dissection"]


def assemble_stiffness(model: Model) -> tuple[sp.csr_matrix, list[ShellKinematics], list[BeamGeometry]]:
    """Global stiffness ``K (n_dofs, n_dofs)`` CSR (springs and elastic supports included).

    Also returns the shell kinematics and beam geometries, reused for load vectors.
    """
    n = model.n_dofs
    coo = COOData.empty(n)
    kins, geos = [], []
    for s in model.shells:
        kin = shell_kinematics(model.nodes[s.conn])
        kins.append(kin)
        ke = shell_stiffness(None, s.thickness, s.E, s.nu, kin, s.drill_factor)
        coo.add_elements(element_dofs(s.conn), ke)
    for b in model.beams:
        geo = beam_geometry(
            model.nodes[b.conn[:, 0]], model.nodes[b.conn[:, 1]], b.orientation, b.offset_i, b.offset_j
        )
        geos.append(geo)
        coo.add_elements(
            element_dofs(b.conn), beam_stiffness(geo, b.A, b.Iy, b.Iz, b.J, b.E, b.G, b.Asy, b.Asz)
        )
    for sp_ in model.springs:
        ground = sp_.node_j < 0
        pair = ~ground
        if pair.any():
            conn = np.stack([sp_.node_i[pair], sp_.node_j[pair]], axis=1)
            coo.add_elements(element_dofs(conn), spring_stiffness(sp_.k[pair]))
        if ground.any():
            coo.add_diagonal(element_dofs(sp_.node_i[ground][:, None]), sp_.k[ground])
    for s in model.supports:
        if not s.rigid:
            dofs = 6 * s.nodes[:, None] + np.array(s.dofs)[None, :]
            coo.add_diagonal(dofs, np.broadcast_to(s.stiffness, dofs.shape))
    return coo.tocsr(), kins, geos


#: Largest error of the factorization's self-check ``solve(K x) - x`` (x ~ N(0, 1)) before the
#: matrix is declared singular; well-posed models stay many orders of magnitude below.
MECHANISM_TOL = 1e-2


def nested_dissection(k: sp.spmatrix, groups: np.ndarray) -> np.ndarray | None:
    """Fill-reducing order of the rows of ``k`` by METIS nested dissection on the node graph, or None.

    ``groups (n,)`` names the node of each row; the DOFs of a node stay together. Needs the optional
    ``pymetis`` package; returns None when it is not importable.
    """
    try:
        import pymetis  # type: ignore[import-not-found]
    except ImportError:
        return None
    groups = np.asarray(groups, np.int64)
    _, node = np.unique(groups, return_inverse=True)
    n_nodes = int(node.max()) + 1
    p = sp.csr_matrix((np.ones(len(node)), (np.arange(len(node)), node)), shape=(len(node), n_nodes))
    pattern = sp.csr_matrix(k, copy=True)
    pattern.data[:] = 1.0
    g = (p.T @ pattern @ p).tocsr()
    g.setdiag(0)
    g.eliminate_zeros()
    adjacency = pymetis.CSRAdjacency(g.indptr, g.indices) if hasattr(pymetis, "CSRAdjacency") else None
    if adjacency is not None:
        perm, _ = pymetis.nested_dissection(adjacency)
    else:
        perm, _ = pymetis.nested_dissection(xadj=g.indptr, adjncy=g.indices)
    rank = np.empty(n_nodes, np.int64)
    rank[np.asarray(perm)] = np.arange(n_nodes)
    return np.lexsort((np.arange(len(node)), rank[node]))


class Factorization:
    """Sparse direct factorization of a symmetric positive definite matrix, reused for many right-hand sides.

    Backends: ``cholmod`` (scikit-sparse, optional), ``splu-nd`` (SuperLU in symmetric mode on a
    METIS nested-dissection order of the node graph; needs the optional ``pymetis`` and ``groups``),
    ``splu-mmd`` (SuperLU with ``MMD_AT_PLUS_A``, always available). ``auto`` takes the first available.
    """

    def __init__(self, k: sp.spmatrix, backend: str = "auto", groups: np.ndarray | None = None) -> None:
        if backend not in ("auto", "cholmod", "splu-nd", "splu-mmd"):
            raise SolverError(f"unknown solver backend {backend!r} (auto, cholmod, splu-nd, splu-mmd)")
        k = sp.csc_matrix(k)
        self.n = k.shape[0]
        self.backend = "splu-mmd"
        self._order: np.ndarray | None = None
        if self.n == 0:
            self._solve = lambda b: np.zeros_like(b)
            return
        if backend in ("auto", "cholmod"):
            try:
                from sksparse.cholmod import cholesky  # type: ignore[import-not-found]
            except ImportError:
                if backend == "cholmod":
                    raise SolverError(
                        "backend 'cholmod' needs scikit-sparse, which is not installed"
                    ) from None
            else:
                try:
                    self._solve = cholesky(k)
                except Exception as err:  # CholmodNotPositiveDefiniteError and friends
                    raise SolverError(f"stiffness matrix not positive definite (mechanism?): {err}") from err
                self.backend = "cholmod"
                return
        spec = "MMD_AT_PLUS_A"
        if backend in ("auto", "splu-nd") and groups is not None:
            self._order = nested_dissection(k, groups)
            if self._order is not None:
                k = k[self._order][:, self._order].tocsc()
                spec = "NATURAL"
                self.backend = "splu-nd"
        if backend == "splu-nd" and self._order is None:
            raise SolverError("backend 'splu-nd' needs pymetis and DOF groups")
        try:
            lu = spla.splu(k, permc_spec=spec, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as err:
            raise SolverError(f"singular stiffness matrix (mechanism or missing support): {err}") from err
        self._solve = lu.solve
        # A mechanism leaves a (near) zero pivot that SuperLU does not always flag: solve for a known
        # random x and look at the error, which is O(1) or worse only along a mechanism.
        x = np.random.default_rng(0).standard_normal(self.n)
        err = np.abs(self._solve(k @ x) - x)
        if not np.all(np.isfinite(err)) or err.max() > MECHANISM_TOL:
            first = int(np.argmax(np.where(np.isfinite(err), err, np.inf)))
            index = int(first if self._order is None else self._order[first])
            error = SolverError(
                f"singular stiffness matrix (mechanism or missing support) at unknown {index}"
            )
            error.index = index  # type: ignore[attr-defined]
            raise error

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``K x = b`` for ``b (n,)`` or ``(n, m)``."""
        b = np.asarray(b, float)
        if self._order is None:
            x = self._solve(b)
        else:
            x = np.empty_like(b)
            x[self._order] = self._solve(np.ascontiguousarray(b[self._order]))
        if not np.all(np.isfinite(x)):
            raise SolverError("non-finite displacements (mechanism or missing support)")
        return x


@dataclass
class Result:
    """Solution of one load case.

    Attributes:
        case: load case name.
        u: (n_nodes, 6) displacements and rotations in global axes, m and rad.
        reactions: support name -> (len(support.dofs),) force/moment the support exerts on the
            structure, summed over its nodes, global axes, N and N m.
        dofs: support name -> DOF names of the entries in ``reactions``.

    """

    case: str
    u: np.ndarray
    reactions: dict[str, np.ndarray]
    dofs: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def reaction(self, support: str, dof: str = "uz") -> float:
        """Reaction of ``support`` along ``dof`` (N or N m)."""
        try:
            return float(self.reactions[support][self.dofs[support].index(dof)])
        except (KeyError, ValueError) as err:
            raise ModelError(f"no reaction {support!r}/{dof!r} in this result") from err


class LinearStaticSolver:
    """Assemble and factorize a model once; solve any number of load cases against it.

    Attributes:
        model: the model. K: (n_dofs, n_dofs) CSR global stiffness before constraints.
        constraints: elimination of slave/prescribed DOFs. n_free: number of unknowns solved for.
        timings: seconds spent in ``assembly``, ``factorization`` and the last ``solve``.

    """

    def __init__(self, model: Model, backend: str = "auto") -> None:
        model.validate()
        self.model = model
        t0 = time.perf_counter()
        self.K, self._kins, self._geos = assemble_stiffness(model)
        self.constraints: Constraints = build_constraints(model)
        cf, cp = self.constraints.cf, self.constraints.cp
        if model.links:
            self._kf = (cf.T @ self.K @ cf).tocsc()
            self._kfp = (cf.T @ self.K @ cp).tocsr()
        else:  # plain selection: slicing is cheaper than two sparse products
            rows = self.K[self.constraints.free]
            self._kf = rows[:, self.constraints.free].tocsc()
            self._kfp = rows[:, self.constraints.presc].tocsr()
        t1 = time.perf_counter()
        try:
            self._factor = Factorization(self._kf, backend, groups=self.constraints.free // 6)
        except SolverError as err:
            index = getattr(err, "index", None)
            if index is None:
                raise
            dof = int(self.constraints.free[index])
            raise SolverError(
                f"singular stiffness matrix: mechanism or missing support near node {dof // 6} "
                f"({DOF_NAMES[dof % 6]})"
            ) from err
        t2 = time.perf_counter()
        self.timings = {"assembly": t1 - t0, "factorization": t2 - t1, "solve": 0.0}

    @property
    def n_free(self) -> int:
        """Number of independent unknowns."""
        return self._kf.shape[0]

    @property
    def backend(self) -> str:
        """Factorization backend in use (``cholmod``, ``splu-nd`` or ``splu-mmd``)."""
        return self._factor.backend

    def _prescribed(self, case: LoadCase) -> np.ndarray:
        """Vector of prescribed values on the rigid support DOFs (n_presc,), and ground shifts."""
        up = np.zeros(len(self.constraints.presc))
        names = {s.name for s in self.model.supports}
        for name, value in case.prescribed.items():
            if name not in names:
                raise ModelError(f"load case {case.name!r}: no support named {name!r}")
            s = self.model.support(name)
            if s.rigid:
                idx = self.constraints.presc_index[name]
                up[idx] = np.broadcast_to(np.asarray(value, float), (idx.shape[1],))[None, :]
        return up

    def _elastic_shift(self, case: LoadCase) -> np.ndarray:
        """Load ``k g`` from the ground displacement ``g`` of elastic supports (n_dofs,)."""
        f = np.zeros(self.model.n_dofs)
        for name, value in case.prescribed.items():
            s = self.model.support(name)
            if not s.rigid:
                g = np.broadcast_to(np.asarray(value, float), (len(s.dofs),))
                dofs = 6 * s.nodes[:, None] + np.array(s.dofs)[None, :]
                np.add.at(f, dofs, np.broadcast_to(s.stiffness * g, dofs.shape))
        return f

    def load_vector(self, case: LoadCase) -> np.ndarray:
        """Global load vector of ``case`` (n_dofs,), N and N m (without elastic-support ground shifts)."""
        return load_vector(self.model, case, self._kins, self._geos)

    def solve(self, cases: LoadCase | Sequence[LoadCase]) -> Result | list[Result]:
        """Solve one load case (returns a Result) or several (returns a list, one factorization)."""
        single = isinstance(cases, LoadCase)
        seq: list[LoadCase] = [cases] if single else list(cases)  # type: ignore[list-item]
        t0 = time.perf_counter()
        cf, cp = self.constraints.cf, self.constraints.cp
        f = np.stack([self.load_vector(c) + self._elastic_shift(c) for c in seq], axis=1)
        up = np.stack([self._prescribed(c) for c in seq], axis=1)
        rhs = cf.T @ f - self._kfp @ up
        q = self._factor.solve(rhs)
        u = cf @ q + cp @ up
        resid = self.K @ u - f
        rp = cp.T @ resid
        results = [self._result(c, u[:, i], rp[:, i]) for i, c in enumerate(seq)]
        self.timings["solve"] = time.perf_counter() - t0
        return results[0] if single else results

    def _result(self, case: LoadCase, u: np.ndarray, rp: np.ndarray) -> Result:
        reactions: dict[str, np.ndarray] = {}
        dofs: dict[str, tuple[str, ...]] = {}
        for s in self.model.supports:
            dofs[s.name] = tuple(DOF_NAMES[d] for d in s.dofs)
            if s.rigid:
                reactions[s.name] = rp[self.constraints.presc_index[s.name]].sum(axis=0)
            else:
                g = np.zeros(len(s.dofs))
                if s.name in case.prescribed:
                    g = np.broadcast_to(np.asarray(case.prescribed[s.name], float), (len(s.dofs),))
                ud = u[6 * s.nodes[:, None] + np.array(s.dofs)[None, :]]
                reactions[s.name] = (s.stiffness * (g[None, :] - ud)).sum(axis=0)
        return Result(case=case.name, u=u.reshape(-1, 6), reactions=reactions, dofs=dofs)

    def support_stiffness(self, names: Sequence[str], dof: str = "uz") -> np.ndarray:
        """Generalized stiffness ``(m, m)`` of the supports ``names`` along ``dof``.

        Entry ``(i, j)`` is the reaction at support i per unit displacement imposed at support j
        (all other supports at rest, no load): N/m for translations. It equals the Schur complement
        of K on those DOFs; symmetric positive semi-definite.
        """
        d = DOF_NAMES.index(dof)
        for name in names:
            if d not in self.model.support(name).dofs:
                raise ModelError(f"support {name!r} does not restrain {dof!r}")
        cases = []
        for name in names:
            s = self.model.support(name)
            value = np.zeros(len(s.dofs))
            value[s.dofs.index(d)] = 1.0
            cases.append(LoadCase(name=f"unit {name}", prescribed={name: value}))
        res = self.solve(cases)
        return np.array([[r.reaction(name, dof) for r in res] for name in names])  # type: ignore[union-attr]
