"""The sim-to-real gap diagnosis: where the gap lies, which effect causes it, how far it shrinks.

``diagnose(data)`` aggregates the monitoring data to 60 s windows, forms the residual against the
baseline model (``bridge_shadow.effects``: ``u0 + A x_k`` with the known imposed settlement
``x_k``, zero unless given, plus the FE uniform thermal case times the air temperature change),
fits every candidate of the vocabulary with whole-day cross-validation inside its plausible
range, rejects those whose data-optimal fit lies outside that range, ranks the rest by held-out
improvement, adds further effects by forward selection, gives every named effect its group of
candidates the two reactions cannot tell apart, and (with ``shadow=True``) compares the shadow's
posterior settlements before and after adding the named effects to the model. It never reads the
truth twin's ground-truth file.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.effects import EFFECTS, MODEL_FORM_EFFECTS, SETTLEMENT_EFFECTS, plausible_range
from bridge_shadow.gap.candidates import (
    CANDIDATES,
    Candidate,
    Context,
    spring_bearings,
    step_times,
    stiffness_sensitivities,
)
from bridge_shadow.gap.drivers import Drivers, compute_drivers
from bridge_shadow.gap.errors import GapError
from bridge_shadow.gap.fit import (
    CvResult,
    ar1_phi,
    chance_threshold,
    chance_threshold_mc,
    cross_validate,
    effective_n,
    fit_best,
    folds_of,
)
from bridge_shadow.gap.posterior import ModelChange, shadow_posteriors
from bridge_shadow.gap.records import IMPOSED_SD_M, Record, records_of
from bridge_shadow.gap.spring import SpringModel, best_spring, cross_validate_spring
from bridge_shadow.gap.where import where
from bridge_shadow.gap.windows import NS, Windows, aggregate
from bridge_shadow.model.surrogate_file import Surrogate, load_surrogate

if TYPE_CHECKING:  # pragma: no cover - the level analysis is imported when a day of records needs it
    from bridge_shadow.gap.levels import ImposedAnalysis, LevelPair
from bridge_shadow.series import MonitoringData

__all__ = ["COLLINEAR_COS", "Diagnosis", "baseline_residual", "diagnose", "imposed_path"]

#: Two candidates whose all-data fitted reaction changes have a cosine above this, and of which
#: neither adds a significant held-out gain to the other, are reported as indistinguishable.
COLLINEAR_COS = 0.9
#: Below this effective sample size the chance level of the held-out gain is simulated
#: (``chance_threshold_mc``) instead of taken from its large-sample formula.
MC_BELOW_N_EFF = 100.0
#: Minimum number of valid windows (per channel) to diagnose at all.
MIN_WINDOWS = 8
#: Softest support spring searched when checking plausibility, as a share of the plausible low
#: end: a data-optimal spring below the plausible range is found and rejected, not cut off.
SPRING_SEARCH_SHARE = 1e-3
#: Share of the span from the first to the last record below which the windows with data make a
#: day of records (a load-test day: 12-minute records hours apart, 0.12 of the span on 2022-04-11,
#: 0.46 for its first two records alone) rather than a stream with outages (mostly data).
RECORD_COVERAGE = 0.5
#: Relative tolerance on a bound before a fit counts as outside it.
BOUND_RTOL = 1e-6

_BY_NAME = {c.name: c for c in CANDIDATES}


@dataclass
class Diagnosis:
    """Result of ``diagnose``: the JSON-ready summary plus the arrays the report plots.

    Attributes:
        summary: the JSON object of ``bridge-shadow gap --json``.
        windows: the window statistics.
        drivers: the temporal drivers.
        resid: (n, 2) N, window-mean residual against the baseline model.
        fold: (n,) int, cross-validation fold per window (-1: training only).
        cv: candidate name -> its cross-validated fit (inside its plausible range).
        best: the best effect's name or ``"none"``.
        joint_fit: (n, 2) N, all-data fit of the best effect plus those also present (or None).
        surrogate_after: the model with the named model-form effects added (``--out-surrogate``);
            the model in use when none is named.

    """

    summary: dict[str, Any]
    windows: Windows
    drivers: Drivers
    resid: np.ndarray
    fold: np.ndarray
    cv: dict[str, CvResult] = field(default_factory=dict)
    best: str = "none"
    joint_fit: np.ndarray | None = None
    surrogate_after: Surrogate | None = None


def imposed_path(t_ns: np.ndarray, width_s: float, steps: Sequence[tuple[int, float, float]]) -> np.ndarray:
    """Known imposed settlement (n, 2) m at the window centres ``t_ns`` from steps ``(t_ns, dx_s, dx_n)``.

    A window that holds the step gets the share of it after the step.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    half = 0.5 * width_s * NS
    x = np.zeros((len(t), 2))
    for when, dxs, dxn in steps:
        share = np.clip((t + half - int(when)) / (2.0 * half), 0.0, 1.0)
        x += share[:, None] * np.array([dxs, dxn])[None, :]
    return x


def baseline_residual(w: Windows, d: Drivers, s: Surrogate, x_known: np.ndarray | None = None) -> np.ndarray:
    """Window means minus the baseline ``u0 + A x_known + thermal_uniform (T - mean T)``; (n, 2) N."""
    return w.mean_n - Context.build(d, s, {}, x_known).baseline


