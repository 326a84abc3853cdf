"""The candidates fitted to one residual: cross-validated, alone or beside fixed effects, in bounds.

``Fitter`` holds the residual, its folds and every candidate's design on the window grid (demeaned
per record on a day of records) and answers the questions the ranking asks: the cross-validated
fit of a candidate (``cv``), its design block for later joint fits, its data-optimal fit without
bounds and whether that lies outside the plausible range (``implausible``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.effects import EFFECTS, plausible_range
from bridge_shadow.engine import Mapper
from bridge_shadow.gap.candidates import CANDIDATES, Candidate, Context, spring_bearings
from bridge_shadow.gap.fit import CvResult, cross_validate, fit_best
from bridge_shadow.gap.si import si_params
from bridge_shadow.gap.spring import SpringModel, best_spring, cross_validate_spring

__all__ = ["BOUND_RTOL", "BY_NAME", "SPRING_SEARCH_SHARE", "Fitter", "candidate_params", "demean_records"]

#: Softest support spring searched when checking plausibility, as a share of the plausible low
#: end: a data-optimal spring below the plausible range is found and rejected, not cut off.
SPRING_SEARCH_SHARE = 1e-3


#: Relative tolerance on a bound before a fit counts as outside it.
BOUND_RTOL = 1e-6

#: Every candidate by name.
BY_NAME = {c.name: c for c in CANDIDATES}


def _k_of(c: float) -> float | None:
    """Spring stiffness N/m of a compliance m/N (None: rigid)."""
    return None if c <= 0 else float(1.0 / c)


def candidate_params(c: Candidate, beta: np.ndarray, grid_value: Any) -> dict[str, Any]:
    """Fitted parameters by name (SI); the support spring as stiffness per bearing."""
    if c.nonlinear:
        # stiffer than the plausible high end is the rigid support of the as-built model
        k_high = plausible_range("support_spring")[1]
        ks = [_k_of(float(b)) for b in beta]
        ks = [None if k is None or k > k_high else k for k in ks]
        side = "both" if all(ks) else "south" if ks[0] else "north" if ks[1] else "none"
        level = " levelled" if str(grid_value).endswith("levelled") else ""
        return {"bearing": side + level, "k_south [N/m]": ks[0], "k_north [N/m]": ks[1]}
    out: dict[str, Any] = {name: float(v) for name, v in zip(c.params, beta, strict=True)}
    if c.grid_name is not None:
        out[c.grid_name] = grid_value
    return out


def demean_records(x: np.ndarray, record: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Subtract each record's mean from ``x`` (n, 2, ...) per channel, over its windows with data.

    ``record``: (n,) record index per window (-1: none; left as is). On a day of records the level
    of a record is the settlement's business (``gap.levels``); what is left is the variation
    inside the records, which a fit of demeaned columns explains exactly as a joint fit with a
    free level per record would (Frisch-Waugh).
    """
    out = np.array(x, float, copy=True)
    for k in np.unique(record[record >= 0]):
        rows = record == k
        for ch in range(2):
            m = rows & valid[:, ch]
            if m.any():
                block = out[m, ch]
                out[rows, ch] = out[rows, ch] - np.nanmean(block, axis=0)
    return out


