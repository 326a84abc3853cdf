"""Which effect: candidates ranked by held-out gain, the best one's group, further effects.

``select_effects`` cross-validates every candidate inside its plausible range, rejects those whose
data-optimal fit lies outside it, ranks the rest by held-out improvement against their chance
level for AR(1) noise (``rank``), gives the best one the group of candidates the two reactions
cannot tell apart (``best_group``), and adds further effects by forward selection.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.gap.candidates import Candidate
from bridge_shadow.gap.fit import (
    CvResult,
    ar1_phi,
    chance_threshold,
    chance_threshold_mc,
    cross_validate,
    effective_n,
)
from bridge_shadow.gap.fitter import BY_NAME, Fitter

__all__ = [
    "COLLINEAR_COS",
    "MC_BELOW_N_EFF",
    "Named",
    "Ranking",
    "Selection",
    "beats",
    "best_group",
    "collinearity",
    "forward_selection",
    "own_beta",
    "rank",
    "select_effects",
]

#: Two candidates whose all-data fitted reaction changes have a cosine above this, and of which
#: neither adds a significant held-out gain to the other, are reported as indistinguishable.
COLLINEAR_COS = 0.9


#: Below this effective sample size the chance level of the held-out gain is simulated
#: (``chance_threshold_mc``) instead of taken from its large-sample formula.
MC_BELOW_N_EFF = 100.0


def beats(gain: float, threshold: float) -> bool:
    """Return whether a held-out gain is significant: positive and at least its chance level."""
    return gain > 0.0 and gain >= threshold


def collinearity(a: np.ndarray, b: np.ndarray, valid: np.ndarray) -> float:
    """Absolute cosine between two predictions (n, 2) over the entries with data (``valid``)."""
    ok = valid & np.isfinite(a) & np.isfinite(b)
    na, nb = np.linalg.norm(a[ok]), np.linalg.norm(b[ok])
    return float(abs(np.sum(a[ok] * b[ok])) / (na * nb)) if na > 0 and nb > 0 else 0.0


@dataclass
class Ranking:
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


def rank(fitter: Fitter, cv: dict[str, CvResult], eligible: set[str], z: float) -> Ranking:
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
    return Ranking(
        ranked, eligible, top, phi, n_eff, thr, chance_level, ic, partial, top_given, runner_up, valid
    )


def best_group(rk: Ranking, cv: dict[str, CvResult]) -> list[str]:
    """Return the best effect and those indistinguishable from it (best first); empty for none.

    A plausible candidate joins the top one's group when it also beats its chance level, its
    all-data fit is nearly collinear with the top one's (``COLLINEAR_COS``) and the top one adds no
    significant held-out gain to it. The group is ordered by the information criterion.
    """
    top = rk.top.name
    if top not in rk.eligible or not beats(cv[top].mse_gain, rk.threshold[top]):
        return []
    group = [top] + [
        c.name
        for c in rk.ranked
        if c is not rk.top
        and c.name in rk.eligible
        and beats(cv[c.name].mse_gain, rk.threshold[c.name])
        and collinearity(cv[top].pred_full, cv[c.name].pred_full, rk.valid) >= COLLINEAR_COS
        and rk.top_given[c.name] < rk.threshold[top]
    ]
    return sorted(group, key=lambda name: rk.ic[name])


@dataclass
class Named:
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


def own_beta(name: str, r: CvResult) -> np.ndarray:
    """Return the candidate's own parameters of a fit (a joint fit's last columns)."""
    c = BY_NAME[name]
    return r.beta if c.nonlinear else r.beta[len(r.beta) - len(c.params) :]


def forward_selection(
    fitter: Fitter,
    best: str,
    group: list[str],
    cv: dict[str, CvResult],
    rk: Ranking,
    max_steps: int = 3,
) -> tuple[list[Named], list[dict[str, Any]]]:
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
    out: list[Named] = []
    rejected: list[dict[str, Any]] = []
    blocks = [(best, fixed)]
    final: CvResult | None = None
    for _ in range(max_steps):
        trials = {name: fitter.cv(name, fixed=fixed) for name in remaining}
        gains = {name: float(1.0 - r.sse_after.sum() / sse_now) for name, r in trials.items()}
        chosen = None
        for name in sorted(gains, key=lambda k: -gains[k]):
            if not beats(gains[name], thr[name]):
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
        params = {chosen: fitter.params(chosen, own_beta(chosen, r), r.grid_index)}
        for other in sorted(gains, key=lambda k: -gains[k]):
            if other == chosen or other not in remaining or not beats(gains[other], thr[other]):
                continue
            if fitter.implausible(other, fixed) is not None:
                continue
            # what each adds to the joint prediction (its own part is not identifiable where it is
            # collinear with a fixed block, as a stiffness's u0 change with the offset)
            added, added_other = r.pred_full - pred_now, trials[other].pred_full - pred_now
            if collinearity(added, added_other, fitter.valid) < COLLINEAR_COS:
                continue
            both = np.concatenate([fixed, fitter.block(other, trials[other])], axis=2)
            given = fitter.cv(chosen, fixed=both).sse_after.sum()
            if 1.0 - given / trials[other].sse_after.sum() < thr[chosen]:
                members.append(other)
                t = trials[other]
                params[other] = fitter.params(other, own_beta(other, t), t.grid_index)
        group_cv = {m: trials[m] for m in members}
        out.append(Named(chosen, members, gains[chosen], r, params[chosen], params, None, group_cv))
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
        first = Named(best, group, cv[best].mse_gain, cv[best], {}, {}, contributions[best])
        if not BY_NAME[best].nonlinear:
            # the best one's parameters in the final joint model (alone, they absorb the others)
            p = blocks[0][1].shape[2]
            first.params = fitter.params(best, beta_all[:p], cv[best].grid_index)
        out.insert(0, first)
    return out, rejected


@dataclass
class Selection:
    """What ``select_effects`` found.

    Attributes:
        fitter: the fits it asked. cv: candidate -> its cross-validated fit inside its range.
        why: candidate -> why its data-optimal fit is implausible (None: plausible); for those, the
            rejection entry with its held-out gain if allowed.
        eligible: the plausible candidates. ranking: the ranking (``rank``).
        group: the best effect and those indistinguishable from it (empty: none beats the noise).
        best: the best effect's name or ``"none"``.
        named: the best effect (with its group's fits) followed by the further effects.
        also: the further effects. rejected: the implausible candidates that would have been named.

    """

    fitter: Fitter
    cv: dict[str, CvResult]
    why: dict[str, Any]
    eligible: set[str]
    ranking: Ranking
    group: list[str]
    best: str
    named: list[Named] = field(default_factory=list)
    also: list[Named] = field(default_factory=list)
    rejected: list[dict[str, Any]] = field(default_factory=list)


def select_effects(fitter: Fitter, z: float) -> Selection:
    """Cross-validate, reject the implausible, rank, group, then add further effects by forward selection."""
    candidates = fitter.candidates
    cv = {c.name: fitter.cv(c.name) for c in candidates}
    why: dict[str, Any] = {c.name: fitter.implausible(c.name) for c in candidates}
    eligible = {name for name, reason in why.items() if reason is None}
    rk = rank(fitter, cv, eligible, z)
    group = best_group(rk, cv)
    best = group[0] if group else "none"
    named, rejected_later = forward_selection(fitter, best, group, cv, rk) if group else ([], [])
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
        if beats(free.mse_gain, rk.threshold[c.name]) and free.mse_gain > bar:
            rejected.append(entry)
    rejected += rejected_later

    if group and not named:  # the best one alone
        named = [Named(best, group, cv[best].mse_gain, cv[best], {}, {}, cv[best].pred_full)]
    if named:
        named[0].group_cv = {g: cv[g] for g in group}
    return Selection(fitter, cv, why, eligible, rk, group, best, named, also, rejected)