def _folds(d: Drivers, valid: np.ndarray, holdout_days: Sequence[int] | None) -> tuple[np.ndarray, str]:
    """Folds of the cross-validation: whole days (or blocks), or the days given to hold out."""
    if not holdout_days:
        return folds_of(d.day, valid)
    days = set(np.unique(d.day).tolist())
    bad = [h for h in holdout_days if h not in days]
    if bad:
        raise GapError(f"--holdout-days {bad} not in the record (days 0..{max(days)})")
    hold = np.isin(d.day, list(holdout_days))
    if hold.all():
        raise GapError("--holdout-days leaves no day to fit on")
    return np.where(hold, 0, -1), "holdout"


def _beats(gain: float, threshold: float) -> bool:
    """Return whether a held-out gain is significant: positive and at least its chance level."""
    return gain > 0.0 and gain >= threshold


def _cos(a: np.ndarray, b: np.ndarray, valid: np.ndarray) -> float:
    """Absolute cosine between two predictions (n, 2) over the entries with data (``valid``)."""
    ok = valid & np.isfinite(a) & np.isfinite(b)
    na, nb = np.linalg.norm(a[ok]), np.linalg.norm(b[ok])
    return float(abs(np.sum(a[ok] * b[ok])) / (na * nb)) if na > 0 and nb > 0 else 0.0


def _per_support(x: np.ndarray, total: float | None = None) -> dict[str, float]:
    out = {SUPPORTS[0]: float(x[0]), SUPPORTS[1]: float(x[1])}
    if total is not None:
        out["total"] = float(total)
    return out


def _k_of(c: float) -> float | None:
    """Spring stiffness N/m of a compliance m/N (None: rigid)."""
    return None if c <= 0 else float(1.0 / c)


def _params(c: Candidate, beta: np.ndarray, grid_value: Any) -> dict[str, Any]:
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


class _Fitter:
    """Cross-validated fits of candidates, alone or added to fixed columns, inside their bounds.

    ``candidates``: the effects tried (all by default). ``record``: (n,) record index per window on
    a day of records: the residual and every design are then demeaned per record.
    """

    def __init__(
        self,
        ctx: Context,
        resid: np.ndarray,
        valid: np.ndarray,
        fold: np.ndarray,
        candidates: tuple[Candidate, ...] = CANDIDATES,
        record: np.ndarray | None = None,
    ) -> None:
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
        """Fitted parameters by name (SI)."""
        return _params(_BY_NAME[name], beta, self.grids[name][grid_index])

    def magnitude(self, name: str, beta: np.ndarray, grid_index: int) -> float | None:
        """Return the fitted value in the vocabulary's magnitude unit (None when not finite)."""
        c = _BY_NAME[name]
        if c.magnitude is None:
            return None
        v = c.magnitude(beta, self.grids[name][grid_index])
        return None if not np.isfinite(v) else float(v)

    def cv(self, name: str, fixed: np.ndarray | None = None, bounded: bool = True) -> CvResult:
        """Cross-validate ``name`` (with ``fixed`` (n, 2, q) columns fitted jointly)."""
        c = _BY_NAME[name]
        if c.nonlinear:
            c_max = self.c_plausible if bounded else self.c_search
            r, _ = cross_validate_spring(
                self.spring, self.spring_alts, self.resid, self.valid, self.fold, c_max, fixed
            )
            return r
        alts = self.designs[name]
        if fixed is not None:
            alts = [np.concatenate([fixed, x], axis=2) for x in alts]
        bounds = c.plausible_bounds(self.ctx) if bounded else None
        caps = c.alternative_caps(self.ctx) if bounded else None
        return cross_validate(alts, self.resid, self.valid, self.fold, bounds, caps)

    def block(self, name: str, r: CvResult) -> np.ndarray:
        """Design block of a named effect for later joint fits (n, 2, p).

        A linear effect keeps its columns at the chosen grid value (its parameters are refitted
        jointly); the support spring enters as its fitted change with a free scale.
        """
        if _BY_NAME[name].nonlinear:
            return np.asarray(r.pred_part)[:, :, None]
        return self.designs[name][r.grid_index]

    def free_fit(self, name: str, fixed: np.ndarray | None = None) -> tuple[np.ndarray, int]:
        """All-data fit without bounds (the spring: down to ``SPRING_SEARCH_SHARE`` of its range).

        Returns the candidate's own parameters and the grid index.
        """
        c = _BY_NAME[name]
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
        c = _BY_NAME[name]
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


@dataclass
class _Ranking:
    """Candidates ranked by held-out gain, with the noise level and the partial effects.

    Attributes:
        ranked: candidates, largest held-out gain first (plausible or not).
        eligible: names of the candidates whose data-optimal fit is plausible.
        top: the eligible candidate with the largest held-out gain.
        phi: AR(1) coefficient of what the top candidate leaves.
        n_eff: effective sample size of the record for that noise.
        threshold: candidate -> chance level of its held-out gain.
        chance_level: ``"simulated"`` or ``"large-sample formula"``.
        ic: candidate -> BIC with the AR(1) effective sample size (relative to no effect).
        partial: candidate -> held-out gain when added to the top one (the top one: added to the
            runner-up).
        top_given: candidate -> held-out gain of the top one when added to that candidate.
        runner_up: the candidate the top one's partial effect is given.
        valid: (n, 2) the entries with data.

    """

    ranked: list[Candidate]
    eligible: set[str]
    top: Candidate
    phi: float
    n_eff: float
    threshold: dict[str, float]
    chance_level: str
    ic: dict[str, float]
    partial: dict[str, float]
    top_given: dict[str, float]
    runner_up: Candidate
    valid: np.ndarray