class Fitter:
    """Cross-validated fits of candidates, alone or added to fixed columns, inside their bounds.

    ``candidates``: the effects tried (all by default). ``record``: (n,) record index per window on
    a day of records: the residual and every design are then demeaned per record. ``mapper``: how
    the held-out folds are fitted (``engine.client_mapper`` on Dask; default one after the other).
    """

    def __init__(
        self,
        ctx: Context,
        resid: np.ndarray,
        valid: np.ndarray,
        fold: np.ndarray,
        candidates: tuple[Candidate, ...] = CANDIDATES,
        record: np.ndarray | None = None,
        mapper: Mapper | None = None,
    ) -> None:
        self.mapper = mapper
        self.candidates = candidates
        self.record = record
        if record is not None:
            resid = demean_records(resid, record, valid)
        self.ctx, self.resid, self.valid, self.fold = ctx, resid, valid, fold
        self.grids = {c.name: c.grid_of(ctx) for c in candidates}
        self.designs = {
            c.name: [self._demean(c.design(ctx, g)) for g in self.grids[c.name]] for c in candidates
        }
        spring = next(c for c in CANDIDATES if c.nonlinear)
        self.spring_alts = [(spring_bearings(ch), not ch.endswith("levelled")) for ch in spring.grid]
        s = ctx.surrogate
        z = np.column_stack([np.ones(len(resid)), ctx.x_known, ctx.drivers.dtemp_k])
        if record is not None:  # the same drivers for both channels: demean on windows with both
            both = np.repeat(valid.all(axis=1, keepdims=True), 2, axis=1)
            z = demean_records(np.stack([z, z], axis=1), record, both)[:, 0, :]
        self.spring = SpringModel(s.A, s.u0, s.thermal.get("uniform", np.zeros(2)), z)
        k_low = plausible_range("support_spring")[0]
        self.c_plausible = 1.0 / k_low
        self.c_search = 1.0 / (k_low * SPRING_SEARCH_SHARE)

    def _demean(self, x: np.ndarray) -> np.ndarray:
        return x if self.record is None else demean_records(x, self.record, self.valid)

    def params(self, name: str, beta: np.ndarray, grid_index: int) -> dict[str, Any]:
        """Fitted parameters by name (SI: ``gap.si``)."""
        return si_params(candidate_params(BY_NAME[name], beta, self.grids[name][grid_index]))

    def magnitude(self, name: str, beta: np.ndarray, grid_index: int) -> float | None:
        """Return the fitted value in the vocabulary's magnitude unit (None: not finite; JSON: ``gap.si``)."""
        c = BY_NAME[name]
        if c.magnitude is None:
            return None
        v = c.magnitude(beta, self.grids[name][grid_index])
        return None if not np.isfinite(v) else float(v)

    def cv(self, name: str, fixed: np.ndarray | None = None, bounded: bool = True) -> CvResult:
        """Cross-validate ``name`` (with ``fixed`` (n, 2, q) columns fitted jointly)."""
        c = BY_NAME[name]
        if c.nonlinear:
            c_max = self.c_plausible if bounded else self.c_search
            r, _ = cross_validate_spring(
                self.spring, self.spring_alts, self.resid, self.valid, self.fold, c_max, fixed, self.mapper
            )
            return r
        alts = self.designs[name]
        if fixed is not None:
            alts = [np.concatenate([fixed, x], axis=2) for x in alts]
        bounds = c.plausible_bounds(self.ctx) if bounded else None
        caps = c.alternative_caps(self.ctx) if bounded else None
        return cross_validate(alts, self.resid, self.valid, self.fold, bounds, caps, self.mapper)

    def block(self, name: str, r: CvResult) -> np.ndarray:
        """Design block of a named effect for later joint fits (n, 2, p).

        A linear effect keeps its columns at the chosen grid value (its parameters are refitted
        jointly); the support spring enters as its fitted change with a free scale.
        """
        if BY_NAME[name].nonlinear:
            return np.asarray(r.pred_part)[:, :, None]
        return self.designs[name][r.grid_index]

    def free_fit(self, name: str, fixed: np.ndarray | None = None) -> tuple[np.ndarray, int]:
        """All-data fit without bounds (the spring: down to ``SPRING_SEARCH_SHARE`` of its range).

        Returns the candidate's own parameters and the grid index.
        """
        c = BY_NAME[name]
        if c.nonlinear:
            i, fit = best_spring(self.spring, self.spring_alts, self.resid, self.valid, self.c_search, fixed)
            return fit.c, i
        alts = self.designs[name]
        if c.alternative_caps(self.ctx) is not None:
            # a secant is the FE's response near its own r only: what the data ask for without
            # bounds is the tangent's answer (index 0), as without sweeps
            alts = alts[:1]
        if fixed is not None:
            alts = [np.concatenate([fixed, x], axis=2) for x in alts]
        i, beta, _ = fit_best(alts, self.resid, self.valid)
        return beta[len(beta) - len(c.params) :], i

    def implausible(self, name: str, fixed: np.ndarray | None = None) -> dict[str, Any] | None:
        """Why the data-optimal fit of ``name`` lies outside its plausible range, or None if inside."""
        c = BY_NAME[name]
        beta, i = self.free_fit(name, fixed)
        if c.nonlinear:
            too_soft = beta > self.c_plausible * (1.0 + BOUND_RTOL)
            if not too_soft.any():
                return None
            lo, hi = plausible_range(name)
            ks = [f"{s} {1.0 / b:.3g} N/m" for s, b, t in zip(SUPPORTS, beta, too_soft, strict=True) if t]
            return {
                "params": self.params(name, beta, i),
                "plausible_range": [lo, hi],
                "reason": f"the data ask for a support spring of {', '.join(ks)}, softer than the "
                f"plausible {lo:.3g} N/m",
            }
        bounds = c.plausible_bounds(self.ctx)
        out = []
        for pname, v, (lo, hi) in zip(c.params, beta, bounds, strict=True):
            tol = BOUND_RTOL * max(abs(lo), abs(hi), 1e-300)
            if not (lo - tol <= v <= hi + tol):
                out.append(f"{pname.split(' ')[0]} = {v:.4g} outside [{lo:.4g}, {hi:.4g}]")
        if not out:
            return None
        return {
            "params": self.params(name, beta, i),
            "plausible_range": [list(b) for b in bounds],
            "reason": "the data ask for " + "; ".join(out) + f" ({EFFECTS[name].plausible_source})",
        }
