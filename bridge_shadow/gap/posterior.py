"""Posterior settlements of the shadow before and after adding the named effects to the model.

One estimator: both come from the online ``Shadow`` pipeline (``bridge_shadow.estimate``; gate,
60 s windows, P-spline compensation, noise model, Kalman update), run exactly as
``bridge-shadow replay`` runs it (same parameters, same surrogate, no checkpoint written):

- ``before``: the shadow with the model in use, on the record as it is. It is the answer of
  ``bridge-shadow replay BAG`` with the same ``--params`` and surrogate.
- ``after``: the shadow with the named effects added to the model: a model-form effect
  (stiffness, support spring, slab-joint opening) changes the surrogate the shadow uses
  (``model.sensitivities.change_surrogate``); an additive effect (thermal, traffic, sensor drift)
  has its fitted contribution taken off every force sample (interpolated between window centres).
  Settlement effects are never added: the settlements are what the shadow estimates.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.effects import MODEL_FORM_EFFECTS
from bridge_shadow.model.sensitivities import StiffnessSensitivity, change_surrogate
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import ForceSeries, MonitoringData

__all__ = ["IMPOSED_AVERAGE", "ModelChange", "shadow_config", "shadow_posteriors", "subtract_contribution"]

#: The model after when imposed steps name no effect: the average over their explanations, the
#: model as given among them (``gap.levels.ImposedAnalysis.surrogate_average``).
IMPOSED_AVERAGE = "imposed_steps_average"


@dataclass
class ModelChange:
    """What the named effects add to the model.

    Attributes:
        effects: names of the effects added (vocabulary order of naming).
        ratios: first-order parameter name -> relative change ``r``.
        springs_n_per_m: support springs [south, north] in N/m (``inf``: none).
        springs_levelled: the supports were levelled under the dead load (``u0`` kept).
        additive_n: (n, 2) N on the window grid, the summed additive contributions.
        replaced: a whole model to start from instead of the one in use (the imposed steps'
            explanation of a day of records, ``gap.levels``), or None.

    """

    effects: list[str] = field(default_factory=list)
    ratios: dict[str, float] = field(default_factory=dict)
    springs_n_per_m: tuple[float, float] = (np.inf, np.inf)
    springs_levelled: bool = False
    additive_n: np.ndarray | None = None
    replaced: Surrogate | None = None

    @property
    def empty(self) -> bool:
        """Nothing is added."""
        return not self.effects

    def surrogate(self, base: Surrogate, sensitivities: Mapping[str, StiffnessSensitivity]) -> Surrogate:
        """Return the model with this change: ``replaced`` (or ``base``), then ratios and springs."""
        start = self.replaced if self.replaced is not None else base
        changed, _ = change_surrogate(
            start, dict(sensitivities), self.ratios, self.springs_n_per_m, levelled=self.springs_levelled
        )
        return changed


def shadow_config(params_path: str | None = None, surrogate_path: str | None = None) -> Any:
    """Load the shadow's parameters as replay does, with checkpoints off (the gap writes no state)."""
    from bridge_shadow.estimate import load_config

    overrides: dict[str, Any] = {"checkpoint_path": ""}
    if surrogate_path:
        overrides["surrogate_path"] = str(surrogate_path)
    return load_config(params_path, overrides=overrides)


def subtract_contribution(
    data: MonitoringData, t_ns: np.ndarray, contribution_n: np.ndarray
) -> MonitoringData:
    """Take ``contribution_n`` (n, 2) N at window centres ``t_ns`` off each force sample."""
    forces = {}
    for i, ch in enumerate(CHANNELS):
        f = data.forces[ch]
        c = np.interp(f.stamp_ns.astype(float), t_ns.astype(float), np.nan_to_num(contribution_n[:, i]))
        forces[ch] = ForceSeries(f.stamp_ns, f.force_n - c, f.frame_id, f.log_ns)
    return MonitoringData(forces, data.temperature)


def _posterior_json(result: Any) -> dict[str, Any]:
    mean, cov = np.asarray(result.mean_m, float), np.asarray(result.covariance_m2, float)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return {
        "mean_m": mean.tolist(),
        "covariance_m2": cov.tolist(),
        "sigma_m": sd.tolist(),
        "interval95_m": [[float(m - 1.96 * v), float(m + 1.96 * v)] for m, v in zip(mean, sd, strict=True)],
        "updates": int(result.updates),
        "state": dict(result.state),  # which state it stands for (a state nobody saw: unseen_from)
        # the settlement events this run found: a model change can add (or take away) one
        "events": [
            {"kind": e["kind"], "time_ns": e["time_ns"], "time": e["time"], "size_m": e["size_m"]}
            for e in (ev.to_json() for ev in result.events)
        ],
        "warnings": list(result.warnings),
    }


