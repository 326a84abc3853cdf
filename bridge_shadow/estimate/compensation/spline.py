"""Online penalized cubic B-spline regression ``y = g(T) + e`` from sufficient statistics.

The fit minimizes ``sum_i w_i (y_i - g(T_i))^2 + lambda int g''(T)^2 dT`` over cubic splines on
fixed breakpoints, i.e. ``(G + lambda Omega) beta = r`` with ``G = sum w b b^T``, ``r = sum w b y``.
Only ``G``, ``r``, ``sum w y^2``, ``sum w`` and ``sum w y`` are kept, so the online fit equals the
batch fit on all data seen; exponential forgetting multiplies the sums by a factor before each
update (a weighted batch fit). ``Omega`` is exact: ``b''`` is linear on each knot interval, so
two-point Gauss-Legendre per interval integrates ``b_k'' b_l''`` exactly.

``lambda`` is chosen by REML (default) or GCV from the sums alone, through the simultaneous
diagonalization of ``(G, Omega)``: with ``S = G + kappa Omega = R^T R`` and
``R^-T Omega R^-1 = V diag(d) V^T``, ``G + lambda Omega = R^T V diag(g + lambda d) V^T R`` where
``g = 1 - kappa d``, so every criterion costs O(q) per trial ``lambda``. (Small dense algebra
goes through numpy/LAPACK calls that do not start BLAS threads: on a busy 2-core machine
``scipy.linalg.solve_triangular`` took 14 ms for a 16x16 system.)
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import linalg
from scipy.interpolate import BSpline

__all__ = [
    "OnlinePSpline",
    "SplineFit",
    "basis_nonzero",
    "clamped_knots",
    "gram_penalty",
    "gram_slope",
    "nonzero_at",
    "select_lambda",
]

_DEGREE = 3


def clamped_knots(breakpoints: np.ndarray) -> np.ndarray:
    """Full cubic knot vector with the end breakpoints repeated (q = len(breakpoints) + 2)."""
    b = np.asarray(breakpoints, dtype=float)
    if b.ndim != 1 or len(b) < 2 or np.any(np.diff(b) <= 0):
        raise ValueError("breakpoints must be a strictly increasing 1-D array of length >= 2")
    return np.concatenate([np.full(_DEGREE, b[0]), b, np.full(_DEGREE, b[-1])])


def _basis(knots: np.ndarray, x: np.ndarray, nu: int = 0) -> np.ndarray:
    """Dense basis (or its ``nu``-th derivative) at ``x`` inside the knot range: (len(x), q).

    Values use the Cox-de Boor recursion vectorized over ``x`` (equal to
    ``BSpline.design_matrix`` to rounding, without its per-call overhead); derivatives use scipy.
    """
    q = len(knots) - _DEGREE - 1
    if nu:
        return BSpline(knots, np.eye(q), _DEGREE).derivative(nu)(x)
    x = np.asarray(x, dtype=float)
    if x.size <= _SCALAR_PATH_MAX:
        return _basis_few(knots, x.tolist(), q)
    first, n = basis_nonzero(knots, x)
    out = np.zeros((len(x), q))
    cols = first[:, None] + np.arange(_DEGREE + 1)
    np.put_along_axis(out, cols, n, axis=1)
    return out


#: Up to this many points the basis (dense, ``_basis``, or its non-zero part, ``basis_nonzero``) is
#: evaluated point by point in plain floats: a window adds one temperature per channel, and numpy's
#: per-call overhead made the vectorized recursion 4-10x slower.
_SCALAR_PATH_MAX = 4


def _basis_few(knots: np.ndarray, xs: list[float], q: int) -> np.ndarray:
    """``_basis`` for a few points (``_nonzero_few`` placed in the dense rows)."""
    first, values = _nonzero_few(knots, xs, q)
    out = np.zeros((len(xs), q))
    for row, (i, n) in enumerate(zip(first.tolist(), values, strict=True)):
        out[row, i : i + _DEGREE + 1] = n
    return out


def _nonzero_few(knots: np.ndarray, xs: list[float], q: int) -> tuple[np.ndarray, np.ndarray]:
    """``basis_nonzero`` for a few points: the same Cox-de Boor recursion on Python floats."""
    t = knots.tolist()
    first = np.empty(len(xs), dtype=np.int64)
    values = np.empty((len(xs), _DEGREE + 1))
    for row, x in enumerate(xs):
        first[row], values[row] = nonzero_at(t, x, q)
    return first, values


def nonzero_at(t: list[float], x: float, q: int) -> tuple[int, list[float]]:
    """Return the four non-zero cubic B-splines at one point ``x`` (knots ``t`` floats): first index, values.

    The Cox-de Boor recursion of ``basis_nonzero`` on Python floats, operation for operation.
    """
    i = min(max(bisect_right(t, x) - 1, _DEGREE), q - 1)
    n = [1.0, 0.0, 0.0, 0.0]
    left = [0.0] * (_DEGREE + 1)
    right = [0.0] * (_DEGREE + 1)
    for j in range(1, _DEGREE + 1):
        left[j] = x - t[i + 1 - j]
        right[j] = t[i + j] - x
        saved = 0.0
        for r in range(j):
            temp = n[r] / (right[r + 1] + left[j - r])
            n[r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        n[j] = saved
    return i - _DEGREE, n


def gram_penalty(knots: np.ndarray) -> np.ndarray:
    """``Omega_kl = int b_k'' b_l''`` over the knot range, exact (2-point Gauss-Legendre), (q, q)."""
    edges = np.unique(knots)
    left, right = edges[:-1], edges[1:]
    half, mid = 0.5 * (right - left), 0.5 * (right + left)
    node = 1.0 / np.sqrt(3.0)
    xq = np.concatenate([mid - half * node, mid + half * node])
    wq = np.concatenate([half, half])
    d2 = _basis(knots, xq, nu=2)
    omega = (d2 * wq[:, None]).T @ d2
    return 0.5 * (omega + omega.T)


def gram_slope(knots: np.ndarray) -> np.ndarray:
    """``Omega1_kl = int b_k' b_l'`` over the knot range, exact (3-point Gauss-Legendre), (q, q).

    ``beta' Omega1 beta = int g'(T)^2 dT``: the first-derivative penalty (``b'`` is quadratic, the
    product of degree 4, so three Gauss-Legendre points per knot interval integrate it exactly).
    """
    edges = np.unique(knots)
    left, right = edges[:-1], edges[1:]
    half, mid = 0.5 * (right - left), 0.5 * (right + left)
    nodes, weights = np.polynomial.legendre.leggauss(3)
    xq = np.concatenate([mid + half * t for t in nodes])
    wq = np.concatenate([half * w for w in weights])
    d1 = _basis(knots, xq, nu=1)
    omega1 = (d1 * wq[:, None]).T @ d1
    return 0.5 * (omega1 + omega1.T)


def _solve(lhs: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve the symmetric ``lhs x = rhs``; the minimum-norm least squares when it is (near) singular.

    A Cholesky factor with a diagonal spread under 1e-6 (condition under about 1e12) solves it;
    otherwise (data at one temperature leave the slope unidentified) ``lstsq``.
    """
    try:
        chol = np.linalg.cholesky(lhs)
    except np.linalg.LinAlgError:
        chol = None
    if chol is not None:
        diag = np.diagonal(chol)
        if diag.min() > 1e-6 * diag.max():
            x, info = linalg.lapack.dpotrs(chol, rhs, lower=1)
            if info == 0:
                return x
    return np.linalg.lstsq(lhs, rhs, rcond=1e-13)[0]


