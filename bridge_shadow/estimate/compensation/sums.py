"""Sufficient statistics of the window means: everything the fit, the noise model and the posterior need.

Each accepted window ``w`` brings, per channel ``c``, the sample count ``m`` (its weight), the
window-mean force ``y`` relative to ``u0`` (N), the cubic B-spline basis ``b`` (q,) of its mean
air temperature (4 non-zeros; none when the temperature is unknown) and the settlement segment
``s`` it belongs to (segments are separated by detected events; the settlement is constant inside
one). The sums below are additive, so a fit over every window ever seen costs O(q^2) memory and an
update costs a few ``np.bincount`` calls per batch of windows, whatever the record length:

==============================  ====================================================================
per channel                      ``W = sum m``, ``sy = sum m y``, ``yy = sum m y^2``, ``sb = sum m b``,
                                 ``r = sum m b y``, ``G = sum m b b'``
per segment and channel          ``Ws, sys, sbs`` (the same over the segment's windows), ``ns``;
                                 ``Ssv = sum m sv`` (the sun covariate's sd, for its share of a level)
across channels (``p = sqrt(m0 m1)``)  ``X1s, Xy0s, Xy1s, Xb0s, Xb1s`` per segment; ``Xyy = sum p y0 y1``,
                                 ``Xb0y1 = sum p b0 y1``, ``Xy0b1 = sum p y0 b1``, ``XBB = sum p b0 b1'``
lag 1 (adjacent windows of one   ``L1s, Lyps, Lycs, Lbps, Lbcs`` per segment (``p = sqrt(m' m)``, ``'`` the
segment, per channel)            earlier window); ``Lyy = sum p y' y``, ``Lby = sum p b' y``,
                                 ``Lyb = sum p y' b``, ``LBB = sum p b' b'``
==============================  ====================================================================

``residual_moments`` turns them into the weighted second moments and lag-1 products of the
residuals ``e = y - l_s - b' beta`` for any coefficients ``beta`` and segment levels ``l``, exactly
as a batch pass over the windows would (up to rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FitSums", "Moments", "WindowRows", "residual_moments", "row_columns"]

_FIELDS = ("k", "m", "y", "t", "i0", "bv", "seg", "sv")


@dataclass
class WindowRows:
    """Accepted windows ready for the sums (one row per window).

    Attributes:
        k: (n,) int64 window index.
        m: (n, 2) float, samples per channel (the weight of the mean).
        y: (n, 2) N, window-mean force minus ``u0`` (minus ``A x`` when the settlement moves).
        t: (n, 2) C, window-mean air temperature (NaN when unknown).
        i0: (n, 2) int, first non-zero basis index, -1 when the temperature is unknown.
        bv: (n, 2, w) the non-zero basis values: the four B-splines, and the sun covariate when the
            compensation has a sun term (``w = 5``, ``row_columns``).
        seg: (n,) int, settlement segment.
        sv: (n,) sd of the sun covariate (what it does not know of the sky; 0 without a sun term).

    """

    k: np.ndarray
    m: np.ndarray
    y: np.ndarray
    t: np.ndarray
    i0: np.ndarray
    bv: np.ndarray
    seg: np.ndarray
    sv: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.sv is None:
            self.sv = np.zeros(len(self.k))

    def __len__(self) -> int:
        return len(self.k)

    def dense_b(self, q: int) -> np.ndarray:
        """Return the full basis rows (n, 2, q) (zeros where the temperature is unknown)."""
        out = np.zeros((len(self.k), 2, q))
        for c in range(2):
            ok = self.i0[:, c] >= 0
            rows = np.flatnonzero(ok)
            cols = row_columns(self.i0[ok, c], self.bv.shape[-1], q)
            out[rows[:, None], c, cols] = self.bv[ok, c]
        return out

    @classmethod
    def concat(cls, parts: list[WindowRows]) -> WindowRows:
        """Rows of several batches in order."""
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in _FIELDS))


def row_columns(i0: np.ndarray, width: int, q: int) -> np.ndarray:
    """Basis columns (n, width) of rows whose spline part starts at ``i0``.

    The four cubic B-splines sit at ``i0 .. i0 + 3``; a fifth value (``width == 5``) is the sun
    covariate, in the last column ``q - 1`` (``Compensation`` with a sun term).
    """
    cols = np.asarray(i0)[:, None] + np.arange(4)
    if width == 4:
        return cols
    return np.column_stack([cols, np.full(len(cols), q - 1)])


def _scatter_vec(idx: np.ndarray, vals: np.ndarray, q: int) -> np.ndarray:
    """Sum over rows of a q-vector with ``vals`` (n, k) at columns ``idx`` (n, k)."""
    if not len(idx):
        return np.zeros(q)
    return np.bincount(idx.ravel(), weights=vals.ravel(), minlength=q)


def _scatter_outer(
    ia: np.ndarray, a: np.ndarray, ib: np.ndarray, b: np.ndarray, w: np.ndarray, q: int
) -> np.ndarray:
    """Sum over rows of ``w a b'`` (a at columns ia, b at ib) as a (q, q) matrix."""
    if not len(ia):
        return np.zeros((q, q))
    idx = (ia[:, :, None] * q + ib[:, None, :]).ravel()
    vals = (w[:, None, None] * a[:, :, None] * b[:, None, :]).ravel()
    return np.bincount(idx, weights=vals, minlength=q * q).reshape(q, q)


