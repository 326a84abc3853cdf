"""What the named effects mean: the model change they make, its stand-ins, the statement for people.

``model_change`` turns the named effects into a change of the model (settlements are left to the
shadow); ``stand_in_changes`` lets each model-form member of a group stand in for the effect named
there; ``settlement_if_softer`` reads a settlement effect through a softer model; ``statement``
and ``level_statement`` say the answer in one paragraph.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from bridge_shadow.effects import EFFECTS, MODEL_FORM_EFFECTS, SETTLEMENT_EFFECTS, plausible_range
from bridge_shadow.gap.day_levels import DayLevels
from bridge_shadow.gap.fit import CvResult
from bridge_shadow.gap.fitter import BY_NAME, Fitter
from bridge_shadow.gap.posterior import IMPOSED_AVERAGE, ModelChange
from bridge_shadow.gap.rank import Named, Ranking, own_beta
from bridge_shadow.model.surrogate_file import Surrogate

if TYPE_CHECKING:  # pragma: no cover - the level analysis is imported when a day of records needs it
    from bridge_shadow.gap.levels import ImposedAnalysis

__all__ = ["level_statement", "model_change", "settlement_if_softer", "stand_in_changes", "statement"]


def model_change(entries: list[Named]) -> ModelChange:
    """Return what the named effects add to the model (not settlements: the shadow estimates them)."""
    change = ModelChange()
    additive = None
    for e in entries:
        if e.name in SETTLEMENT_EFFECTS:
            continue
        change.effects.append(e.name)
        c = BY_NAME[e.name]
        if c.nonlinear:
            springs = [np.inf if v <= 0 else 1.0 / v for v in e.cv.beta]
            change.springs_n_per_m = (float(springs[0]), float(springs[1]))
            change.springs_levelled = str(c.grid[e.cv.grid_index]).endswith("levelled")
        elif e.name in MODEL_FORM_EFFECTS:
            # the joint fit's own r when the effect was added later, else its own fit
            change.ratios[e.name] = float(own_beta(e.name, e.cv)[0])
        else:
            contrib = np.nan_to_num(e.contribution if e.contribution is not None else e.cv.pred_full)
            additive = contrib if additive is None else additive + contrib
    change.additive_n = additive
    return change


def stand_in_changes(fitter: Fitter, entries: list[Named], max_runs: int = 2) -> dict[str, ModelChange]:
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
            stand_in = Named(g, [g], e.gain, r, {}, {}, None)
            out[g] = model_change([*entries[:k], stand_in, *entries[k + 1 :]])
    return out


def settlement_if_softer(name: str, params: dict[str, Any], s: Surrogate) -> dict[str, Any] | None:
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
        x = np.array([params["v_south [m/s]"], params["v_north [m/s]"]])
        unit = "m/s"
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


def statement(
    group: list[str],
    also: list[Named],
    rk: Ranking,
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


def misfit_text(bad: dict[str, Any]) -> str:
    """Return the sentence for an imposed step no explanation fits (``ImposedAnalysis.misfit``)."""
    if bad.get("kind") == "data":
        from bridge_shadow.calibrate.explain import data_misfit_text

        return data_misfit_text(bad)
    return (
        f"no explanation fits the imposed step(s): even {bad['effect']} needs the jacks of "
        f"{bad['pair']} {1e3 * bad['jack_error_m']:+.2f} mm off what was imposed, {bad['in_sd']:.0f} "
        f"times the fit's uncertainty of that error ({bad.get('in_accuracy', 0.0):.1f} times the "
        "jacks' accuracy). Check the step's sign, size and time (and that the bag is the one "
        "the step was made in) before using a model written from it."
    )


def _prior_sets_text(an: ImposedAnalysis) -> str:
    """Say how the model after weighs the prior sets (sets that keep the sources' prior merged)."""
    fits = an.by_prior.get(an.best) or {}
    left_out = an.prior_left_out.get(an.best) or {}
    if len(fits) < 2 and not left_out:
        return ""
    w = an.prior_weights()
    parts: list[str] = []
    done: set[str] = set()
    for k, f in fits.items():
        if k in done:
            continue
        same = [j for j, g in fits.items() if g is f]
        done.update(same)
        label = k if len(same) == 1 else f"{k} (and {', '.join(same[1:])}, the same prior here)"
        values = ", ".join(f"{n} {v:.3g}" for n, v in f.values().items())
        parts.append(f"{label} {sum(w[j] for j in same):.2f}, {values}")
    parts += [f"{k} left out: {why}" for k, why in left_out.items()]
    return f" The model after averages it over the prior sets by their evidence ({'; '.join(parts)})."


def level_statement(lv: DayLevels, inside: str) -> str:
    """One paragraph for a day of records: the levels, then what happens inside the records."""
    mm = 1e3
    text = f"A day of {len(lv.records)} records."
    blind = lv.blind
    if blind:  # left out: a level needs both channels (the WARN lines say which)
        text = text[:-1] + f", and {len(blind)} more with a force channel silent, left out."
    an = lv.imposed
    if an is not None:
        rows = {r["effect"]: r for r in an.table()}
        bad = an.misfit(None, rows)  # the best, as the JSON and the WARN line say
        if an.named:
            p = ", ".join(f"{k} {v:.3g}" for k, v in rows[an.best]["parameters"].items())
            text += (
                f" The response to the imposed step(s) is not the model's: {an.best} ({p}) explains it "
                f"(probability {an.weights[an.best]:.2f}; the imposed steps within the jacks' accuracy, "
                f"settlement_step, {rows['settlement_step']['delta_log_evidence']:.1f} in log evidence)."
            )
            if an.group[1:]:
                text += f" It cannot be told apart from {', '.join(an.group[1:])}."
            text += _prior_sets_text(an)
        elif bad is None and an.best == "settlement_step":
            text += (
                " The model explains the response to the imposed step(s) within the jacks' accuracy "
                f"(probability {an.weights['settlement_step']:.2f})."
            )
        elif bad is None:  # likelier explanations, none by the factor that names one
            text += (
                " The imposed step(s) cannot tell whether the model explains them: "
                f"{an.best} is likelier (probability {an.weights[an.best]:.2f}) than the model as given "
                f"(settlement_step, {an.weights['settlement_step']:.2f}), not by the Bayes factor that "
                "names an effect; the records are too far apart or too few to show it."
            )
        after = getattr(lv, "model", None)  # the model the levels hand on (a DayLevels always has one)
        averaged = (
            after is not None
            and after.provenance.get("gap_model_change", {}).get("effect") == IMPOSED_AVERAGE
        )
        if not an.named and averaged:
            text += (
                " The model after averages the explanations by their probability, the model as given "
                "among them, their spread in its uncertainty."
            )
        if bad is not None:
            text += " But " + misfit_text(bad)
    steps = [st for st in lv.steps if st["significant"]]
    if steps:
        sizes = "; ".join(f"{st['x_m'][0] * mm:+.2f} / {st['x_m'][1] * mm:+.2f} mm" for st in steps)
        text += f" Between records the settlements stepped by {sizes} (the steps the shadow estimates)."
    return text + " Inside the records: " + inside