def _eigen(G: np.ndarray, omega: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simultaneous diagonalization of ``(G, Omega)``: (g, d, v~ = V^T L^-1 r)."""
    q = len(r)
    kappa = np.trace(G) / np.trace(omega)
    # S = L L^T; a relative 1e-12 ridge keeps S definite when the data leave the slope
    # unidentified (all windows at one temperature); it only steers the lambda search
    S = G + kappa * omega
    chol = np.linalg.cholesky(S + 1e-12 * np.trace(S) / q * np.eye(q))
    linv, info = linalg.lapack.dtrtri(chol, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("singular Cholesky factor")
    d, vecs = np.linalg.eigh(linv @ omega @ linv.T)
    d = np.clip(d, 0.0, None)
    g = np.clip(1.0 - kappa * d, 0.0, None)
    return g, d, vecs.T @ (linv @ r)


def _criterion(
    g: np.ndarray, d: np.ndarray, vt: np.ndarray, p0: int, yy: float, n_obs: float, mode: str
) -> Callable[[np.ndarray], np.ndarray]:
    """REML or GCV score as a function of trial ``log10 lambda`` values (vectorized)."""
    v2 = vt * vt
    pos = d > 0
    g_pen, d_pen = g[pos], d[pos]
    n_pen = len(d_pen)

    def reml(log_lam: np.ndarray) -> np.ndarray:
        lam = (10.0**log_lam)[:, None]
        fit_ss = yy - np.sum(v2 / (g + lam * d), axis=1)
        log_det = np.sum(np.log(g_pen + lam * d_pen), axis=1)
        return (n_obs - p0) * np.log(np.maximum(fit_ss, 1e-300)) + log_det - n_pen * np.log(lam[:, 0])

    def gcv(log_lam: np.ndarray) -> np.ndarray:
        a = g + (10.0**log_lam)[:, None] * d
        rss = yy - np.sum(v2 * (2.0 / a - g / a**2), axis=1)
        edf = np.sum(g / a, axis=1)
        return n_obs * np.maximum(rss, 1e-300) / np.maximum(n_obs - edf, 1e-12) ** 2

    return reml if mode == "reml" else gcv


def select_lambda(
    G: np.ndarray, omega: np.ndarray, r: np.ndarray, yy: float, n_obs: float, mode: str = "reml"
) -> float:
    """Minimize REML or GCV of ``(G + lambda Omega) beta = r`` over ``log10 lambda``, from sums alone.

    ``G = sum w b b'`` (q, q), ``r = sum w b y`` (q,), ``yy = sum w y^2`` and ``n_obs`` the number of
    observations (the residual degrees of freedom before the fit). A 0.25-decade grid over 16
    decades, a 0.005-decade grid around its best point, and the vertex of the parabola through the
    best fine point and its neighbours.
    """
    g, d, vt = _eigen(G, omega, r)
    dmax = float(d.max()) if d.size else 0.0
    pos = d > 1e-9 * dmax
    d = np.where(pos, d, 0.0)
    p0 = int(np.count_nonzero(~pos))
    score = _criterion(g, d, vt, p0, float(yy), float(n_obs), mode)
    # lambda d ~ 1 at the balance point: search 8 decades either side of 1 / median(d).
    center = -np.log10(np.median(d[pos])) if pos.any() else 0.0
    coarse = center + np.linspace(-8.0, 8.0, 65)
    fine = coarse[int(np.argmin(score(coarse)))] + np.linspace(-0.25, 0.25, 101)
    values = score(fine)
    j = int(np.argmin(values))
    best = float(fine[j])
    if 0 < j < len(fine) - 1:
        lo, mid, hi = values[j - 1], values[j], values[j + 1]
        curvature = hi - 2.0 * mid + lo
        if curvature > 0:
            best -= 0.5 * (fine[1] - fine[0]) * (hi - lo) / curvature
    return 10.0**best


def basis_nonzero(knots: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return the four non-zero cubic B-splines at ``x``: (first index (n,), values (n, 4)).

    The same Cox-de Boor recursion as ``_basis``, vectorized over ``x``; column ``j`` of the values
    is basis function ``i0 + j``.
    """
    x = np.asarray(x, dtype=float).ravel()
    q = len(knots) - _DEGREE - 1
    if len(x) <= _SCALAR_PATH_MAX:
        return _nonzero_few(knots, x.tolist(), q)
    # interval i with t_i <= x < t_{i+1}; the right end belongs to the last non-empty interval
    i = np.minimum(np.maximum(np.searchsorted(knots, x, side="right") - 1, _DEGREE), q - 1)
    n = np.zeros((len(x), _DEGREE + 1))
    n[:, 0] = 1.0
    left = np.empty((len(x), _DEGREE + 1))
    right = np.empty((len(x), _DEGREE + 1))
    for j in range(1, _DEGREE + 1):
        left[:, j] = x - knots[i + 1 - j]
        right[:, j] = knots[i + j] - x
        saved = np.zeros(len(x))
        for r in range(j):
            temp = n[:, r] / (right[:, r + 1] + left[:, j - r])
            n[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        n[:, j] = saved
    return (i - _DEGREE).astype(np.int64), n


@dataclass
class SplineFit:
    """Result of one fit.

    Attributes:
        beta: (q,) coefficients (units of y).
        lam: smoothing parameter (units of y^2 per (d^2 g / dT^2)^2 dT); inf for a constant fit.
        edf: effective degrees of freedom ``tr((G + lambda Omega)^-1 G)``.
        mean_y: weighted mean of y (the level added back by compensation).

    """

    beta: np.ndarray
    lam: float
    edf: float
    mean_y: float


class OnlinePSpline:
    """Penalized cubic B-spline fitted online from sufficient statistics.

    Attributes:
        knots: full clamped knot vector; the basis has ``q = len(knots) - 4`` functions.
        omega: (q, q) curvature penalty.
        mode: ``reml`` | ``gcv`` | ``fixed`` | ``none`` (``none``: g is the constant mean of y).
        lam_fixed: lambda used in ``fixed`` mode.
        G, r, yy, sw, sy, st: the sums ``w b b^T``, ``w b y``, ``w y^2``, ``w``, ``w y``, ``w T``.
        n_obs: observations added (not decayed); n_clamped: those with T outside the range.

    """

    def __init__(self, breakpoints: np.ndarray, mode: str = "reml", lam: float = 10.0) -> None:
        if mode not in ("reml", "gcv", "fixed", "none"):
            raise ValueError(f"unknown smoothing mode {mode!r}")
        self.knots = clamped_knots(breakpoints)
        self.t_min, self.t_max = float(self.knots[0]), float(self.knots[-1])
        self.q = len(self.knots) - _DEGREE - 1
        self.omega = gram_penalty(self.knots)
        self.mode = mode
        self.lam_fixed = float(lam)
        self.G = np.zeros((self.q, self.q))
        self.r = np.zeros(self.q)
        self.yy = 0.0
        self.sw = 0.0
        self.sy = 0.0
        self.st = 0.0
        self.n_obs = 0
        self.n_clamped = 0
        self._fit: SplineFit | None = None

    @classmethod
    def uniform(cls, t_min: float, t_max: float, segments: int, **kwargs: object) -> OnlinePSpline:
        """Equally spaced breakpoints over ``[t_min, t_max]`` with ``segments`` intervals."""
        return cls(np.linspace(t_min, t_max, segments + 1), **kwargs)  # type: ignore[arg-type]

    def basis(self, temp_c: np.ndarray) -> np.ndarray:
        """Basis at temperatures clamped into the knot range: (n, q)."""
        t = np.asarray(temp_c, dtype=float)
        if t.size <= _SCALAR_PATH_MAX:
            t = np.array([min(max(v, self.t_min), self.t_max) for v in t.ravel().tolist()])
        else:
            t = np.clip(t, self.t_min, self.t_max)
        return _basis(self.knots, t)

    def add(self, temp_c: np.ndarray, y: np.ndarray, w: np.ndarray | float = 1.0, decay: float = 1.0) -> None:
        """Add observations (after multiplying the old sums by ``decay``); NaN must be gated before."""
        t = np.atleast_1d(np.asarray(temp_c, dtype=float))
        yv = np.atleast_1d(np.asarray(y, dtype=float))
        wv = np.broadcast_to(np.asarray(w, dtype=float), yv.shape)
        if decay != 1.0:
            self.G *= decay
            self.r *= decay
            self.yy *= decay
            self.sw *= decay
            self.sy *= decay
            self.st *= decay
        if self.mode != "none":  # a constant curve needs only the scalar sums
            b = self.basis(t)
            self.G += (b * wv[:, None]).T @ b
            self.r += b.T @ (wv * yv)
        self.yy += float(np.sum(wv * yv * yv))
        self.sw += float(np.sum(wv))
        self.sy += float(np.sum(wv * yv))
        self.st += float(np.sum(wv * np.clip(t, self.t_min, self.t_max)))
        self.n_obs += len(yv)
        self.n_clamped += int(np.count_nonzero((t < self.t_min) | (t > self.t_max)))
        self._fit = None

    @property
    def mean_t(self) -> float:
        """Weighted mean of the (clamped) temperatures added, C."""
        return self.st / self.sw if self.sw > 0 else float("nan")

    # -- fitting ----------------------------------------------------------------------------
    def select_lambda(self) -> float:
        """Smoothing parameter of the current mode (REML/GCV minimized over log10 lambda)."""
        if self.mode == "fixed":
            return self.lam_fixed
        return select_lambda(self.G, self.omega, self.r, self.yy, self.sw, self.mode)

    def fit(self) -> SplineFit:
        """Fit with the current sums (cached until the next ``add``); needs data."""
        if self._fit is not None:
            return self._fit
        if self.sw <= 0:
            raise ValueError("no data in the spline yet")
        mean_y = self.sy / self.sw
        if self.mode == "none":
            beta = np.full(self.q, mean_y)  # B-splines sum to one: a constant curve
            self._fit = SplineFit(beta, float("inf"), 1.0, mean_y)
            return self._fit
        lam = self.select_lambda()
        lhs = self.G + lam * self.omega
        sol = _solve(lhs, np.column_stack([self.r, self.G]))
        beta, edf = sol[:, 0], float(np.trace(sol[:, 1:]))
        self._fit = SplineFit(beta, float(lam), edf, mean_y)
        return self._fit

    def predict(self, temp_c: np.ndarray) -> np.ndarray:
        """``g(T)`` (temperatures clamped into the knot range)."""
        if self.mode == "none":
            return np.full(np.shape(np.atleast_1d(temp_c)), self.fit().mean_y)
        return self.basis(np.atleast_1d(temp_c)) @ self.fit().beta

    def leverage(self, temp_c: np.ndarray) -> np.ndarray:
        """Diagonal of the hat matrix ``b(T)' (G + lambda Omega)^-1 b(T)`` for unit weight (n,).

        ``(y - g(T)) / (1 - h)`` is then the leave-one-out residual of an observation in the fit.
        """
        if self.mode == "none":
            return np.full(np.shape(np.atleast_1d(temp_c)), 1.0 / self.sw)
        fit = self.fit()
        b = self.basis(np.atleast_1d(temp_c))
        lhs = self.G + fit.lam * self.omega
        return np.einsum("ij,ji->i", b, _solve(lhs, b.T))

    def compensate(self, temp_c: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Compensated values ``y - g(T) + mean(y)``."""
        fit = self.fit()
        return np.asarray(y, float) - self.predict(temp_c) + fit.mean_y

    # -- state ----------------------------------------------------------------------------
    def state_dict(self) -> dict[str, object]:
        """Plain-data state (arrays and scalars)."""
        return {
            "G": self.G.copy(),
            "r": self.r.copy(),
            "yy": self.yy,
            "sw": self.sw,
            "sy": self.sy,
            "st": self.st,
            "n_obs": self.n_obs,
            "n_clamped": self.n_clamped,
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore sums written by ``state_dict``."""
        self.G = np.array(state["G"], dtype=float).reshape(self.q, self.q)
        self.r = np.array(state["r"], dtype=float).reshape(self.q)
        self.yy = float(state["yy"])  # type: ignore[arg-type]
        self.sw = float(state["sw"])  # type: ignore[arg-type]
        self.sy = float(state["sy"])  # type: ignore[arg-type]
        self.st = float(state["st"])  # type: ignore[arg-type]
        self.n_obs = int(state["n_obs"])  # type: ignore[call-overload]
        self.n_clamped = int(state["n_clamped"])  # type: ignore[call-overload]
        self._fit = None