def _scatter_seg_vec(seg: np.ndarray, idx: np.ndarray, vals: np.ndarray, n_seg: int, q: int) -> np.ndarray:
    """Per-segment q-vectors (n_seg, q)."""
    if not len(idx):
        return np.zeros((n_seg, q))
    flat = (seg[:, None] * q + idx).ravel()
    return np.bincount(flat, weights=vals.ravel(), minlength=n_seg * q).reshape(n_seg, q)


class FitSums:
    """The additive sums of the accepted windows (see the module docstring for each name).

    Attributes:
        q: number of basis functions; width: basis values per row (4, or 5 with a sun term).
        n: windows added; n_pairs: (2,) lag-1 pairs added per channel (the same for both).
        t_lo, t_hi: (2,) C, lowest and highest window temperature added per channel.
        prev: the last window added (for the lag-1 pair with the next one), or None.

    """

    _GLOBAL = ("W", "sy", "yy", "sb", "r", "G", "Xyy", "Xb0y1", "Xy0b1", "XBB", "Lyy", "Lby", "Lyb", "LBB")
    _SEG = (
        "ns",
        "Ws",
        "sys",
        "sbs",
        "X1s",
        "Xy0s",
        "Xy1s",
        "Xb0s",
        "Xb1s",
        "L1s",
        "Lyps",
        "Lycs",
        "Lbps",
        "Lbcs",
        "Ssv",
    )

    def __init__(self, q: int, width: int = 4) -> None:
        self.q = q
        self.width = width
        self.n = 0
        self.n_pairs = 0
        self.W = np.zeros(2)
        self.sy = np.zeros(2)
        self.yy = np.zeros(2)
        self.sb = np.zeros((2, q))
        self.r = np.zeros((2, q))
        self.G = np.zeros((2, q, q))
        self.Xyy = np.zeros(())
        self.Xb0y1 = np.zeros(q)
        self.Xy0b1 = np.zeros(q)
        self.XBB = np.zeros((q, q))
        self.Lyy = np.zeros(2)
        self.Lby = np.zeros((2, q))
        self.Lyb = np.zeros((2, q))
        self.LBB = np.zeros((2, q, q))
        self.t_lo = np.full(2, np.inf)
        self.t_hi = np.full(2, -np.inf)
        self._alloc_segments(0)
        self.prev: WindowRows | None = None

    def _alloc_segments(self, n_seg: int) -> None:
        q = self.q
        shapes = {
            "ns": (n_seg,),
            "Ws": (n_seg, 2),
            "sys": (n_seg, 2),
            "sbs": (n_seg, 2, q),
            "X1s": (n_seg,),
            "Xy0s": (n_seg,),
            "Xy1s": (n_seg,),
            "Xb0s": (n_seg, q),
            "Xb1s": (n_seg, q),
            "L1s": (n_seg, 2),
            "Lyps": (n_seg, 2),
            "Lycs": (n_seg, 2),
            "Lbps": (n_seg, 2, q),
            "Lbcs": (n_seg, 2, q),
            "Ssv": (n_seg, 2),
        }
        for name, shape in shapes.items():
            old = getattr(self, name, None)
            new = np.zeros(shape)
            if old is not None and len(old):
                new[: len(old)] = old
            setattr(self, name, new)

    @property
    def n_segments(self) -> int:
        """Segments with storage (the last may still be empty)."""
        return len(self.ns)

    def ensure_segment(self, s: int) -> None:
        """Make room for segment index ``s``."""
        if s >= self.n_segments:
            self._alloc_segments(s + 1)

    # -- adding ---------------------------------------------------------------------------------
    def add(self, rows: WindowRows) -> None:
        """Add accepted windows (in window order, after every window added before)."""
        n = len(rows)
        if not n:
            return
        q, width = self.q, rows.bv.shape[-1]
        self.ensure_segment(int(rows.seg.max()))
        n_seg = self.n_segments
        m, y, seg = rows.m, rows.y, rows.seg
        self.n += n
        self.W += m.sum(axis=0)
        self.sy += (m * y).sum(axis=0)
        self.yy += (m * y * y).sum(axis=0)
        self.ns += np.bincount(seg, minlength=n_seg)
        has = rows.i0 >= 0  # (n, 2): the window's temperature is known on that channel
        cols = [row_columns(np.where(has[:, c], rows.i0[:, c], 0), width, q) for c in range(2)]
        for c in range(2):
            self.Ws[:, c] += np.bincount(seg, weights=m[:, c], minlength=n_seg)
            self.sys[:, c] += np.bincount(seg, weights=m[:, c] * y[:, c], minlength=n_seg)
            self.Ssv[:, c] += np.bincount(seg, weights=m[:, c] * rows.sv, minlength=n_seg)
            ok = has[:, c]
            if ok.any():
                bv, mc, yc = rows.bv[ok, c], m[ok, c], y[ok, c]
                ix = cols[c][ok]
                self.sb[c] += _scatter_vec(ix, mc[:, None] * bv, q)
                self.r[c] += _scatter_vec(ix, (mc * yc)[:, None] * bv, q)
                self.G[c] += _scatter_outer(ix, bv, ix, bv, mc, q)
                self.sbs[:, c] += _scatter_seg_vec(seg[ok], ix, mc[:, None] * bv, n_seg, q)
                self.t_lo[c] = min(self.t_lo[c], float(np.min(rows.t[ok, c])))
                self.t_hi[c] = max(self.t_hi[c], float(np.max(rows.t[ok, c])))
        # across channels
        p = np.sqrt(m[:, 0] * m[:, 1])
        self.Xyy += float(np.sum(p * y[:, 0] * y[:, 1]))
        self.X1s += np.bincount(seg, weights=p, minlength=n_seg)
        self.Xy0s += np.bincount(seg, weights=p * y[:, 0], minlength=n_seg)
        self.Xy1s += np.bincount(seg, weights=p * y[:, 1], minlength=n_seg)
        ok0, ok1 = has[:, 0], has[:, 1]
        if ok0.any():
            self.Xb0s += _scatter_seg_vec(seg[ok0], cols[0][ok0], p[ok0, None] * rows.bv[ok0, 0], n_seg, q)
            self.Xb0y1 += _scatter_vec(cols[0][ok0], (p * y[:, 1])[ok0, None] * rows.bv[ok0, 0], q)
        if ok1.any():
            self.Xb1s += _scatter_seg_vec(seg[ok1], cols[1][ok1], p[ok1, None] * rows.bv[ok1, 1], n_seg, q)
            self.Xy0b1 += _scatter_vec(cols[1][ok1], (p * y[:, 0])[ok1, None] * rows.bv[ok1, 1], q)
        both = ok0 & ok1
        if both.any():
            self.XBB += _scatter_outer(
                cols[0][both], rows.bv[both, 0], cols[1][both], rows.bv[both, 1], p[both], q
            )
        self._add_pairs(rows)
        self.prev = WindowRows(*(getattr(rows, f)[-1:].copy() for f in _FIELDS))

    def _add_pairs(self, rows: WindowRows) -> None:
        """Lag-1 products of adjacent windows (k' + 1 = k) of the same segment."""
        full = rows if self.prev is None else WindowRows.concat([self.prev, rows])
        a = np.flatnonzero((np.diff(full.k) == 1) & (np.diff(full.seg) == 0))
        if not len(a):
            return
        b = a + 1
        q, n_seg, width = self.q, self.n_segments, full.bv.shape[-1]
        seg = full.seg[b]
        self.n_pairs += len(a)
        for c in range(2):
            p = np.sqrt(full.m[a, c] * full.m[b, c])
            ya, yb = full.y[a, c], full.y[b, c]
            self.Lyy[c] += float(np.sum(p * ya * yb))
            self.L1s[:, c] += np.bincount(seg, weights=p, minlength=n_seg)
            self.Lyps[:, c] += np.bincount(seg, weights=p * ya, minlength=n_seg)
            self.Lycs[:, c] += np.bincount(seg, weights=p * yb, minlength=n_seg)
            ok = full.i0[:, c] >= 0
            cols = row_columns(np.where(ok, full.i0[:, c], 0), width, q)  # once for both ends of a pair
            oka, okb = ok[a], ok[b]
            ca, cb, va, vb = cols[a], cols[b], full.bv[a, c], full.bv[b, c]
            if oka.any():
                self.Lbps[:, c] += _scatter_seg_vec(seg[oka], ca[oka], p[oka, None] * va[oka], n_seg, q)
                self.Lby[c] += _scatter_vec(ca[oka], (p * yb)[oka, None] * va[oka], q)
            if okb.any():
                self.Lbcs[:, c] += _scatter_seg_vec(seg[okb], cb[okb], p[okb, None] * vb[okb], n_seg, q)
                self.Lyb[c] += _scatter_vec(cb[okb], (p * ya)[okb, None] * vb[okb], q)
            ab = oka & okb
            if ab.any():
                self.LBB[c] += _scatter_outer(ca[ab], va[ab], cb[ab], vb[ab], p[ab], q)

    def remove_last(self, rows: WindowRows, before: WindowRows | None) -> None:
        """Take out ``rows``, the last windows added, and the lag-1 pair that joined them to ``before``.

        ``before``: the window added just before them (one row; None if they were the first). The
        sums are additive: those of ``rows`` alone (with ``before`` as their previous window) are
        subtracted. The temperature range stays as it was (it only widens the curve's support).
        """
        if not len(rows):
            return
        part = FitSums(self.q, self.width)
        part.ensure_segment(self.n_segments - 1)
        part.prev = before
        part.add(rows)
        self.ensure_segment(part.n_segments - 1)
        for name in (*self._GLOBAL, *self._SEG):
            setattr(self, name, getattr(self, name) - getattr(part, name))
        self.n -= part.n
        self.n_pairs -= part.n_pairs
        self.prev = None if before is None else WindowRows(*(getattr(before, f)[-1:].copy() for f in _FIELDS))

    def merge_into_previous(self, s: int) -> None:
        """Make segment ``s`` part of segment ``s - 1`` (later segments move down by one).

        The sums are additive, so the merged segment's sums are those of its windows; a lag-1 pair
        across the former boundary (adjacent windows only, never across a gap) stays uncounted.
        """
        if not 0 < s < self.n_segments:
            return
        for name in self._SEG:
            a = getattr(self, name)
            a[s - 1] += a[s]
            setattr(self, name, np.delete(a, s, axis=0))
        if self.prev is not None and int(self.prev.seg[0]) >= s:
            self.prev.seg = self.prev.seg - 1

    # -- state ----------------------------------------------------------------------------------
    def state_dict(self) -> dict[str, object]:
        """Plain-data state."""
        out: dict[str, object] = {name: np.array(getattr(self, name)) for name in (*self._GLOBAL, *self._SEG)}
        out.update(
            n=self.n,
            n_pairs=self.n_pairs,
            t_lo=self.t_lo.copy(),
            t_hi=self.t_hi.copy(),
            has_prev=self.prev is not None,
        )
        prev = self.prev or WindowRows(
            np.zeros(1, np.int64),
            np.zeros((1, 2)),
            np.zeros((1, 2)),
            np.zeros((1, 2)),
            np.zeros((1, 2), int),
            np.zeros((1, 2, self.width)),
            np.zeros(1, int),
            np.zeros(1),
        )
        out["prev"] = {f: getattr(prev, f) for f in _FIELDS}
        return out

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore the sums."""
        for name in (*self._GLOBAL, *self._SEG):
            setattr(self, name, np.array(state[name], dtype=float))
        self.ns = np.asarray(self.ns, float)
        self.n = int(state["n"])  # type: ignore[call-overload]
        self.n_pairs = int(state["n_pairs"])  # type: ignore[call-overload]
        self.t_lo = np.asarray(state["t_lo"], float).reshape(2)
        self.t_hi = np.asarray(state["t_hi"], float).reshape(2)
        p = state["prev"]
        self.prev = (
            WindowRows(
                np.asarray(p["k"], np.int64).reshape(1),  # type: ignore[index]
                np.asarray(p["m"], float).reshape(1, 2),  # type: ignore[index]
                np.asarray(p["y"], float).reshape(1, 2),  # type: ignore[index]
                np.asarray(p["t"], float).reshape(1, 2),  # type: ignore[index]
                np.asarray(p["i0"], int).reshape(1, 2),  # type: ignore[index]
                np.asarray(p["bv"], float).reshape(1, 2, -1),  # type: ignore[index]
                np.asarray(p["seg"], int).reshape(1),  # type: ignore[index]
                np.asarray(p["sv"], float).reshape(1),  # type: ignore[index]
            )
            if bool(state["has_prev"])
            else None
        )


@dataclass
class Moments:
    """Weighted residual moments (per-sample-equivalent ``u = sqrt(m) e``).

    Attributes:
        s2: (2, 2) sum of ``u u'`` over the windows (cross term with ``sqrt(m0 m1)``).
        lag: (2,) sum of ``u' u`` over adjacent pairs per channel.
        n: windows; n_pairs: pairs.

    """

    s2: np.ndarray
    lag: np.ndarray
    n: int
    n_pairs: int


def residual_moments(sums: FitSums, beta: np.ndarray, level: np.ndarray) -> Moments:
    """Residual moments of ``e = y - level_s - b' beta`` from the sums alone.

    Args:
        sums: the sufficient statistics.
        beta: (2, q) spline coefficients per channel (N).
        level: (n_seg, 2) N, the level of each segment per channel (relative to ``u0``).

    """
    s2 = np.zeros((2, 2))
    lag = np.zeros(2)
    for c in range(2):
        b = beta[c]
        ell = level[:, c]
        zs = sums.sys[:, c] - sums.sbs[:, c] @ b  # sum m (y - b'beta) per segment
        s2[c, c] = (
            sums.yy[c] - 2.0 * b @ sums.r[c] + b @ sums.G[c] @ b - 2.0 * ell @ zs + ell**2 @ sums.Ws[:, c]
        )
        zp = sums.Lyps[:, c] - sums.Lbps[:, c] @ b
        zc = sums.Lycs[:, c] - sums.Lbcs[:, c] @ b
        lag[c] = (
            sums.Lyy[c]
            - b @ sums.Lby[c]
            - b @ sums.Lyb[c]
            + b @ sums.LBB[c] @ b
            - ell @ (zp + zc)
            + ell**2 @ sums.L1s[:, c]
        )
    b0, b1 = beta
    l0, l1 = level[:, 0], level[:, 1]
    z0 = sums.Xy0s - sums.Xb0s @ b0
    z1 = sums.Xy1s - sums.Xb1s @ b1
    s2[0, 1] = s2[1, 0] = (
        sums.Xyy
        - b0 @ sums.Xb0y1
        - b1 @ sums.Xy0b1
        + b0 @ sums.XBB @ b1
        - l1 @ z0
        - l0 @ z1
        + (l0 * l1) @ sums.X1s
    )
    return Moments(s2, lag, sums.n, sums.n_pairs)