def _rank(fitter: _Fitter, cv: dict[str, CvResult], eligible: set[str], z: float) -> _Ranking:
    """Rank, estimate the noise and the chance levels, and compute the partial effects."""
    resid, valid, fold = fitter.resid, fitter.valid, fitter.fold
    ranked = sorted(fitter.candidates, key=lambda c: -cv[c.name].mse_gain)
    pool = [c for c in ranked if c.name in eligible] or ranked
    top = pool[0]
    n_folds = len(np.unique(fold[fold >= 0]))
    # AR(1) noise from what the top candidate leaves; one effective size for every candidate.
    phi = ar1_phi(resid - cv[top.name].pred_full)
    n_eff = effective_n(int(valid.sum()), phi)
    if n_eff >= MC_BELOW_N_EFF:
        thr = {c.name: chance_threshold(c.n_params, n_eff, n_folds, z) for c in fitter.candidates}
        chance_level = "large-sample formula"
    else:
        # The support spring enters by its linearization at no spring (a bounded, saturating fit
        # of noise gains no more than its linearization does).
        thr = chance_threshold_mc(fitter.designs, valid, fold, phi, record=fitter.record)
        chance_level = "simulated"
    sse0 = float(np.sum(resid[valid] ** 2))
    ic = {
        c.name: float(
            n_eff * np.log(max(cv[c.name].sse_full, 1e-300) / sse0)
            + c.penalty(n_eff, len(fitter.grids[c.name]))
        )
        for c in fitter.candidates
    }
    partial: dict[str, float] = {}
    top_given: dict[str, float] = {}
    top_block = fitter.block(top.name, cv[top.name])
    for c in ranked:
        if c is top:
            continue
        sse_joint = fitter.cv(c.name, fixed=top_block).sse_after.sum()
        partial[c.name] = float(1.0 - sse_joint / cv[top.name].sse_after.sum())
        top_given[c.name] = float(1.0 - sse_joint / cv[c.name].sse_after.sum())
    runner_up = next(c for c in ranked if c is not top)
    partial[top.name] = top_given[runner_up.name]
    return _Ranking(
        ranked, eligible, top, phi, n_eff, thr, chance_level, ic, partial, top_given, runner_up, valid
    )


def _group(rk: _Ranking, cv: dict[str, CvResult]) -> list[str]:
    """Return the best effect and those indistinguishable from it (best first); empty for none.

    A plausible candidate joins the top one's group when it also beats its chance level, its
    all-data fit is nearly collinear with the top one's (``COLLINEAR_COS``) and the top one adds no
    significant held-out gain to it. The group is ordered by the information criterion.
    """
    top = rk.top.name
    if top not in rk.eligible or not _beats(cv[top].mse_gain, rk.threshold[top]):
        return []
    group = [top] + [
        c.name
        for c in rk.ranked
        if c is not rk.top
        and c.name in rk.eligible
        and _beats(cv[c.name].mse_gain, rk.threshold[c.name])
        and _cos(cv[top].pred_full, cv[c.name].pred_full, rk.valid) >= COLLINEAR_COS
        and rk.top_given[c.name] < rk.threshold[top]
    ]
    return sorted(group, key=lambda name: rk.ic[name])


@dataclass
class _Named:
    """One effect named by the forward selection, with its group and all-data joint fit.

    Attributes:
        name: the effect.
        group: the others the data cannot tell from it (in the fit where it was added).
        gain: held-out gain when added (the best one: its own held-out gain).
        cv: its cross-validated fit in the joint model where it was added.
        params: its fitted parameters (the joint all-data fit), by name.
        group_params: member -> its fitted parameters in the same place.
        contribution: (n, 2) N, its all-data contribution in the final joint fit.
        group_cv: member -> its cross-validated fit in the same place.

    """

    name: str
    group: list[str]
    gain: float
    cv: CvResult
    params: dict[str, Any]
    group_params: dict[str, dict[str, Any]]
    contribution: np.ndarray | None = None
    group_cv: dict[str, CvResult] = field(default_factory=dict)


def _own_beta(name: str, r: CvResult) -> np.ndarray:
    c = _BY_NAME[name]
    return r.beta if c.nonlinear else r.beta[len(r.beta) - len(c.params) :]


