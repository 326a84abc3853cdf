"""The sim-to-real gap diagnosis: where the gap lies, which effect causes it, how far it shrinks.

``diagnose(data)`` aggregates the monitoring data to 60 s windows, forms the residual against the
baseline model (``bridge_shadow.effects``: ``u0`` plus the FE uniform thermal case times the air
temperature change), fits every candidate of the vocabulary with whole-day cross-validation, ranks
them by held-out improvement, groups candidates the two reactions cannot tell apart, and compares
the shadow's posterior settlements before and after adding the best effect. It never reads the
truth twin's ground-truth file.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.effects import EFFECTS
from bridge_shadow.gap.candidates import CANDIDATES, Candidate, Context, stiffness_sensitivities
from bridge_shadow.gap.drivers import Drivers, compute_drivers
from bridge_shadow.gap.errors import GapError
from bridge_shadow.gap.fit import (
    CvResult,
    ar1_phi,
    chance_threshold,
    chance_threshold_mc,
    cross_validate,
    effective_n,
    folds_of,
)
from bridge_shadow.gap.posterior import posterior, replay_posterior
from bridge_shadow.gap.where import where
from bridge_shadow.gap.windows import Windows, aggregate
from bridge_shadow.model.surrogate_file import Surrogate, load_surrogate
from bridge_shadow.series import MonitoringData

__all__ = ["COLLINEAR_COS", "Diagnosis", "baseline_residual", "diagnose"]

#: Two candidates whose all-data fitted reaction changes have a cosine above this, and of which
#: neither adds a significant held-out gain to the other, are reported as indistinguishable.
COLLINEAR_COS = 0.9
#: Below this effective sample size the chance level of the held-out gain is simulated
#: (``chance_threshold_mc``) instead of taken from its large-sample formula.
MC_BELOW_N_EFF = 100.0
#: Minimum number of valid windows (per channel) to diagnose at all.
MIN_WINDOWS = 8


@dataclass
class Diagnosis:
    """Result of ``diagnose``: the JSON-ready summary plus the arrays the report plots.

    Attributes:
        summary: the JSON object of ``bridge-shadow gap --json``.
        windows: the window statistics.
        drivers: the temporal drivers.
        resid: (n, 2) N, window-mean residual against the baseline model.
        fold: (n,) int, cross-validation fold per window (-1: training only).
        cv: candidate name -> its cross-validated fit.
        best: the best effect's name or ``"none"``.
        joint_fit: (n, 2) N, all-data fit of the best effect plus those also present (or None).

    """

    summary: dict[str, Any]
    windows: Windows
    drivers: Drivers
    resid: np.ndarray
    fold: np.ndarray
    cv: dict[str, CvResult] = field(default_factory=dict)
    best: str = "none"
    joint_fit: np.ndarray | None = None


def baseline_residual(w: Windows, d: Drivers, s: Surrogate) -> np.ndarray:
    """Window means minus the baseline ``u0 + thermal_uniform (T - mean T)``; (n, 2) N."""
    uniform = s.thermal.get("uniform", np.zeros(2))
    return w.mean_n - (s.u0[None, :] + d.dtemp_k[:, None] * uniform[None, :])


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


def _cos(a: np.ndarray, b: np.ndarray) -> float:
    """Absolute cosine between two predictions (n, 2) over the entries finite in both."""
    ok = np.isfinite(a) & np.isfinite(b)
    na, nb = np.linalg.norm(a[ok]), np.linalg.norm(b[ok])
    return float(abs(np.sum(a[ok] * b[ok])) / (na * nb)) if na > 0 and nb > 0 else 0.0


def _per_support(x: np.ndarray, total: float | None = None) -> dict[str, float]:
    out = {SUPPORTS[0]: float(x[0]), SUPPORTS[1]: float(x[1])}
    if total is not None:
        out["total"] = float(total)
    return out


def _params(c: Candidate, r: CvResult) -> dict[str, Any]:
    out: dict[str, Any] = {name: float(v) for name, v in zip(c.params, r.beta, strict=True)}
    if c.grid_name is not None:
        out[c.grid_name] = c.grid[r.grid_index]
    return out


def _forward_selection(
    best: str,
    group: list[str],
    designs: dict[str, list[np.ndarray]],
    cv: dict[str, CvResult],
    resid: np.ndarray,
    valid: np.ndarray,
    fold: np.ndarray,
    thr: dict[str, float],
    max_steps: int = 3,
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    """Further effects present beside the best one: forward selection on the held-out gain.

    From the best effect (its all-data grid value fixed), add at each step the candidate whose
    joint cross-validated fit removes the largest share of what remains, while that share beats
    the candidate's chance level; members of the best one's indistinguishable group are skipped.
    Returns the added effects and the all-data contribution (n, 2) N of each effect of the joint
    model (empty when nothing was added).
    """
    by_name = {c.name: c for c in CANDIDATES}
    fixed = designs[best][cv[best].grid_index]
    sse_now = cv[best].sse_after.sum()
    remaining = [c.name for c in CANDIDATES if c.name not in group]
    out: list[dict[str, Any]] = []
    blocks = [(best, fixed)]
    beta_all = cv[best].beta
    for _ in range(max_steps):
        trials = {}
        for name in remaining:
            joint = [np.concatenate([fixed, x], axis=2) for x in designs[name]]
            trials[name] = cross_validate(joint, resid, valid, fold)
        if not trials:
            break
        name = max(trials, key=lambda k: -trials[k].sse_after.sum())
        r = trials[name]
        gain = float(1.0 - r.sse_after.sum() / sse_now)
        if gain < thr[name]:
            break
        c = by_name[name]
        p = len(c.params)
        beta = r.beta[-p:]
        params: dict[str, Any] = {k: float(v) for k, v in zip(c.params, beta, strict=True)}
        if c.grid_name is not None:
            params[c.grid_name] = c.grid[r.grid_index]
        out.append(
            {
                "effect": name,
                "part": c.part,
                "partial_heldout_gain": gain,
                "params": params,
                "cumulative_heldout_reduction": _per_support(r.reduction, r.reduction_total),
            }
        )
        blocks.append((name, designs[name][r.grid_index]))
        beta_all = r.beta
        fixed = np.concatenate([fixed, designs[name][r.grid_index]], axis=2)
        sse_now = r.sse_after.sum()
        remaining.remove(name)
    if not out:
        return out, {}
    contributions, k = {}, 0
    for name, x in blocks:
        p = x.shape[2]
        contributions[name] = x @ beta_all[k : k + p]
        k += p
    return out, contributions


@dataclass
class _Ranking:
    """Candidates ranked by held-out gain, with the noise level and the partial effects.

    Attributes:
        ranked: candidates, largest held-out gain first.
        phi: AR(1) coefficient of what the top candidate leaves.
        n_eff: effective sample size of the record for that noise.
        threshold: candidate -> chance level of its held-out gain.
        chance_level: ``"simulated"`` or ``"large-sample formula"``.
        ic: candidate -> BIC with the AR(1) effective sample size (relative to no effect).
        partial: candidate -> held-out gain when added to the top one (the top one: added to the
            runner-up).
        top_given: candidate -> held-out gain of the top one when added to that candidate.

    """

    ranked: list[Candidate]
    phi: float
    n_eff: float
    threshold: dict[str, float]
    chance_level: str
    ic: dict[str, float]
    partial: dict[str, float]
    top_given: dict[str, float]

    @property
    def top(self) -> Candidate:
        """The candidate with the largest held-out gain."""
        return self.ranked[0]

    @property
    def runner_up(self) -> Candidate:
        """The second candidate."""
        return self.ranked[1]


def _rank(
    designs: dict[str, list[np.ndarray]],
    cv: dict[str, CvResult],
    resid: np.ndarray,
    valid: np.ndarray,
    fold: np.ndarray,
    z: float,
) -> _Ranking:
    """Rank, estimate the noise and the chance levels, and compute the partial effects."""
    ranked = sorted(CANDIDATES, key=lambda c: -cv[c.name].mse_gain)
    top = ranked[0]
    n_folds = len(np.unique(fold[fold >= 0]))
    # AR(1) noise from what the top candidate leaves; one effective size for every candidate.
    phi = ar1_phi(resid - cv[top.name].pred_full)
    n_eff = effective_n(int(valid.sum()), phi)
    if n_eff >= MC_BELOW_N_EFF:
        thr = {c.name: chance_threshold(c.n_params, n_eff, n_folds, z) for c in CANDIDATES}
        chance_level = "large-sample formula"
    else:
        thr = chance_threshold_mc(designs, valid, fold, phi)
        chance_level = "simulated"
    sse0 = float(np.sum(resid[valid] ** 2))
    ic = {
        c.name: float(n_eff * np.log(max(cv[c.name].sse_full, 1e-300) / sse0) + c.penalty(n_eff))
        for c in CANDIDATES
    }
    partial: dict[str, float] = {}
    top_given: dict[str, float] = {}
    top_design = designs[top.name][cv[top.name].grid_index]
    for c in ranked[1:]:
        joint = [np.concatenate([top_design, x], axis=2) for x in designs[c.name]]
        sse_joint = cross_validate(joint, resid, valid, fold).sse_after.sum()
        partial[c.name] = float(1.0 - sse_joint / cv[top.name].sse_after.sum())
        top_given[c.name] = float(1.0 - sse_joint / cv[c.name].sse_after.sum())
    partial[top.name] = top_given[ranked[1].name]
    return _Ranking(ranked, phi, n_eff, thr, chance_level, ic, partial, top_given)


def _group(rk: _Ranking, cv: dict[str, CvResult]) -> list[str]:
    """Return the best effect and those indistinguishable from it (best first); empty for none.

    A candidate joins the top one's group when it also beats its chance level, its all-data fit is
    nearly collinear with the top one's (``COLLINEAR_COS``) and the top one adds no significant
    held-out gain to it. The group is ordered by the information criterion.
    """
    top = rk.top.name
    if cv[top].mse_gain < rk.threshold[top]:
        return []
    group = [top] + [
        c.name
        for c in rk.ranked[1:]
        if cv[c.name].mse_gain >= rk.threshold[c.name]
        and _cos(cv[top].pred_full, cv[c.name].pred_full) >= COLLINEAR_COS
        and rk.top_given[c.name] < rk.threshold[top]
    ]
    return sorted(group, key=lambda name: rk.ic[name])


def _statement(group: list[str], also: list[dict[str, Any]], rk: _Ranking, cv: dict[str, CvResult]) -> str:
    """One paragraph for people: the answer, its ambiguity, and what else is present."""
    top = rk.top.name
    if not group:
        return (
            f"No candidate beats the noise: the largest held-out gain ({top}, "
            f"{cv[top].mse_gain:.3f} of the squared residual) is below the chance level "
            f"{rk.threshold[top]:.3f} for AR(1) noise with phi = {rk.phi:.2f}."
        )
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
        listed = ", ".join(
            f"{a['effect']} ({100 * a['partial_heldout_gain']:.0f}% of what remained)" for a in also
        )
        text += f" Also present, each given the ones before: {listed}."
    return text


def _candidate_json(rank: int, c: Candidate, r: CvResult, rk: _Ranking) -> dict[str, Any]:
    """Return the JSON entry of one ranked candidate."""
    with np.errstate(invalid="ignore", divide="ignore"):
        rms_b = np.sqrt(r.sse_before / r.n_heldout)
        rms_a = np.sqrt(r.sse_after / r.n_heldout)
    thr = rk.threshold[c.name]
    return {
        "effect": c.name,
        "part": c.part,
        "rank": rank,
        "heldout_reduction": _per_support(r.reduction, r.reduction_total),
        "heldout_rms_before_n": _per_support(rms_b),
        "heldout_rms_after_n": _per_support(rms_a),
        "heldout_gain": r.mse_gain,
        "chance_threshold": thr,
        "significant": bool(r.mse_gain >= thr),
        "params": _params(c, r),
        "magnitude": {
            "value": c.magnitude(r.beta, c.grid[r.grid_index]) if c.magnitude else None,
            "unit": "h" if c.name == "thermal_lag" else EFFECTS[c.name].unit,
        },
        "partial_effect": {
            "given": rk.runner_up.name if c is rk.top else rk.top.name,
            "heldout_gain": rk.partial[c.name],
            "significant": bool(rk.partial[c.name] >= thr),
        },
        "information_criterion": {"bic_ar1": rk.ic[c.name], "n_params": c.n_params},
    }


def diagnose(
    data: MonitoringData,
    surrogate: Surrogate | None = None,
    *,
    width_s: float = 60.0,
    holdout_days: Sequence[int] | None = None,
    z: float = 4.0,
    replay: bool = False,
) -> Diagnosis:
    """Diagnose the sim-to-real gap of a monitoring record (see the module docstring).

    ``replay`` also replays the whole online shadow before and after adding the best effect
    (slower: the shadow handles a few thousand messages per second).
    """
    t0 = time.perf_counter()
    s = surrogate if surrogate is not None else load_surrogate()
    w = aggregate(data, width_s)
    d = compute_drivers(w)
    resid = baseline_residual(w, d, s)
    valid = np.isfinite(resid)
    if valid.sum(axis=0).min() < MIN_WINDOWS:
        have = int(valid.sum(axis=0).min())
        raise GapError(f"only {have} windows of {width_s:g} s with data; need {MIN_WINDOWS}")
    fold, cv_kind = _folds(d, valid, holdout_days)
    n_folds = len(np.unique(fold[fold >= 0]))
    if n_folds < 1:
        raise GapError("not enough data for a held-out check")

    # Which effect: every candidate cross-validated, ranked, grouped, then further effects.
    ctx = Context(d, s, stiffness_sensitivities(s))
    designs = {c.name: [c.design(ctx, g) for g in c.grid] for c in CANDIDATES}
    cv = {c.name: cross_validate(designs[c.name], resid, valid, fold) for c in CANDIDATES}
    rk = _rank(designs, cv, resid, valid, fold, z)
    group = _group(rk, cv)
    best = group[0] if group else "none"
    also, contributions = (
        _forward_selection(best, group, designs, cv, resid, valid, fold, rk.threshold) if group else ([], {})
    )

    # How far: the shadow's posterior before and after adding the effect(s) to the model.
    contribution = np.nan_to_num(cv[best].pred_full) if group else np.zeros_like(resid)
    post_before = posterior(w.mean_n, d.dtemp_k, s)
    post_after = posterior(w.mean_n - contribution, d.dtemp_k, s)
    post: dict[str, Any] = {
        "before": post_before,
        "after": post_after,
        "change_m": (np.array(post_after["mean_m"]) - np.array(post_before["mean_m"])).tolist(),
        "method": "shadow batch update (estimate.kalman.batch_posterior) on the window means",
    }
    if contributions:
        # Every effect found except settlements goes into the model; settlements stay the shadow's.
        added = [k for k in contributions if k not in ("settlement_offset", "settlement_drift")]
        total = sum((np.nan_to_num(contributions[k]) for k in added), np.zeros_like(resid))
        post["after_all_but_settlement"] = {
            **posterior(w.mean_n - total, d.dtemp_k, s),
            "effects_added": added,
        }
    if replay:
        per_window = int(np.median(w.count[w.count.min(axis=1) > 0].min(axis=1)))
        post["shadow_replay"] = replay_posterior(data, s, w.t_ns, contribution, min(10, per_window))

    # Where: the residual's breakdown, plus the model part of the held-out gains.
    parts: dict[str, float] = {}
    for c in CANDIDATES:
        parts[c.part] = max(parts.get(c.part, 0.0), max(0.0, cv[c.name].mse_gain))
    where_json = where(w, d, resid)
    where_json["model_part"] = {
        "heldout_gain_by_part": parts,
        "part": EFFECTS[best].part if group else "none",
    }

    top_pred = cv[rk.top.name].pred_full
    candidates_json = []
    for rank, c in enumerate(rk.ranked, start=1):
        entry = _candidate_json(rank, c, cv[c.name], rk)
        entry["collinearity_with_top"] = _cos(top_pred, cv[c.name].pred_full)
        candidates_json.append(entry)
    summary: dict[str, Any] = {
        "best": best,
        "indistinguishable_from": group[1:],
        "also_present": also,
        "statement": _statement(group, also, rk, cv),
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
        "validation": {"kind": cv_kind, "folds": n_folds},
        "baseline": {
            "model": "u0 + thermal['uniform'] * (T_air - mean T_air)",
            "air_temperature": "present" if d.has_temperature else "missing: temperature drivers are zero",
            "surrogate": str(s.provenance.get("solver", "")),
            "sensitivities": ctx.sensitivities["bearing_stiffness"].source,
        },
        "windows": {
            "width_s": width_s,
            "count": len(w),
            "start_ns": int(w.t_ns[0]),
            "end_ns": int(w.t_ns[-1]),
        },
        "seconds": time.perf_counter() - t0,
    }
    joint = sum(contributions.values()) if contributions else None
    return Diagnosis(summary, w, d, resid, fold, cv, best, joint)