def _after(
    data: MonitoringData,
    surrogate: Surrogate,
    config: Any,
    change: ModelChange,
    t_ns: np.ndarray,
    sensitivities: Mapping[str, StiffnessSensitivity],
) -> dict[str, Any]:
    """Run the shadow with ``change`` added to the model."""
    from bridge_shadow.estimate import Shadow

    changed = change.surrogate(surrogate, sensitivities)
    run_data = data
    if change.additive_n is not None and np.any(change.additive_n):
        run_data = subtract_contribution(data, t_ns, change.additive_n)
    after = _posterior_json(Shadow(config, changed).run(run_data))
    if change.replaced is not None:
        model_change = changed.provenance.get("gap_model_change", {})
        after["model_change_from_levels"] = model_change
    named = [e for e in change.effects if e != IMPOSED_AVERAGE]
    after["what"] = (
        f"the shadow with {', '.join(named)} added to the model (settlements stay the shadow's to estimate)"
        if named
        else "the shadow"
    )
    if IMPOSED_AVERAGE in change.effects:
        after["what"] += (
            ", its model averaged over the imposed steps' explanations by their probability (the model "
            "as given among them: the steps named none)"
        )
    after["effects_added"] = list(change.effects)
    # what a surrogate file can carry (``gap --out-surrogate``) and what only this run takes off
    model_form = (*MODEL_FORM_EFFECTS, IMPOSED_AVERAGE)
    after["effects_in_surrogate"] = [e for e in change.effects if e in model_form]
    after["effects_off_the_record"] = [e for e in change.effects if e not in model_form]
    model: dict[str, Any] = {k: float(v) for k, v in change.ratios.items()}
    if np.any(np.isfinite(change.springs_n_per_m)):
        model["support_spring_n_per_m"] = [None if np.isinf(k) else float(k) for k in change.springs_n_per_m]
        model["support_spring_levelled"] = change.springs_levelled
    if model:
        after["model_change"] = model
        after["surrogate_A"] = changed.A.tolist()
        after["surrogate_u0"] = changed.u0.tolist()
    return after


def shadow_posteriors(
    data: MonitoringData,
    surrogate: Surrogate,
    config: Any,
    change: ModelChange,
    t_ns: np.ndarray,
    sensitivities: Mapping[str, StiffnessSensitivity],
    alternatives: Mapping[str, ModelChange] | None = None,
) -> dict[str, Any]:
    """Run the shadow before and after ``change``; return the ``posterior`` JSON of the diagnosis.

    ``alternatives``: model-form effects the data cannot tell from a named one -> the model change
    with that effect standing in; each is run too (``posterior.alternatives``, empty when asked
    for and there is none; absent when not asked for).
    """
    from bridge_shadow.estimate import Shadow

    before = _posterior_json(Shadow(config, surrogate).run(data))
    before["what"] = "the shadow with the model in use (the answer of `bridge-shadow replay` on this bag)"
    if surrogate.model_cov is None and surrogate.discrepancy is None:
        # an uncalibrated model: its interval is the noise's alone, however wrong the model is
        before["what"] += "; the model carries no model uncertainty, so its interval is the noise's alone"
    if change.empty:
        after = dict(before)
        after["what"] = (
            "nothing added: no effect named, or settlements only, which are what the shadow estimates "
            "(after = before)"
        )
        after["effects_added"] = after["effects_in_surrogate"] = after["effects_off_the_record"] = []
    else:
        after = _after(data, surrogate, config, change, t_ns, sensitivities)
    out = {
        "before": before,
        "after": after,
        "change_m": (np.array(after["mean_m"]) - np.array(before["mean_m"])).tolist(),
        "method": "online Shadow (bridge_shadow.estimate), run as `bridge-shadow replay` runs it",
    }
    if alternatives is not None:  # asked for: an empty block says there was none to run
        alt = {}
        for name, ch in alternatives.items():
            alt[name] = _after(data, surrogate, config, ch, t_ns, sensitivities)
            why = "which the data cannot tell from the named effect"
            alt[name]["what"] = f"if {name} ({why}) is the cause: {alt[name]['what']}"
        out["alternatives"] = alt
    return out