def _forward_selection(
    fitter: _Fitter,
    best: str,
    group: list[str],
    cv: dict[str, CvResult],
    rk: _Ranking,
    max_steps: int = 3,
) -> tuple[list[_Named], list[dict[str, Any]]]:
    """Further effects present beside the best one: forward selection on the held-out gain.

    From the best effect (its all-data grid value fixed), add at each step the plausible candidate
    whose joint cross-validated fit removes the largest share of what remains, while that share
    beats the candidate's chance level and its joint data-optimal fit stays plausible; members of
    an earlier group are skipped. Each added effect gets its own group: the candidates that remove
    a comparable share there, with a nearly collinear contribution, to which it adds no
    significant gain. Returns the added effects and the candidates rejected on the way as
    implausible.
    """
    thr = rk.threshold
    fixed = fitter.block(best, cv[best])
    # What the best effect leaves with its grid value fixed (as in every joint fit below), so that
    # fixing it is not counted as a gain of the next effect.
    base = cross_validate([fixed], fitter.resid, fitter.valid, fitter.fold)
    sse_now, pred_now = base.sse_after.sum(), base.pred_full
    taken = set(group)
    # Plausibility is judged where an effect is named: here in the joint fit, whatever its fit
    # alone said (alone, a gradient may have to stand in for the offset beside it).
    remaining = [c.name for c in fitter.candidates if c.name not in taken]
    out: list[_Named] = []
    rejected: list[dict[str, Any]] = []
    blocks = [(best, fixed)]
    final: CvResult | None = None
    for _ in range(max_steps):
        trials = {name: fitter.cv(name, fixed=fixed) for name in remaining}
        gains = {name: float(1.0 - r.sse_after.sum() / sse_now) for name, r in trials.items()}
        chosen = None
        for name in sorted(gains, key=lambda k: -gains[k]):
            if not _beats(gains[name], thr[name]):
                break
            why = fitter.implausible(name, fixed)
            if why is None:
                chosen = name
                break
            given = [b for b, _ in blocks]
            rejected.append({"effect": name, "given": given, **why, "heldout_gain_if_allowed": gains[name]})
            remaining.remove(name)
        if chosen is None:
            break
        r = trials[chosen]
        members = [chosen]
        params = {chosen: fitter.params(chosen, _own_beta(chosen, r), r.grid_index)}
        for other in sorted(gains, key=lambda k: -gains[k]):
            if other == chosen or other not in remaining or not _beats(gains[other], thr[other]):
                continue
            if fitter.implausible(other, fixed) is not None:
                continue
            # what each adds to the joint prediction (its own part is not identifiable where it is
            # collinear with a fixed block, as a stiffness's u0 change with the offset)
            if _cos(r.pred_full - pred_now, trials[other].pred_full - pred_now, fitter.valid) < COLLINEAR_COS:
                continue
            both = np.concatenate([fixed, fitter.block(other, trials[other])], axis=2)
            given = fitter.cv(chosen, fixed=both).sse_after.sum()
            if 1.0 - given / trials[other].sse_after.sum() < thr[chosen]:
                members.append(other)
                t = trials[other]
                params[other] = fitter.params(other, _own_beta(other, t), t.grid_index)
        group_cv = {m: trials[m] for m in members}
        out.append(_Named(chosen, members, gains[chosen], r, params[chosen], params, None, group_cv))
        taken.update(members)
        blocks.append((chosen, fitter.block(chosen, r)))
        fixed = np.concatenate([fixed, blocks[-1][1]], axis=2)
        # what the joint model leaves with every grid value fixed (see ``base`` above)
        base = cross_validate([fixed], fitter.resid, fitter.valid, fitter.fold)
        sse_now, pred_now = base.sse_after.sum(), base.pred_full
        final = base  # the joint all-data fit of every block (a spring's own cv holds only its compliances)
        remaining = [n for n in remaining if n not in taken]
    if final is not None:
        k = 0
        beta_all = final.beta
        contributions = {}
        for name, x in blocks:
            p = x.shape[2]
            contributions[name] = x @ beta_all[k : k + p]
            k += p
        for named in out:
            named.contribution = contributions[named.name]
        first = _Named(best, group, cv[best].mse_gain, cv[best], {}, {}, contributions[best])
        if not _BY_NAME[best].nonlinear:
            # the best one's parameters in the final joint model (alone, they absorb the others)
            p = blocks[0][1].shape[2]
            first.params = fitter.params(best, beta_all[:p], cv[best].grid_index)
        out.insert(0, first)
    return out, rejected


def _model_change(entries: list[_Named]) -> ModelChange:
    """Return what the named effects add to the model (not settlements: the shadow estimates them)."""
    change = ModelChange()
    additive = None
    for e in entries:
        if e.name in SETTLEMENT_EFFECTS:
            continue
        change.effects.append(e.name)
        c = _BY_NAME[e.name]
        if c.nonlinear:
            springs = [np.inf if v <= 0 else 1.0 / v for v in e.cv.beta]
            change.springs_n_per_m = (float(springs[0]), float(springs[1]))
            change.springs_levelled = str(c.grid[e.cv.grid_index]).endswith("levelled")
        elif e.name in MODEL_FORM_EFFECTS:
            # the joint fit's own r when the effect was added later, else its own fit
            change.ratios[e.name] = float(_own_beta(e.name, e.cv)[0])
        else:
            contrib = np.nan_to_num(e.contribution if e.contribution is not None else e.cv.pred_full)
            additive = contrib if additive is None else additive + contrib
    change.additive_n = additive
    return change


def _alternatives(fitter: _Fitter, entries: list[_Named], max_runs: int = 2) -> dict[str, ModelChange]:
    """Model changes where a model-form member of a group stands in for the effect named there.

    The data cannot tell such a member from the named effect, but the shadow's settlements differ
    between them (a support spring rescales A): each alternative is refitted beside the other
    named effects (inside its plausible range) and run too.
    """
    out: dict[str, ModelChange] = {}
    for k, e in enumerate(entries):
        for g in e.group[1:]:
            if g not in MODEL_FORM_EFFECTS or g in out or len(out) >= max_runs:
                continue
            others = [fitter.block(o.name, o.cv) for j, o in enumerate(entries) if j != k]
            fixed = np.concatenate(others, axis=2) if others else None
            r = fitter.cv(g, fixed=fixed)
            stand_in = _Named(g, [g], e.gain, r, {}, {}, None)
            out[g] = _model_change([*entries[:k], stand_in, *entries[k + 1 :]])
    return out


