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
from typing import Any

import numpy as np

from bridge_shadow.engine import Mapper
from bridge_shadow.gap.drivers import Drivers
from bridge_shadow.gap.explain import model_change, stand_in_changes
from bridge_shadow.gap.fit import CvResult
from bridge_shadow.gap.fitter import Fitter
from bridge_shadow.gap.posterior import IMPOSED_AVERAGE, ModelChange, shadow_posteriors
from bridge_shadow.gap.posterior import shadow_config as default_config
from bridge_shadow.gap.rank import Selection, select_effects
from bridge_shadow.gap.records import IMPOSED_SD_M
from bridge_shadow.gap.residual import Residual, residual_of
from bridge_shadow.gap.summary import gap_summary
from bridge_shadow.gap.windows import Windows
from bridge_shadow.model.surrogate_file import Surrogate, load_surrogate
from bridge_shadow.series import MonitoringData

__all__ = ["Diagnosis", "diagnose"]


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
    mapper: Mapper | None = None,
    baseline_change: str = "uncertainty",
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
        mapper: how the held-out folds of every candidate are fitted (``engine.client_mapper``: as
            Dask tasks; default one after the other here). The same fits either way.
        baseline_change: on a day of records, the baseline's change between them
            (``calibrate.change``: ``uncertainty``, ``linear`` or ``sun``).

    """
    t0 = time.perf_counter()
    s = surrogate if surrogate is not None else load_surrogate()
    # Where the gap lies: the residual against the baseline model on the window grid.
    r = residual_of(data, s, width_s, holdout_days, imposed, imposed_sd_m, surrogate_path, baseline_change)
    # Which effect: every candidate cross-validated inside its plausible range; a candidate whose
    # data-optimal fit lies outside it is rejected; the rest ranked, grouped, then further effects.
    sel = select_effects(Fitter(r.ctx, r.resid, r.valid, r.fold, r.candidates, r.record, mapper), z)
    # How far: the shadow's posterior before and after adding the named effects to the model.
    change = model_change(sel.named)
    lv = r.levels
    if lv is not None and lv.model is not s:
        change.replaced = lv.model
        an = lv.imposed
        change.effects.insert(0, "model" if an is None else an.best if an.named else IMPOSED_AVERAGE)
    after_model = change.surrogate(s, r.sens)
    post: dict[str, Any] = {"computed": False, "why": "run with shadow=True (the CLI always does)"}
    if shadow:
        cfg = shadow_config if shadow_config is not None else default_config()
        alts = (_stand_ins(r, sel, change, s) or {}) if alternatives else None
        post = shadow_posteriors(data, s, cfg, change, r.windows.t_ns, r.sens, alts)
        post["computed"] = True
    summary = gap_summary(r, sel, post, s, imposed, imposed_sd_m, z, width_s, t0)
    joint = None
    if sel.also:
        joint = sum(np.nan_to_num(e.contribution) for e in sel.named if e.contribution is not None)
    best = summary["best"]
    return Diagnosis(summary, r.windows, r.drivers, r.resid, r.fold, sel.cv, best, joint, after_model)


def _stand_ins(
    r: Residual, sel: Selection, change: ModelChange, s: Surrogate
) -> dict[str, ModelChange] | None:
    """Model changes with each indistinguishable model-form effect standing in for a named one.

    The members of the named effects' groups (``explain.stand_in_changes``) and, on a day of records
    whose imposed steps named a stiffness, each member of that group.
    """
    alts = stand_in_changes(sel.fitter, sel.named)
    lv = r.levels
    if lv is not None and lv.imposed is not None and lv.imposed.named:
        # the imposed steps' group: each member standing in for the named stiffness
        for g in lv.imposed.group[1:]:
            alt = ModelChange([g, *change.effects[1:]], dict(change.ratios), change.springs_n_per_m)
            alt.springs_levelled, alt.additive_n = change.springs_levelled, change.additive_n
            alt.replaced = lv.imposed.surrogate_after(s, g)
            alts = {**(alts or {}), g: alt}
    return alts
