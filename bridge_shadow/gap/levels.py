"""Levels on a day of records: the response to known imposed steps and the steps between records.

A load-test day is not a stream: a few short records hours apart, the central support lowered
between them (DESIGN section 3). What tells model from reality there is the *level* of each record
against the one before it, not the variation inside a record, and a record's level cannot be held
out and predicted (its step is unknown unless imposed). So the levels are read pair by pair,
across every gap between records:

- ``level_pairs``: the car-free level of the records on both sides of a gap
  (:func:`bridge_shadow.calibrate.change.record_level`: test car left out, AR(1) noise, the drift
  within the records) and their change with its covariance, the baseline's change across the gap
  an uncertainty (:func:`~bridge_shadow.calibrate.change.measured_change`; or, with
  ``baseline_change="sun"``, the deck's vertical temperature difference under the sun, as
  ``calibrate --baseline-change sun`` reads it, the day's clearness from all of the day's air
  temperature in the data). A step given with
  ``--imposed`` inside a continuous record splits it; at most ``PAIR_SPAN_S`` on each side is used.
- ``explain_imposed``: at the gaps with a known imposed step, the calibration's machinery
  (:class:`~bridge_shadow.calibrate.problem.CalibrationProblem`, Levenberg-Marquardt, Laplace
  evidence, the priors and plausible ranges of ``model.parameters``) on the model in use, through
  its sweeps and closed forms (:class:`~bridge_shadow.calibrate.surrogate_forward.SurrogateForward`,
  no FE solve). The explanations are ``IMPOSED_EXPLANATIONS``; ``settlement_step`` is the model as
  given, the settlements differing from the imposed ones by the jacks' error only (``imposed_sd``).
  With two or more imposed pairs each explanation also gets a leave-one-pair-out score. Each is
  also fitted under the other prior sets not chosen after the data (``model.parameters.PRIOR_SETS``:
  the springs' first-written centre, every prior widened); the model after averages the named
  one over them by their evidence (``ImposedAnalysis.surrogate_after``), so it does not hinge on
  where one prior is centred (issue 20): a fit the steps cannot pin (three 10 mm steps at the
  jacks' 0.5 mm leave a support between 2e8 N/m and rigid open) is otherwise the prior's.
- ``free_steps``: at the other gaps the settlement step ``x = A^-1 dR`` the shadow will estimate
  (with the model after the imposed analysis), and whether it is significant.

Nothing here reads a twin's ground-truth file. No ROS import.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from bridge_shadow.calibrate.change import (
    MeasuredChange,
    SunBaseline,
    clearness_by_day,
    measured_change,
    record_level,
)
from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.calibrate.explain import Explanation, data_misfit, fit_explanation
from bridge_shadow.calibrate.problem import PairData
from bridge_shadow.calibrate.run import evidence_weights, model_average
from bridge_shadow.calibrate.surrogate_forward import SurrogateForward
from bridge_shadow.contract import CHANNELS
from bridge_shadow.gap.posterior import IMPOSED_AVERAGE
from bridge_shadow.gap.records import IMPOSED_SD_M, OneChannel, Record
from bridge_shadow.model.build import SUPPORT_SPRINGS
from bridge_shadow.model.parameters import PRIOR_SETS, defensible_prior_sets, outside_plausible, prior_table
from bridge_shadow.model.sensitivities import StiffnessSensitivity
from bridge_shadow.model.surrogate_file import THERMAL_CASES, Discrepancy, Surrogate
from bridge_shadow.model.sweeps import Sweep
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries
from bridge_shadow.sun_change import solar_day

__all__ = [
    "IMPOSED_EXPLANATIONS",
    "ImposedAnalysis",
    "LevelPair",
    "explain_imposed",
    "free_steps",
    "level_pairs",
    "slice_data",
]

NS = 1_000_000_000
#: Data used on each side of a step, s: a whole 12-minute record; inside a continuous record an
#: hour each side (longer spans mix in the daily thermal swing the level line cannot follow).
PAIR_SPAN_S = 3600.0
#: Bayes factor below which two explanations are not told apart: 3, "not worth more than a bare
#: mention" (Kass and Raftery 1995, Table 1).
INDISTINGUISHABLE_LOG_BF = math.log(3.0)
#: Bayes factor over the model as given above which the imposed steps say the model is wrong:
#: 20, "strong" evidence (Kass and Raftery 1995).
NAMED_LOG_BF = math.log(20.0)
#: chi-square (2 dof) probability beyond which a step between two records is significant: the
#: shadow's event probability (``event_probability`` 0.999999 in config/shadow.yaml).
STEP_PROBABILITY = 0.999999

_SPRINGS = tuple(SUPPORT_SPRINGS.values())
#: Explanations of the response to a known imposed step: effect name -> the parameters fitted.
IMPOSED_EXPLANATIONS: dict[str, tuple[str, ...]] = {
    "settlement_step": (),
    "support_spring": _SPRINGS,
    "bearing_stiffness": ("bearing_stiffness",),
    "connector_stiffness": ("connector_stiffness",),
    "slab_joint_opening": ("slab_joint_opening",),
}


def slice_data(data: MonitoringData, start_ns: int, end_ns: int) -> MonitoringData:
    """Return the samples of ``data`` with ``start_ns <= stamp < end_ns`` (forces and temperature)."""
    forces = {}
    for ch in CHANNELS:
        s = data.forces[ch]
        k = (s.stamp_ns >= start_ns) & (s.stamp_ns < end_ns)
        log = s.log_ns[k] if s.log_ns is not None else None
        forces[ch] = ForceSeries(s.stamp_ns[k], s.force_n[k], s.frame_id[k], log)
    t = data.temperature
    k = (t.stamp_ns >= start_ns) & (t.stamp_ns < end_ns)
    var = t.variance[k] if t.variance is not None else None
    log = t.log_ns[k] if t.log_ns is not None else None
    return MonitoringData(forces, TemperatureSeries(t.stamp_ns[k], t.temp_c[k], var, t.frame_id[k], log))


@dataclass
class LevelPair:
    """The level change across one gap (or one imposed step inside a record).

    Attributes:
        name: label (``step N at HH:MM``). at_ns: the step time (the imposed one, or the start of
            the record after the gap). imposed_m: (2,) the imposed step (None: free, the shadow
            estimates it). imposed_sd_m: (2,) its sd. change: the measured change.
        before, after: ``(start_ns, end_ns)`` of the data on each side.
        settlement_before_m: (2,) the imposed settlement accumulated before the step (m).

    """

    name: str
    at_ns: int
    imposed_m: np.ndarray | None
    imposed_sd_m: np.ndarray
    change: MeasuredChange
    before: tuple[int, int]
    after: tuple[int, int]
    settlement_before_m: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def imposed(self) -> bool:
        """Whether the step was given (``--imposed``)."""
        return self.imposed_m is not None

    def pair_data(self) -> PairData:
        """Return the calibration's view of an imposed pair."""
        assert self.imposed_m is not None
        return PairData(self.name, self.imposed_m, self.imposed_sd_m, self.change)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (SI)."""
        c = self.change
        return {
            "name": self.name,
            "at_ns": int(self.at_ns),
            "imposed_m": None if self.imposed_m is None else self.imposed_m.tolist(),
            "imposed_sd_m": self.imposed_sd_m.tolist() if self.imposed else None,
            "dR_n": c.dR_n.tolist(),
            "dR_sd_n": c.sd_n.tolist(),
            "seconds_between": c.dt_s,
            "air_temp_change_k": c.air_temp_change_k,
            "baseline_change": c.baseline_change,
            "sun": c.sun,
            "before_ns": list(self.before),
            "after_ns": list(self.after),
        }


def _hhmm(t_ns: int) -> str:
    """Local time of the bridge (the records' own clock, Europe/Berlin) as ``HH:MM``."""
    import datetime as dt
    from zoneinfo import ZoneInfo

    return dt.datetime.fromtimestamp(t_ns / NS, ZoneInfo("Europe/Berlin")).strftime("%H:%M")


def level_pairs(
    data: MonitoringData,
    records: Sequence[Record],
    imposed: Sequence[tuple[int, float, float]],
    imposed_sd_m: float = IMPOSED_SD_M,
    baseline_change: str = "uncertainty",
    sun: SunBaseline | None = None,
    blind: Sequence[OneChannel] = (),
) -> tuple[list[LevelPair], list[str]]:
    """Measure the level change across every record gap and every imposed step.

    ``baseline_change``, ``sun``: as ``calibrate.change.measured_change`` takes them. ``blind``:
    records with a silent channel (``records.one_channel_records``); a pair across one is not
    measured, since a change in that record would be in it.

    Returns the pairs (in time order) and notes on what could not be measured (a record with too
    few car-free windows).
    """
    bounds: list[tuple[int, int, np.ndarray | None]] = []  # (t, index of the record before, step)
    steps = sorted((int(t), np.array([a, b], float)) for t, a, b in imposed)
    for r in records[1:]:
        prev = records[r.index - 1]
        inside = [s for s in steps if prev.end_ns <= s[0] < r.start_ns]
        step = sum((s[1] for s in inside), np.zeros(2)) if inside else None
        at = inside[0][0] if inside else r.start_ns
        bounds.append((at, prev.index, step))
    for t, step in steps:  # imposed steps inside a record split it
        for r in records:
            if r.start_ns < t < r.end_ns:
                bounds.append((t, -1 - r.index, step))
    bounds.sort(key=lambda b: b[0])
    pairs, notes = [], []
    clearness = clearness_by_day(data)  # each day's, from all of its air in the data
    cumulative = np.zeros(2)
    for k, (t, where, step) in enumerate(bounds):
        if where >= 0:
            rb, ra = records[where], records[where + 1]
            before = (max(rb.start_ns, rb.end_ns - round(PAIR_SPAN_S * NS)), rb.end_ns)
            after = (ra.start_ns, min(ra.end_ns, ra.start_ns + round(PAIR_SPAN_S * NS)))
        else:
            r = records[-1 - where]
            before = (max(r.start_ns, t - round(PAIR_SPAN_S * NS)), t)
            after = (t, min(r.end_ns, t + round(PAIR_SPAN_S * NS)))
        # the data's own gaps inside a span are the records', not this pair's
        prev_t = bounds[k - 1][0] if k else None
        next_t = bounds[k + 1][0] if k + 1 < len(bounds) else None
        before = (max(before[0], prev_t) if prev_t is not None else before[0], before[1])
        after = (after[0], min(after[1], next_t) if next_t is not None else after[1])
        name = f"step {k + 1} at {_hhmm(t)}"
        unused = f"; {IMPOSED_UNUSED}" if step is not None else ""
        across = [b for b in blind if before[1] <= b.start_ns and b.end_ns <= after[0]]
        if across:
            b = across[0]
            notes.append(
                f"{name}: level not measured (the record between, {_hhmm(b.start_ns)} to "
                f"{_hhmm(b.end_ns)}, has {b.silent} silent: a change there would be in this pair"
                f"{unused})"
            )
            if step is not None:
                cumulative = cumulative + step
            continue
        try:
            lb = record_level(slice_data(data, *before), window_s=_window_s(data))
            la = record_level(slice_data(data, *after), window_s=_window_s(data))
            # the day's clearness from all of its air, not from the slices' minutes
            lb = replace(lb, clearness=clearness.get(solar_day(lb.t_ns), float("nan")))
            la = replace(la, clearness=clearness.get(solar_day(la.t_ns), float("nan")))
            change = measured_change(lb, la, baseline_change, sun)
        except (CalibrationError, ValueError) as err:
            notes.append(f"{name}: level not measured ({err}{unused})")
            if step is not None:
                cumulative = cumulative + step
            continue
        sd = np.full(2, imposed_sd_m)
        pairs.append(LevelPair(name, t, step, sd, change, before, after, cumulative.copy()))
        if step is not None:
            cumulative = cumulative + step
    return pairs, notes


#: The end of a note on a pair that held an imposed step and could not be measured.
IMPOSED_UNUSED = "the imposed step there is not used"


def _window_s(data: MonitoringData) -> float:
    """Car-free window length for the level fit: 10 s, or 5 samples where forces come slower."""
    s = data.forces[CHANNELS[0]].stamp_ns
    if len(s) < 3:
        return 10.0
    spacing = float(np.median(np.diff(s))) / NS
    return max(10.0, 5.0 * spacing)


#: An explanation whose MAP needs a jack off the imposed step by more than this many of the jacks'
#: sds does not explain the step (two-sided normal tail 6e-5 a number: with a few pairs' four
#: numbers, under 1e-3 that any of them is so far by chance).
MISFIT_SD = 4.0


@dataclass
class ImposedAnalysis:
    """What explains the response to the known imposed steps.

    Attributes:
        pairs: the imposed pairs. explanations: effect -> fitted explanation.
        weights: effect -> posterior probability (equal prior odds).
        best: the most probable effect. group: effects within ``INDISTINGUISHABLE_LOG_BF`` of it.
        named: the model as given (``settlement_step``: jacks' error only) is beaten by a Bayes
            factor over ``NAMED_LOG_BF``, i.e. the imposed steps say the model is wrong.
        forward: how the surrogate was varied (sweeps, first-order, closed forms).
        by_prior: effect -> prior set -> the explanation fitted under that set
            (``defensible_prior_sets``; the one in use is ``explanations``' own), for the model after.
        prior_left_out: effect -> prior set -> why its fit is not averaged (outside the table's
            plausible range).

    """

    pairs: list[LevelPair]
    explanations: dict[str, Explanation]
    weights: dict[str, float]
    best: str
    group: list[str]
    named: bool
    forward: dict[str, Any]
    by_prior: dict[str, dict[str, Explanation]] = field(default_factory=dict)
    prior_left_out: dict[str, dict[str, str]] = field(default_factory=dict)

    def misfit(
        self, name: str | None = None, rows: Mapping[str, dict[str, Any]] | None = None
    ) -> dict[str, Any] | None:
        """Whether explanation ``name`` (default ``best``) needs the jacks far off what was imposed.

        Returns None when it fits: every jack error of its MAP within ``MISFIT_SD`` of the jacks'
        accuracy and the measured changes within their uncertainty (``calibrate.explain.data_misfit``).
        Otherwise the largest error and its size in those sds (``kind`` ``jacks``), or the data's
        chi-square (``kind`` ``data``): the probabilities rank
        the explanations against each other, and the best of those that all fail is no answer
        (a step given with the wrong sign was "explained" by a softer deck at probability 1.00).
        ``rows``: ``table()`` by effect, when already built (else the explanation's own summary).
        """
        effect = name or self.best
        row = rows[effect] if rows is not None else self.explanations[effect].summary()
        worst = (0.0, "", 0.0, 0.0)
        accuracy = {p.name: p.imposed_sd_m for p in self.pairs}
        for pair, err in row["imposed_error_m"].items():
            # in the fit's own sd of the error: precise levels pin it, so a jack the explanation
            # needs off by a steady amount is told from chance. Against the jacks' accuracy instead
            # (tried on stop 78), a step given at half its size on the calibrated twin, "explained"
            # by closed joints and jacks 1-2 accuracies off all one way, passed unsaid (12 mm off)
            for value, sd, acc in zip(err["map"], err["sd"], accuracy[pair], strict=True):
                ratio = abs(value) / sd if sd > 0 else math.inf
                if ratio > worst[0]:
                    worst = (ratio, pair, value, abs(value) / acc)
        if worst[0] > MISFIT_SD:
            return {
                "effect": effect,
                "kind": "jacks",
                "pair": worst[1],
                "jack_error_m": worst[2],
                "in_sd": worst[0],
                "in_accuracy": worst[3],
            }
        if effect != self.best:
            return None  # "even X" is said of the best; a likelier one may fit the data
        # the jacks within their accuracy, the data may still not fit: a later step's level carries
        # hours of baseline drift, so the fit keeps its jack and leaves the mismatch in the data
        return data_misfit(effect, float(row["chi2_data"]), self.explanations[effect].problem.n_data)

    def prior_weights(self, name: str | None = None) -> dict[str, float]:
        """Posterior probability of each defensible prior set for explanation ``name`` (default ``best``)."""
        effect = name or self.best
        return evidence_weights(self._fits(effect))

    def _fits(self, effect: str) -> dict[str, Explanation]:
        """Explanation ``effect``'s fit under each defensible prior set (one set: the sources')."""
        return self.by_prior.get(effect) or {"sources": self.explanations[effect]}

    def _sets_json(self, effect: str) -> dict[str, Any]:
        """Explanation ``effect``'s weight, log evidence and MAP (SI) under each prior set."""
        fits = self._fits(effect)
        w = evidence_weights(fits)
        return {
            k: {"weight": w[k], "log_evidence": f.post.log_evidence, "parameters": f.values()}
            for k, f in fits.items()
        }

    def prior_sets_json(self) -> dict[str, Any]:
        """Per explanation with parameters: its fit and evidence under each defensible prior set (SI)."""
        out: dict[str, Any] = {
            "rule": (
                "the model after (and --out-surrogate) averages the named explanation over the prior "
                "sets not chosen after the data (model.parameters.PRIOR_SETS), each set equally "
                "likely beforehand (a prior two sets share counts twice), by their evidence; its "
                "spread joins the model uncertainty; a set whose fit leaves the plausible range (the "
                "sources' table, which calibrate and gap share) is left out"
            )
        }
        for effect in self.by_prior:
            out[effect] = self._sets_json(effect)
            for k, why in self.prior_left_out.get(effect, {}).items():
                out[effect][k] = {"weight": 0.0, "left_out": why}
        return out

    def surrogate_after(self, base: Surrogate, name: str | None = None) -> Surrogate:
        """Return the model in use with explanation ``name`` (default ``best``) added.

        ``A`` and ``thermal`` from the explanation's MAP, averaged over the defensible prior sets
        by their evidence (``by_prior``; one set: its MAP), so the model after does not hinge on
        where one prior is centred; ``u0`` stays the base's (the supports were set under the dead
        load, which the precast deck put on the steel girders before any stiffness the steps
        reveal; as in ``calibrate.run``), the FE's ``u0`` at the average entering as an
        uncertainty; ``model_uncertainty``: the base's (12 x 12, or 6 x 6 padded) plus the
        explanation's parameter posterior propagated under each set (``Explanation.model_cov``)
        and the spread between the sets (``calibrate.run.model_average``); a ``discrepancy``
        anchored at the imposed settlements the steps passed through (beyond them, larger steps
        are extrapolation).
        """
        effect = name or self.best
        e = self.explanations[effect]
        mean, spread = model_average(self._fits(effect))
        change = {
            "effect": e.name,
            "parameters": e.values(),
            "fitted_to": [p.name for p in self.pairs],
            "log_evidence": e.post.log_evidence,
            "prior_sets": self._sets_json(effect),
        }
        return self._model(base, mean, spread, e, change)

    def surrogate_average(self, base: Surrogate) -> Surrogate:
        """Return the model average over every explanation, the model as given among them.

        For imposed steps that name no effect (``named`` false: no explanation beats the model as
        given by the naming factor) the model as given is one explanation of several, not the
        answer: each explanation weighs by its probability (``weights``), within it each prior set
        by its evidence (``by_prior``), and the spread between them joins the model uncertainty
        (``calibrate.run.model_average``'s moments), the rest as ``surrogate_after``.
        """
        fits: dict[str, Explanation] = {}
        w: dict[str, float] = {}
        for effect in self.explanations:
            sets = self._fits(effect)
            within = evidence_weights(sets)
            for k, f in sets.items():
                fits[f"{effect} ({k})"] = f
                w[f"{effect} ({k})"] = self.weights[effect] * within[k]
        mean, spread = model_average(fits, weights=w)
        change = {
            "effect": IMPOSED_AVERAGE,
            "fitted_to": [p.name for p in self.pairs],
            "weights": dict(self.weights),
            # each member of the mixture: explanation (prior set), its weight and its MAP
            "members": {k: {"weight": w[k], "parameters": f.values()} for k, f in fits.items()},
        }
        return self._model(base, mean, spread, self.explanations[self.best], change)

    def _model(
        self, base: Surrogate, mean: np.ndarray, spread: np.ndarray, e: Explanation, change: dict[str, Any]
    ) -> Surrogate:
        """Return the model after from a mixture's moments (``surrogate_after``, ``surrogate_average``)."""
        a = mean[:4].reshape(2, 2)
        thermal = dict(e.evaluation.thermal)
        thermal.update({c: mean[6 + 2 * i : 8 + 2 * i].copy() for i, c in enumerate(THERMAL_CASES)})
        cov = np.zeros((12, 12))
        if base.model_cov is not None:
            n = base.model_cov.shape[0]
            cov[:n, :n] = base.model_cov
        shift = mean[4:6] - base.u0
        cov = cov + spread
        cov[4:6, 4:6] += np.outer(shift, shift)
        states = [p.settlement_before_m for p in self.pairs]
        states += [p.settlement_before_m + p.imposed_m for p in self.pairs if p.imposed_m is not None]
        prov = dict(base.provenance)
        prov["gap_model_change"] = change
        return Surrogate(
            0.5 * (a + a.T), base.u0.copy(), thermal, prov, cov, Discrepancy.from_steps(np.array(states))
        )

    def table(self) -> list[dict[str, Any]]:
        """One row per explanation, most probable first (SI)."""
        top = max(e.post.log_evidence for e in self.explanations.values())
        rows = []
        for name, e in sorted(self.explanations.items(), key=lambda kv: -kv[1].post.log_evidence):
            s = e.summary()
            rows.append(
                {
                    "effect": name,
                    "parameters": {k: v["map"] for k, v in s["map"].items()},
                    "intervals95": {k: [v["low95"], v["high95"]] for k, v in s["map"].items()},
                    "log_evidence": e.post.log_evidence,
                    "delta_log_evidence": e.post.log_evidence - top,
                    "probability": self.weights[name],
                    "chi2_data": s["chi2_data"],
                    "heldout_logpdf": s["heldout_logpdf"],
                    "imposed_error_m": s["imposed_error_m"],
                    "in_sample": s["in_sample"],
                    "A": s["A"],
                }
            )
        return rows

    def to_dict(self) -> dict[str, Any]:
        """Return the ``levels.imposed`` block of the gap JSON (SI)."""
        table = self.table()
        return {
            "pairs": [p.to_dict() for p in self.pairs],
            "explanations": table,
            "best": self.best,
            "misfit": self.misfit(rows={r["effect"]: r for r in table}),
            "indistinguishable_from": self.group[1:],
            "named": self.named,
            "rule": (
                f"an effect is named when its evidence beats the model as given (settlement_step: the "
                f"imposed steps within the jacks' accuracy) by a Bayes factor over "
                f"{math.exp(NAMED_LOG_BF):.0f}; effects within a factor of "
                f"{math.exp(INDISTINGUISHABLE_LOG_BF):.0f} of the best are not told apart"
            ),
            "forward": self.forward,
            "prior_sets": self.prior_sets_json(),
            "validation": "leave one imposed pair out"
            if len(self.pairs) > 1
            else "one imposed pair: evidence only (nothing to hold out)",
        }


def explain_imposed(
    pairs: Sequence[LevelPair],
    surrogate: Surrogate,
    sweeps: Mapping[str, Sweep],
    sensitivities: Mapping[str, StiffnessSensitivity],
) -> ImposedAnalysis:
    """Fit every explanation of ``IMPOSED_EXPLANATIONS`` to the imposed pairs (module docstring)."""
    imposed = [p for p in pairs if p.imposed]
    data = [p.pair_data() for p in imposed]

    def make_forward(names: tuple[str, ...]) -> SurrogateForward:
        return SurrogateForward(surrogate, names, sweeps, sensitivities)

    explanations = {}
    for effect, names in IMPOSED_EXPLANATIONS.items():
        try:
            make_forward(names)
        except CalibrationError:
            continue  # neither a sweep nor a sensitivity for it
        explanations[effect] = fit_explanation(
            effect,
            names,
            None,  # type: ignore[arg-type]
            "",
            data,
            heldout=len(data) > 1,
            make_forward=make_forward,
        )
    by_prior: dict[str, dict[str, Explanation]] = {}
    left_out: dict[str, dict[str, str]] = {}
    for effect, e in explanations.items():
        if e.problem.p:
            by_prior[effect], left_out[effect] = _under_prior_sets(e, data, make_forward)
    weights = evidence_weights(explanations)
    best = max(explanations, key=lambda k: explanations[k].post.log_evidence)
    top = explanations[best].post.log_evidence
    group = [
        k
        for k, e in sorted(explanations.items(), key=lambda kv: -kv[1].post.log_evidence)
        if top - e.post.log_evidence < INDISTINGUISHABLE_LOG_BF
    ]
    as_given = explanations["settlement_step"].post.log_evidence
    named = best != "settlement_step" and top - as_given > NAMED_LOG_BF
    fe = tuple(n for e in explanations for n in IMPOSED_EXPLANATIONS[e] if n not in _SPRINGS)
    forward = make_forward(fe).document()
    return ImposedAnalysis(
        list(imposed), explanations, weights, best, group, named, forward, by_prior, left_out
    )


def _under_prior_sets(
    e: Explanation, data: Sequence[PairData], make_forward: Any
) -> tuple[dict[str, Explanation], dict[str, str]]:
    """Explanation ``e`` (fitted under the sources) under every defensible prior set.

    A set that leaves its parameters' priors as they are keeps its fit (as ``calibrate``'s prior
    sensitivity does). A set whose MAP leaves the plausible range of the sources' table (the one
    both ``calibrate`` and ``gap`` read) is left out, with the reason: the model after never holds
    a value the gap would reject as implausible. Returns the fits and the sets left out.
    """
    out, left_out = {}, {}
    for k in defensible_prior_sets():
        s = PRIOR_SETS[k]
        touched = s.widen != 1.0 or any(n in s.changes for n in e.names)
        if k == "sources" or not touched:
            out[k] = e
            continue
        f = fit_explanation(
            e.name, e.names, None, "", data, heldout=False, priors=prior_table(k), make_forward=make_forward
        )
        outside = outside_plausible(f.values())
        if outside:
            left_out[k] = f"its fit ({', '.join(outside)}) lies outside the plausible range"
        else:
            out[k] = f
    return out, left_out


def free_steps(pairs: Sequence[LevelPair], surrogate: Surrogate) -> list[dict[str, Any]]:
    """Read the steps at the gaps without an imposed step: ``x = A^-1 dR`` under ``surrogate`` (SI).

    Each with its covariance (the measured change's and the surrogate's own uncertainty of a
    change), the chi-square of ``dR`` against its covariance, and whether it is a step
    (``STEP_PROBABILITY``).
    """
    from scipy import stats

    limit = float(stats.chi2.ppf(STEP_PROBABILITY, 2))
    out = []
    a_inv = np.linalg.inv(surrogate.A)
    for p in pairs:
        if p.imposed:
            continue
        c = p.change
        x = a_inv @ c.dR_n
        cov = a_inv @ c.cov_n2 @ a_inv.T + surrogate.model_covariance(x, with_u0=False)
        chi2 = float(c.dR_n @ np.linalg.solve(c.cov_n2, c.dR_n))
        out.append(
            {
                "name": p.name,
                "at_ns": int(p.at_ns),
                "x_m": x.tolist(),
                "sigma_m": np.sqrt(np.diag(cov)).tolist(),
                "covariance_m2": cov.tolist(),
                "chi2": chi2,
                "significant": bool(chi2 > limit),
            }
        )
    return out