def _statement(
    group: list[str],
    also: list[_Named],
    rk: _Ranking,
    cv: dict[str, CvResult],
    rejected: list[dict[str, Any]],
) -> str:
    """One paragraph for people: the answer, its ambiguity, what else is present, what was rejected."""
    top = rk.top.name
    if not group:
        text = (
            f"No candidate beats the noise: the largest plausible held-out gain ({top}, "
            f"{cv[top].mse_gain:.3f} of the squared residual) is below the chance level "
            f"{rk.threshold[top]:.3f} for AR(1) noise with phi = {rk.phi:.2f}."
        )
    else:
        best, others = group[0], group[1:]
        red = cv[best].reduction
        text = (
            f"{best} ({EFFECTS[best].part}) explains the gap: held-out RMS down by "
            f"{100 * red[0]:.0f}% (south) and {100 * red[1]:.0f}% (north)."
        )
        if others:
            text += (
                f" It cannot be told apart from {', '.join(others)} with two reactions alone: their fitted "
                "reaction changes are nearly collinear and neither adds a significant held-out gain to "
                f"the other; {best} is listed first by the information criterion."
            )
        if also:
            listed = []
            for a in also:
                item = f"{a.name} ({100 * a.gain:.0f}% of what remained"
                if len(a.group) > 1:
                    item += f"; cannot be told apart from {', '.join(a.group[1:])}"
                listed.append(item + ")")
            text += f" Also present, each given the ones before: {', '.join(listed)}."
    if rejected:
        names = ", ".join(dict.fromkeys(r["effect"] for r in rejected))
        text += (
            f" Rejected as implausible, though the data would take them: {names} (the fit needs a value "
            "outside the plausible range)."
        )
    return text


def _candidate_json(
    rank: int, c: Candidate, r: CvResult, rk: _Ranking, why: dict[str, Any] | None, fitter: _Fitter
) -> dict[str, Any]:
    """Return the JSON entry of one ranked candidate."""
    with np.errstate(invalid="ignore", divide="ignore"):
        rms_b = np.sqrt(r.sse_before / r.n_heldout)
        rms_a = np.sqrt(r.sse_after / r.n_heldout)
    thr = rk.threshold[c.name]
    given = rk.runner_up.name if c is rk.top else rk.top.name
    plausible = why is None
    entry: dict[str, Any] = {
        "effect": c.name,
        "part": c.part,
        "rank": rank,
        "heldout_reduction": _per_support(r.reduction, r.reduction_total),
        "heldout_rms_before_n": _per_support(rms_b),
        "heldout_rms_after_n": _per_support(rms_a),
        "heldout_gain": r.mse_gain,
        "chance_threshold": thr,
        "significant": bool(plausible and _beats(r.mse_gain, thr)),
        "plausible": plausible,
        "params": fitter.params(c.name, r.beta, r.grid_index),
        "magnitude": {
            "value": fitter.magnitude(c.name, r.beta, r.grid_index),
            "unit": "h" if c.name == "thermal_lag" else EFFECTS[c.name].unit,
        },
        "partial_effect": {
            "given": given,
            "heldout_gain": rk.partial[c.name],
            "significant": bool(plausible and _beats(rk.partial[c.name], thr)),
        },
        "information_criterion": {"bic_ar1": rk.ic[c.name], "n_params": c.n_params},
    }
    if c.nonlinear:
        entry["plausible_range"] = list(plausible_range(c.name))
    else:
        entry["plausible_range"] = [list(b) for b in c.plausible_bounds(fitter.ctx)]
    if why is not None:
        entry["rejected"] = why
    return entry


def _settlement_if_softer(name: str, params: dict[str, Any], s: Surrogate) -> dict[str, Any] | None:
    """Read the same reaction change with support springs at the soft end of their plausible range.

    Without a known settlement, the size of a settlement effect depends on ``A``: a model with a
    spring ``k`` under each bearing reads the reactions ``A x`` as ``x' = A'^-1 A x``.
    """
    from bridge_shadow.model.sensitivities import support_spring_change

    if name == "settlement_offset":
        x = np.array([params["x_south [m]"], params["x_north [m]"]])
        unit = "m"
    elif name == "settlement_step":
        x = np.array([params["dx_south [m]"], params["dx_north [m]"]])
        unit = "m"
    elif name == "settlement_drift":
        x = np.array([params["v_south [m/day]"], params["v_north [m/day]"]])
        unit = "m/day"
    else:
        return None
    k_low = plausible_range("support_spring")[0]
    soft, _ = support_spring_change(s, [k_low, k_low])
    return {
        "as_built": x.tolist(),
        "with_support_springs_n_per_m": k_low,
        "value": np.linalg.solve(soft.A, s.A @ x).tolist(),
        "unit": unit,
        "why": "without a known settlement the reactions fix A x, not x: a softer model reads the same "
        "change as a larger settlement (support_spring at the soft end of its plausible range)",
    }


