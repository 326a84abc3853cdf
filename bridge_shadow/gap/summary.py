"""The JSON summary of a diagnosis (``bridge-shadow gap --json``): candidates, named effects, levels.

``gap_summary`` assembles it from the residual (``gap.residual``), the selection (``gap.rank``)
and the shadow's posterior; the Markdown report with plots is ``gap.report``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.effects import EFFECTS, SETTLEMENT_EFFECTS, plausible_range
from bridge_shadow.gap.candidates import Candidate
from bridge_shadow.gap.day_levels import DayLevels
from bridge_shadow.gap.explain import level_statement, settlement_if_softer, statement
from bridge_shadow.gap.fit import CvResult
from bridge_shadow.gap.fitter import Fitter
from bridge_shadow.gap.rank import Named, Ranking, Selection, beats, collinearity
from bridge_shadow.gap.residual import Residual
from bridge_shadow.gap.si import si_unit_value
from bridge_shadow.gap.where import where
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = ["candidate_json", "gap_summary", "level_named", "named_json", "per_support"]


def per_support(x: np.ndarray, total: float | None = None) -> dict[str, float]:
    """Return ``x`` (2,) by support name, with ``total`` when given."""
    out = {SUPPORTS[0]: float(x[0]), SUPPORTS[1]: float(x[1])}
    if total is not None:
        out["total"] = float(total)
    return out


def candidate_json(
    rank: int, c: Candidate, r: CvResult, rk: Ranking, why: dict[str, Any] | None, fitter: Fitter
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
        "heldout_reduction": per_support(r.reduction, r.reduction_total),
        "heldout_rms_before_n": per_support(rms_b),
        "heldout_rms_after_n": per_support(rms_a),
        "heldout_gain": r.mse_gain,
        "chance_threshold": thr,
        "significant": bool(plausible and beats(r.mse_gain, thr)),
        "plausible": plausible,
        "params": fitter.params(c.name, r.beta, r.grid_index),
        "magnitude": _magnitude(c, fitter.magnitude(c.name, r.beta, r.grid_index)),
        "partial_effect": {
            "given": given,
            "heldout_gain": rk.partial[c.name],
            "significant": bool(plausible and beats(rk.partial[c.name], thr)),
        },
        "information_criterion": {"bic_ar1": rk.ic[c.name], "n_params": c.n_params},
    }
    if c.nonlinear:
        entry["plausible_range"] = list(plausible_range(c.name))
    else:
        units = [name.partition(" [")[2].rstrip("]") for name in c.params]
        entry["plausible_range"] = [
            si_unit_value(u, list(b))[1] for u, b in zip(units, c.plausible_bounds(fitter.ctx), strict=True)
        ]
    if why is not None:
        entry["rejected"] = why
    return entry


def _magnitude(c: Candidate, value: float | None) -> dict[str, Any]:
    """Return the magnitude's JSON (SI: ``gap.si``; a lag's is its time constant, in hours in the fit)."""
    given = c.magnitude_unit or ("h" if c.name == "thermal_lag" else EFFECTS[c.name].unit)
    unit, si_value = si_unit_value(given, value)
    return {"value": si_value, "unit": unit}


def named_json(
    e: Named, first: bool, by_cand: dict[str, dict[str, Any]], imposed: Sequence[Any], s: Surrogate
) -> dict[str, Any]:
    """Return the JSON entry of a named effect (``first``: the best one, its parameters from the ranking)."""
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
        out["size_if_model_softer"] = settlement_if_softer(e.name, params, s)
    return out


#: Said of the posterior after a named explanation that does not fit the imposed steps.
NOT_FITTING = "{effect} does not fit the imposed steps (see warnings): not a corrected model"


def _flag_misfit(lv: DayLevels, best_json: dict[str, Any] | None, post: dict[str, Any]) -> None:
    """Mark the named explanation and the posterior after it when the imposed steps' fit fails.

    The probabilities rank the explanations against each other; the best of those that all need
    the jacks far off (a step given with the wrong sign) is no answer, so the JSON's ``best_effect``
    (``fits_imposed_steps``) and the posterior after say so where they are read, not only in the
    warnings.
    """
    an = lv.imposed
    if an is None or not an.named or best_json is None or best_json.get("effect") != an.best:
        return
    fits = an.misfit() is None
    best_json["fits_imposed_steps"] = fits
    after = post.get("after") if post.get("computed") else None
    if not fits and after is not None and an.best in after.get("effects_added", []):
        after["what"] = f"{after['what']}; {NOT_FITTING.format(effect=an.best)}"


def gap_warnings(lv: DayLevels | None, post: dict[str, Any]) -> list[str]:
    """Return what must not pass silently, said on stderr (WARN) and in the JSON's ``warnings``.

    The levels' (a record left out for a silent channel, an imposed step not used, an explanation
    that needs the jacks far off), and the shadow's own lines on a silent channel in ``before``:
    the level pairs skipped such a record without a word, read an imposed step across it, and
    named a stiffness the model did not need.
    """
    from bridge_shadow.gap.explain import misfit_text

    out = lv.warnings() if lv is not None else []
    misfit = lv.imposed.misfit() if lv is not None and lv.imposed is not None else None
    if misfit is not None:  # the best explanation needs the jacks far off: a model from it rests on nothing
        out.append(misfit_text(misfit))
    before = (post.get("before") or {}).get("warnings", [])
    out += [f"the shadow (before): {w}" for w in before if w.startswith("topic ")]
    return out


def level_named(lv: DayLevels, s: Surrogate) -> list[dict[str, Any]]:
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
            entry["size_if_model_softer"] = settlement_if_softer("settlement_step", params, lv.model)
        out.append(entry)
    return out


def gap_summary(
    r: Residual,
    sel: Selection,
    post: dict[str, Any],
    s: Surrogate,
    imposed: Sequence[tuple[int, float, float]],
    imposed_sd_m: float,
    z: float,
    width_s: float,
    t0: float,
) -> dict[str, Any]:
    """Return the JSON summary (``t0``: ``time.perf_counter()`` at the start, for ``seconds``)."""
    w, d, resid, valid, lv = r.windows, r.drivers, r.resid, r.valid, r.levels
    cv, rk, why, group, also, best = sel.cv, sel.ranking, sel.why, sel.group, sel.also, sel.best

    # Where: the residual's breakdown, plus the model part of the held-out gains.
    parts: dict[str, float] = {}
    for c in r.candidates:
        gain = cv[c.name].mse_gain if c.name in sel.eligible else 0.0
        parts[c.part] = max(parts.get(c.part, 0.0), max(0.0, gain))
    where_json = where(w, d, resid)

    top_pred = cv[rk.top.name].pred_full
    candidates_json = []
    for rank, c in enumerate(rk.ranked, start=1):
        entry = candidate_json(rank, c, cv[c.name], rk, why[c.name], sel.fitter)
        entry["collinearity_with_top"] = collinearity(top_pred, cv[c.name].pred_full, valid)
        candidates_json.append(entry)
    by_cand = {e["effect"]: e for e in candidates_json}

    best_json = named_json(sel.named[0], True, by_cand, imposed, s) if group else None
    if best_json is not None and also:
        best_json["params_alone"] = by_cand[best]["params"]
    also_json = []
    for a in also:
        entry = named_json(a, False, by_cand, imposed, s)
        entry["partial_heldout_gain"] = a.gain
        entry["cumulative_heldout_reduction"] = per_support(a.cv.reduction, a.cv.reduction_total)
        also_json.append(entry)
    text = statement(group, also, rk, cv, sel.rejected)
    indistinguishable = group[1:]

    if lv is not None:  # the levels come first on a day of records
        named_by_levels = level_named(lv, s)
        if named_by_levels:
            inside = ([best_json] if best_json is not None else []) + also_json
            best_json, also_json = named_by_levels[0], named_by_levels[1:] + inside
            best, indistinguishable = best_json["effect"], best_json["indistinguishable_from"]
        text = level_statement(lv, text)
        _flag_misfit(lv, best_json, post)
    where_json["model_part"] = {
        "heldout_gain_by_part": parts,
        "part": EFFECTS[best].part if best != "none" else "none",
    }

    return {
        "best": best,
        "indistinguishable_from": indistinguishable,
        "best_effect": best_json,
        "also_present": also_json,
        "rejected_implausible": sel.rejected,
        "statement": text,
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
            "kind": r.cv_kind,
            "folds": r.n_folds,
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
        "warnings": gap_warnings(lv, post),
        "baseline": {
            "model": "u0 + A x_imposed + thermal['uniform'] * (T_air - mean T_air)",
            "imposed": [{"t_ns": int(t), "settlement_m": [float(a), float(b)]} for t, a, b in imposed],
            "imposed_sd_m": imposed_sd_m,
            "air_temperature": "present" if d.has_temperature else "missing: temperature drivers are zero",
            "surrogate": str(s.provenance.get("solver", "")),
            "sensitivities": {k: v.source for k, v in r.sens.items()},
        },
        "windows": {
            "width_s": width_s,
            "count": len(w),
            "start_ns": int(w.t_ns[0]),
            "end_ns": int(w.t_ns[-1]),
        },
        "seconds": time.perf_counter() - t0,
    }