@dataclass
class _Levels:
    """The level analysis of a day of records (``gap.levels``).

    Attributes:
        records: the records. pairs: the level changes across the gaps and imposed steps.
        notes: pairs that could not be measured. imposed: what explains the imposed steps (None
        without one). steps: the free steps between records. model: the model after the imposed
        analysis (the model in use unless an effect was named there).

    """

    records: list[Record]
    pairs: list[LevelPair]
    notes: list[str]
    imposed: ImposedAnalysis | None
    steps: list[dict[str, Any]]
    model: Surrogate

    def to_dict(self) -> dict[str, Any]:
        """Return the ``levels`` block of the JSON (SI)."""
        return {
            "records": [
                {
                    "index": r.index,
                    "start_ns": r.start_ns,
                    "end_ns": r.end_ns,
                    "windows": r.last - r.first + 1,
                }
                for r in self.records
            ],
            "pairs": [p.to_dict() for p in self.pairs],
            "not_measured": self.notes,
            "imposed": self.imposed.to_dict() if self.imposed is not None else None,
            "steps_between_records": self.steps,
            "model_after": {"A": self.model.A.tolist(), "u0": self.model.u0.tolist()},
        }


def _record_mode(
    d: Drivers, valid: np.ndarray, records: list[Record], holdout_days: Sequence[int] | None
) -> bool:
    """Tell a day of records: under two days with data, two or more records, mostly gaps.

    A stream with an outage is mostly data; a day of records is mostly gaps (RECORD_COVERAGE).
    """
    if holdout_days or len(records) < 2:
        return False
    span = records[-1].last - records[0].first + 1
    covered = sum(r.last - r.first + 1 for r in records)
    return folds_of(d.day, valid)[1] != "day" and covered < RECORD_COVERAGE * span


def _sweeps_of(s: Surrogate, surrogate_path: str | None) -> dict[str, Any]:
    """Return the parameter sweeps of the model in use (its file's ``sweeps`` block, or none)."""
    from bridge_shadow.model.sweeps import read_sweeps

    block = getattr(s, "sweeps", None)
    return read_sweeps(block=block) if isinstance(block, dict) else read_sweeps(surrogate_path)


def _levels(
    data: MonitoringData,
    records: list[Record],
    imposed: Sequence[tuple[int, float, float]],
    imposed_sd_m: float,
    s: Surrogate,
    sens: dict[str, Any],
    surrogate_path: str | None,
) -> _Levels:
    """Read the levels of a day of records: the imposed steps' explanation, the free steps."""
    from bridge_shadow.gap.levels import explain_imposed, free_steps, level_pairs

    pairs, notes = level_pairs(data, records, imposed, imposed_sd_m)
    analysis = None
    model = s
    if any(p.imposed for p in pairs):
        analysis = explain_imposed(pairs, s, _sweeps_of(s, surrogate_path), sens)
        if analysis.named:
            model = analysis.surrogate_after(s)
    return _Levels(records, pairs, notes, analysis, free_steps(pairs, model), model)


def _level_named(lv: _Levels, s: Surrogate) -> list[dict[str, Any]]:
    """List what the levels name: the imposed steps' explanation, then the steps between records."""
    out: list[dict[str, Any]] = []
    an = lv.imposed
    if an is not None and an.named:
        rows = {r["effect"]: r for r in an.table()}
        out.append(
            {
                "effect": an.best,
                "part": EFFECTS[an.best].part,
                "params": rows[an.best]["parameters"],
                "intervals95": rows[an.best]["intervals95"],
                "probability": an.weights[an.best],
                "indistinguishable_from": an.group[1:],
                "group": [{"effect": g, "params": rows[g]["parameters"]} for g in an.group],
                "evidence": "the response to the imposed steps (levels.imposed)",
            }
        )
    steps = [st for st in lv.steps if st["significant"]]
    if steps:
        first = steps[0]
        params = {
            "dx_south [m]": first["x_m"][0],
            "dx_north [m]": first["x_m"][1],
            "at [ns]": first["at_ns"],
            "steps": [{"at [ns]": st["at_ns"], "x_m": st["x_m"], "sigma_m": st["sigma_m"]} for st in steps],
        }
        entry: dict[str, Any] = {
            "effect": "settlement_step",
            "part": EFFECTS["settlement_step"].part,
            "params": params,
            "indistinguishable_from": [],
            "group": [{"effect": "settlement_step", "params": params}],
            "evidence": "the level change between records, read through the model "
            + ("after the imposed analysis" if lv.model is not s else "in use")
            + " (levels.steps_between_records): the steps the shadow estimates",
        }
        if an is None or not an.named:
            entry["size_if_model_softer"] = _settlement_if_softer("settlement_step", params, lv.model)
        out.append(entry)
    return out


def _level_statement(lv: _Levels, named: list[dict[str, Any]], inside: str) -> str:
    """One paragraph for a day of records: the levels, then what happens inside the records."""
    mm = 1e3
    text = f"A day of {len(lv.records)} records."
    an = lv.imposed
    if an is not None:
        rows = {r["effect"]: r for r in an.table()}
        if an.named:
            p = ", ".join(f"{k} {v:.3g}" for k, v in rows[an.best]["parameters"].items())
            text += (
                f" The response to the imposed step(s) is not the model's: {an.best} ({p}) explains it "
                f"(probability {an.weights[an.best]:.2f}; the imposed steps within the jacks' accuracy, "
                f"settlement_step, {rows['settlement_step']['delta_log_evidence']:.1f} in log evidence)."
            )
            if an.group[1:]:
                text += f" It cannot be told apart from {', '.join(an.group[1:])}."
        else:
            text += " The model explains the response to the imposed step(s) within the jacks' accuracy."
    steps = [st for st in lv.steps if st["significant"]]
    if steps:
        sizes = "; ".join(f"{st['x_m'][0] * mm:+.2f} / {st['x_m'][1] * mm:+.2f} mm" for st in steps)
        text += f" Between records the settlements stepped by {sizes} (the steps the shadow estimates)."
    return text + " Inside the records: " + inside


def diagnose(
    data: MonitoringData,
    surrogate: Surrogate | None = None,
    *,
    width_s: float = 60.0,
    holdout_days: Sequence[int] | None = None,
    z: float = 4.0,
    imposed: Sequence[tuple[int, float, float]] = (),
    imposed_sd_m: float = IMPOSED_SD_M,
    shadow: bool = False,
    shadow_config: Any = None,
    alternatives: bool = False,
    surrogate_path: str | None = None,
) -> Diagnosis:
    """Diagnose the sim-to-real gap of a monitoring record (see the module docstring).

    Args:
        data: the monitoring record.
        surrogate: the model as built (default ``config/surrogate.yaml``).
        width_s: window length, s.
        holdout_days: whole days to hold out instead of leave-one-day-out.
        z: chance level in standard deviations of the held-out gain of noise.
        imposed: known imposed settlement steps ``(t_ns, dx_south_m, dx_north_m)`` (for example
            a lowering of the supports): part of the baseline, and what model-form candidates act
            on through ``dA x``.
        imposed_sd_m: the accuracy of an imposed step, 1 sd per bearing, m (the jacks').
        shadow: also run the shadow (as ``replay`` does) before and after adding the named effects
            to the model, for ``posterior``; a few seconds for three days of 60 s windows.
        shadow_config: the shadow's parameters (``gap.posterior.shadow_config()`` by default).
        alternatives: with ``shadow``, also run the shadow with each model-form effect that the
            data cannot tell from a named one standing in for it (``posterior.alternatives``).
        surrogate_path: the file ``surrogate`` came from, whose ``sensitivities`` and ``sweeps``
            blocks are read (default ``config/surrogate.yaml``).

    """
    t0 = time.perf_counter()
    s = surrogate if surrogate is not None else load_surrogate()
    w = aggregate(data, width_s)
    d = compute_drivers(w)
    sens = stiffness_sensitivities(s, surrogate_path)
    records = records_of(w.t_ns, w.valid, width_s)
    lv = None
    if _record_mode(d, w.valid, records, holdout_days):
        lv = _levels(data, records, imposed, imposed_sd_m, s, sens, surrogate_path)
    model = lv.model if lv is not None else s
    x_known = imposed_path(w.t_ns, width_s, imposed)
    ctx = Context.build(d, model, sens, x_known, w.t_ns, width_s)
    if model is s:  # the sweeps are of the model in use (on a day of records the levels own them)
        ctx.sweeps = _sweeps_of(s, surrogate_path)
    resid = w.mean_n - ctx.baseline
    valid = np.isfinite(resid)
    ctx.step_times = step_times(w.t_ns, resid, valid, width_s)
    if valid.sum(axis=0).min() < MIN_WINDOWS:
        have = int(valid.sum(axis=0).min())
        raise GapError(f"only {have} windows of {width_s:g} s with data; need {MIN_WINDOWS}")
    record = None
    candidates = CANDIDATES
    if lv is not None:
        # a day of records: each record a fold, its level the levels' business (demeaned)
        record = np.full(len(w), -1)
        for r in records:
            record[r.first : r.last + 1] = r.index
        fold, cv_kind = record.copy(), "record"
        levels_own = (*SETTLEMENT_EFFECTS, *MODEL_FORM_EFFECTS)
        candidates = tuple(c for c in CANDIDATES if c.name not in levels_own)
    else:
        fold, cv_kind = _folds(d, valid, holdout_days)
    n_folds = len(np.unique(fold[fold >= 0]))
    if n_folds < 1:
        raise GapError("not enough data for a held-out check")

    # Which effect: every candidate cross-validated inside its plausible range; a candidate whose
    # data-optimal fit lies outside it is rejected; the rest ranked, grouped, then further effects.
    fitter = _Fitter(ctx, resid, valid, fold, candidates, record)
    cv = {c.name: fitter.cv(c.name) for c in candidates}
    why = {c.name: fitter.implausible(c.name) for c in candidates}
    eligible = {name for name, reason in why.items() if reason is None}
    rk = _rank(fitter, cv, eligible, z)
    group = _group(rk, cv)
    best = group[0] if group else "none"
    named, rejected_later = _forward_selection(fitter, best, group, cv, rk) if group else ([], [])
    also = named[1:]

    # Rejected where they would have been named: alone, a candidate whose unbounded fit would have
    # beaten the best plausible one; in the forward selection, one that would have been added.
    rejected = []
    bar = max(cv[rk.top.name].mse_gain, 0.0) if group else 0.0
    for c in candidates:
        if why[c.name] is None:
            continue
        free = fitter.cv(c.name, bounded=False)
        entry = {"effect": c.name, "given": [], **why[c.name], "heldout_gain_if_allowed": free.mse_gain}
        why[c.name] = entry
        if _beats(free.mse_gain, rk.threshold[c.name]) and free.mse_gain > bar:
            rejected.append(entry)
    rejected += rejected_later

    # How far: the shadow's posterior before and after adding the named effects to the model.
    post: dict[str, Any] = {"computed": False, "why": "run with shadow=True (the CLI always does)"}
    if group and not named:  # the best one alone
        named = [_Named(best, group, cv[best].mse_gain, cv[best], {}, {}, cv[best].pred_full)]
    if named:
        named[0].group_cv = {g: cv[g] for g in group}
    change = _model_change(named)
    if lv is not None and lv.model is not s:
        change.replaced = lv.model
        change.effects.insert(0, lv.imposed.best if lv.imposed is not None else "model")
    after_model = change.surrogate(s, sens)
    if shadow:
        from bridge_shadow.gap.posterior import shadow_config as default_config

        cfg = shadow_config if shadow_config is not None else default_config()
        alts = _alternatives(fitter, named) if alternatives else None
        if alternatives and lv is not None and lv.imposed is not None and lv.imposed.named:
            # the imposed steps' group: each member standing in for the named stiffness
            for g in lv.imposed.group[1:]:
                alt = ModelChange([g, *change.effects[1:]], dict(change.ratios), change.springs_n_per_m)
                alt.springs_levelled, alt.additive_n = change.springs_levelled, change.additive_n
                alt.replaced = lv.imposed.surrogate_after(s, g)
                alts = {**(alts or {}), g: alt}
        post = shadow_posteriors(data, s, cfg, change, w.t_ns, sens, alts)
        post["computed"] = True

    # Where: the residual's breakdown, plus the model part of the held-out gains.
    parts: dict[str, float] = {}
    for c in candidates:
        gain = cv[c.name].mse_gain if c.name in eligible else 0.0
        parts[c.part] = max(parts.get(c.part, 0.0), max(0.0, gain))
    where_json = where(w, d, resid)

    top_pred = cv[rk.top.name].pred_full
    candidates_json = []
    for rank, c in enumerate(rk.ranked, start=1):
        entry = _candidate_json(rank, c, cv[c.name], rk, why[c.name], fitter)
        entry["collinearity_with_top"] = _cos(top_pred, cv[c.name].pred_full, valid)
        candidates_json.append(entry)
    by_cand = {e["effect"]: e for e in candidates_json}

    def named_json(e: _Named, first: bool) -> dict[str, Any]:
        params = (e.params or by_cand[e.name]["params"]) if first else e.params
        out: dict[str, Any] = {
            "effect": e.name,
            "part": EFFECTS[e.name].part,
            "params": params,
            "indistinguishable_from": e.group[1:],
            "group": [
                {"effect": g, "params": by_cand[g]["params"] if first else e.group_params.get(g, {})}
                for g in e.group
            ],
        }
        if e.name in SETTLEMENT_EFFECTS and not len(imposed):
            out["size_if_model_softer"] = _settlement_if_softer(e.name, params, s)
        return out

    best_json = named_json(named[0], True) if group else None
    if best_json is not None and also:
        best_json["params_alone"] = by_cand[best]["params"]
    also_json = []
    for a in also:
        entry = named_json(a, False)
        entry["partial_heldout_gain"] = a.gain
        entry["cumulative_heldout_reduction"] = _per_support(a.cv.reduction, a.cv.reduction_total)
        also_json.append(entry)
    statement = _statement(group, also, rk, cv, rejected)
    indistinguishable = group[1:]

    if lv is not None:  # the levels come first on a day of records
        level_named = _level_named(lv, s)
        if level_named:
            inside = ([best_json] if best_json is not None else []) + also_json
            best_json, also_json = level_named[0], level_named[1:] + inside
            best, indistinguishable = best_json["effect"], best_json["indistinguishable_from"]
        statement = _level_statement(lv, level_named, statement)
    where_json["model_part"] = {
        "heldout_gain_by_part": parts,
        "part": EFFECTS[best].part if best != "none" else "none",
    }

    summary: dict[str, Any] = {
        "best": best,
        "indistinguishable_from": indistinguishable,
        "best_effect": best_json,
        "also_present": also_json,
        "rejected_implausible": rejected,
        "statement": statement,
        "where": where_json,
        "candidates": candidates_json,
        "posterior": post,
        "noise": {
            "ar1_phi": rk.phi,
            "n_windows": int(valid.sum()),
            "n_eff": rk.n_eff,
            "z": z,
            "chance_level": rk.chance_level,
        },
        "validation": {
            "kind": cv_kind,
            "folds": n_folds,
            **(
                {
                    "note": "a day of records: each record is held out in turn for the variation inside "
                    "the records (levels demeaned; the settlement and model-form effects, which act on "
                    "the levels, are left to `levels`, where the records' levels are read pair by pair)"
                }
                if lv is not None
                else {}
            ),
        },
        "levels": lv.to_dict() if lv is not None else None,
        "baseline": {
            "model": "u0 + A x_imposed + thermal['uniform'] * (T_air - mean T_air)",
            "imposed": [
                {"t_ns": int(t), "settlement_m": [float(a), float(b)]} for t, a, b in imposed
            ],
            "imposed_sd_m": imposed_sd_m,
            "air_temperature": "present" if d.has_temperature else "missing: temperature drivers are zero",
            "surrogate": str(s.provenance.get("solver", "")),
            "sensitivities": {k: v.source for k, v in sens.items()},
        },
        "windows": {
            "width_s": width_s,
            "count": len(w),
            "start_ns": int(w.t_ns[0]),
            "end_ns": int(w.t_ns[-1]),
        },
        "seconds": time.perf_counter() - t0,
    }
    joint = None
    if also:
        joint = sum(np.nan_to_num(e.contribution) for e in named if e.contribution is not None)
    return Diagnosis(summary, w, d, resid, fold, cv, best, joint, after_model)
