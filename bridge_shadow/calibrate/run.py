"""``calibrate``: record pairs with known imposed settlements -> posterior of FE parameters -> surrogate.

Steps (each its own module): read the records and measure the car-free change of each pair with
its covariance (:mod:`.change`); fit every candidate explanation (:mod:`.explain`: projected
Levenberg-Marquardt with FE re-solves and adjoint sensitivities, Laplace posterior and evidence,
priors and plausible ranges from :mod:`bridge_shadow.model.parameters`); combine them:

- ``choose: average`` (the default): Bayesian model averaging. Each explanation's weight is its
  posterior probability ``w_k ~ exp(log Z_k)`` (equal prior odds); the surrogate's ``A``, ``u0`` and
  thermal cases are the weighted means of the explanations' MAP surrogates, and
  ``model_uncertainty`` their total covariance ``sum_k w_k (C_k + (m_k - m)(m_k - m)')`` (each
  one's posterior spread plus the spread between them), so that the surrogate does not hinge on
  one explanation, nor on where one prior is centred;
- ``choose: best`` or a name: that one explanation, with its own posterior as the uncertainty.

The FE model is re-solved at the MAP of the most probable explanation (with the support springs
in the FE itself) for the sensitivities the gap diagnosis reads. ``u0`` is where ``x = 0`` is
(``zero``): with ``before`` the car-free level of the first pair's before record (the imposed
settlements are counted from that state; a monitor is zeroed at a reference record), with
``as_built`` the as-built FE's dead-load reactions. A pair of records measures changes, not the
dead-load reactions, and the supports were set under the dead load, which the precast deck put
on the steel girders before the joints and connectors the explanations soften took part, so the
explanations' FE ``u0`` at the MAP enters as an uncertainty either way (the second moment of
``u0`` about the as-built value), kept with ``before`` too: a record's level moves by kN with the
deck's temperature field between records hours apart. The surrogate also carries a
model ``discrepancy`` beyond the calibrated settlements (``model.surrogate_file.Discrepancy``).
``prior_sensitivity`` refits the explanations under every prior set of
``model.parameters.PRIOR_SETS`` and says which explanation wins under each; with ``choose:
average`` the surrogate is then the model average over the explanations under every prior set
not chosen after the data (``prior_set_members``), so that where one prior is centred does not
decide it, and the spread between the sets is in ``model_uncertainty``.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow import __version__
from bridge_shadow.calibrate.change import (
    MeasuredChange,
    RecordLevel,
    SunBaseline,
    measured_change,
    record_level,
)
from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.calibrate.explain import (
    Explanation,
    common_and_differential,
    data_misfit,
    data_misfit_text,
    fit_explanation,
    in_sample_readings,
)
from bridge_shadow.calibrate.forward import ForwardModel, SolutionStore
from bridge_shadow.calibrate.problem import PairData
from bridge_shadow.calibrate.records import load_record
from bridge_shadow.calibrate.spec import CalibrationSpec
from bridge_shadow.engine import Mapper
from bridge_shadow.model.config import BridgeConfig, load_bridge_config
from bridge_shadow.model.parameters import (
    PRIOR_SETS,
    Parameter,
    defensible_prior_sets,
    outside_plausible,
    prior_table,
)
from bridge_shadow.model.surrogate import SENSITIVITY_PARAMETERS, SurrogateRun, compute_surrogate
from bridge_shadow.model.surrogate_file import MODEL_UNCERTAINTY_ORDER_FULL, THERMAL_CASES, Discrepancy
from bridge_shadow.paths import repo_root

__all__ = [
    "CalibrationResult",
    "calibrate",
    "evidence_weights",
    "measure_pairs",
    "model_average",
    "prior_sensitivity",
    "prior_set_fits",
    "prior_set_members",
]

Progress = Callable[[float, str], None]


@dataclass
class CalibrationResult:
    """Everything a calibration found.

    Attributes:
        spec: the input. pairs: measured pairs. reference: the reference record's level (or None)
        and its reactions (2,) N. explanations: name -> fitted explanation, in the file's order.
        chosen: name of the explanation written to the surrogate. run: the calibrated surrogate
        (FE re-solved at the chosen MAP). store: FE solves. seconds: wall time.

    """

    spec: CalibrationSpec
    pairs: list[PairData]
    reference_level: RecordLevel | None
    reference_n: np.ndarray | None
    explanations: dict[str, Explanation]
    chosen: str
    run: SurrogateRun
    store: SolutionStore
    seconds: float
    extra: dict[str, Any] = field(default_factory=dict)

    def table(self) -> list[dict[str, Any]]:
        """Evidence table rows, best first, with ``delta_log_evidence`` and ``probability``."""
        rows = [e.summary(self.reference_n) for e in self.explanations.values()]
        best = max(r["log_evidence"] for r in rows)
        w = np.exp(np.array([r["log_evidence"] - best for r in rows]))
        for r, wi in zip(rows, w / w.sum(), strict=True):
            r["delta_log_evidence"] = r["log_evidence"] - best
            r["probability"] = float(wi)
        return sorted(rows, key=lambda r: -r["log_evidence"])

    def mixture_cov(self) -> np.ndarray:
        """(12, 12) second moment of the model vector about the chosen one's over all explanations.

        Evidence-weighted: ``sum_k w_k (C_k + (m_k - m*)(m_k - m*)')``, so the spread between
        explanations (which the data cannot tell apart) is in it, not only each one's posterior;
        over the members the written average ran over (``prior_set_members``, when it ran over
        the prior sets too).
        """
        m_star = self.explanations[self.chosen].model_vector()
        return model_average(self.extra.get("members") or self.explanations, about=m_star)[1]

    def weights(self) -> dict[str, float]:
        """Posterior probability of each explanation (equal prior odds)."""
        return evidence_weights(self.explanations)

    def to_dict(self) -> dict[str, Any]:
        """Return the ``--json`` object (SI): surrogate, measured changes, evidence table, posterior."""
        chosen = self.explanations[self.chosen]
        doc = self.run.document()
        table = self.table()
        bad = self.misfit(table)
        return {
            "surrogate": doc,
            "chosen": self.chosen,
            "written": "model average" if self.spec.choose == "average" else self.chosen,
            "model_average": self.extra.get("model_average"),
            "prior_sensitivity": self.extra.get("prior_sensitivity"),
            "measured": {p.name: p.change.to_dict() for p in self.pairs},
            "explanations": table,
            "identifiability": chosen.identifiability(),
            "in_sample": self.written_in_sample(),
            "reference": self._reference_dict(),
            "misfit": bad,
            "warnings": [data_misfit_text(bad)] if bad is not None else [],
            "fe_solves": self.store.solves,
            "seconds": self.seconds,
        }

    def misfit(self, table: list[dict[str, Any]] | None = None) -> dict[str, Any] | None:
        """Return the most probable explanation's misfit of the measured changes (None: it fits).

        ``explain.data_misfit``: beyond their uncertainty at its MAP. The evidence ranks the
        explanations against each other; a pair given with the wrong sign was explained at
        probability 1.00 by the best of several that all fail (chi2 112.7 on 6).
        """
        best = (table or self.table())[0]  # ``table``: ``table()`` when already built
        return data_misfit(best["name"], best["chi2_data"], self.explanations[best["name"]].problem.n_data)

    def written_in_sample(self) -> list[dict[str, Any]]:
        """Per pair: ``x = A^-1 dR`` (m) through the written surrogate against the imposed settlement."""
        return in_sample_readings(self.run.surrogate.A, self.pairs)

    def _reference_dict(self) -> dict[str, Any] | None:
        if self.reference_n is None:
            return None
        return {
            "name": self.spec.reference_name,
            "reactions_n": self.reference_n.tolist(),
            "implied": {k: e.implied(self.reference_n) for k, e in self.explanations.items()},
        }


def _record_level(paths: list[str], spec: CalibrationSpec, dated: bool = True) -> RecordLevel:
    return record_level(load_record(paths, spec.base_dir, dated=dated), window_s=spec.window_s)


def measure_pairs(
    spec: CalibrationSpec, report: Progress | None = None, sun: SunBaseline | None = None
) -> list[PairData]:
    """Read every pair's records and measure its change (car-free levels, noise, baseline change).

    ``sun``: the model's vertical-difference response and prior, for ``baseline_change: sun``.
    """
    out = []
    for i, p in enumerate(spec.pairs):
        if report is not None:
            report(i / max(len(spec.pairs), 1), f"records {p.name}")
        try:
            change: MeasuredChange = measured_change(
                _record_level(p.before, spec), _record_level(p.after, spec), spec.baseline_change, sun
            )
        except CalibrationError as err:  # which file and pair: its records are the user's to fix
            where = f"{spec.path}: " if spec.path is not None else ""
            raise CalibrationError(f"{where}pair {p.name}: {err}") from None
        out.append(PairData(p.name, p.imposed_m, p.imposed_sd_m, change))
    return out


def _choose(spec: CalibrationSpec, explanations: dict[str, Explanation]) -> str:
    """Return the explanation the FE is re-solved at: the named one, else the most probable."""
    if spec.choose not in ("best", "average"):
        return spec.choose
    return max(explanations, key=lambda k: explanations[k].post.log_evidence)


def _fit_alone(
    name: str,
    spec: CalibrationSpec,
    cfg: BridgeConfig,
    pairs: list[PairData],
    priors: Mapping[str, Parameter] | None = None,
) -> tuple[Explanation, int, float]:
    """Fit one explanation with FE solves of its own; return it and its solves and their seconds."""
    store = SolutionStore()
    fit = fit_explanation(name, spec.explanations[name], cfg, spec.mesh, pairs, store, priors=priors)
    return fit, store.solves, store.seconds


def evidence_weights(explanations: dict[str, Explanation]) -> dict[str, float]:
    """Posterior probability of each explanation from its Laplace evidence (equal prior odds)."""
    logz = np.array([e.post.log_evidence for e in explanations.values()])
    w = np.exp(logz - logz.max())
    return dict(zip(explanations, (w / w.sum()).tolist(), strict=True))


def model_average(
    explanations: dict[str, Explanation],
    about: np.ndarray | None = None,
    weights: Mapping[str, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Bayesian model average of the explanations' surrogates: mean (12,) and covariance (12, 12).

    ``m = sum_k w_k m_k`` and ``C = sum_k w_k (C_k + (m_k - c)(m_k - c)')`` with ``c = m`` (the
    total covariance of the mixture) or ``about`` (its second moment about another point). Model
    vectors in ``MODEL_UNCERTAINTY_ORDER_FULL`` order. ``weights``: ``w_k`` (summing to one), by
    default the evidence weights (equal prior odds).
    """
    w = dict(weights) if weights is not None else evidence_weights(explanations)
    vecs = {k: e.model_vector() for k, e in explanations.items()}
    mean = sum(w[k] * vecs[k] for k in explanations)
    centre = mean if about is None else np.asarray(about, float)
    cov = np.zeros((12, 12))
    for k, e in explanations.items():
        d = vecs[k] - centre
        cov += w[k] * (e.model_cov() + np.outer(d, d))
    return np.asarray(mean, float), 0.5 * (cov + cov.T)


def _average_summary(
    explanations: dict[str, Explanation], pairs: list[PairData], mean: np.ndarray, cov: np.ndarray
) -> dict[str, Any]:
    """Summarize the model average: weights, A, common/differential stiffness, in-sample readings."""
    a = 0.5 * (mean[:4].reshape(2, 2) + mean[:4].reshape(2, 2).T)
    common, diff = common_and_differential(a)
    sd = np.sqrt(np.diag(cov))
    in_sample = []
    for pr in pairs:
        x = np.linalg.solve(a, pr.change.dR_n)
        in_sample.append({"pair": pr.name, "x_m": x.tolist(), "common_m": float(x.mean())})
    return {
        "weights": evidence_weights(explanations),
        "A": a.tolist(),
        "u0": mean[4:6].tolist(),
        "thermal": {c: mean[6 + 2 * i : 8 + 2 * i].tolist() for i, c in enumerate(THERMAL_CASES)},
        "sd": dict(zip(MODEL_UNCERTAINTY_ORDER_FULL, sd.tolist(), strict=True)),
        "common_stiffness_n_per_m": common.tolist(),
        "differential_stiffness_n_per_m": diff,
        "in_sample": in_sample,
    }


def prior_set_fits(
    spec: CalibrationSpec,
    cfg: BridgeConfig,
    pairs: list[PairData],
    fitted: dict[str, Explanation],
    store: SolutionStore,
    report: Progress | None = None,
) -> dict[str, dict[str, Explanation]]:
    """Every explanation under every prior set of ``PRIOR_SETS`` (set -> explanation -> fit).

    Explanations whose parameters a set leaves unchanged keep their fit (``fitted``, under the
    set in use); the others are refitted under the set's priors.
    """
    out: dict[str, dict[str, Explanation]] = {}
    sets = list(PRIOR_SETS)
    for j, name in enumerate(sets):
        if report is not None:
            report(j / len(sets), f"prior set {name}")
        prior = PRIOR_SETS[name]
        table = prior_table(name)
        exps: dict[str, Explanation] = {}
        for ename, e in fitted.items():
            touched = prior.widen != 1.0 or any(n in prior.changes for n in e.names)
            if name == spec.priors or not touched:
                exps[ename] = e
            else:
                exps[ename] = fit_explanation(
                    ename, e.names, cfg, spec.mesh, pairs, store, heldout=False, priors=table
                )
        out[name] = exps
    return out


def prior_sensitivity(
    spec: CalibrationSpec, pairs: list[PairData], fits: dict[str, dict[str, Explanation]]
) -> list[dict[str, Any]]:
    """Which explanation wins under each prior set of ``PRIOR_SETS`` (the one in use included).

    Per set of ``fits`` (``prior_set_fits``): the evidence table (log Z, probability), the winner,
    and what the model average of that set says (common and differential stiffness, in-sample
    readings).
    """
    out = []
    for name, exps in fits.items():
        prior = PRIOR_SETS[name]
        w = evidence_weights(exps)
        best = max(exps, key=lambda k: exps[k].post.log_evidence)
        top = exps[best].post.log_evidence
        mean, cov = model_average(exps)
        out.append(
            {
                "prior_set": name,
                "description": prior.description,
                "in_use": name == spec.priors,
                "winner": best,
                "explanations": [
                    {
                        "name": k,
                        "log_evidence": e.post.log_evidence,
                        "delta_log_evidence": e.post.log_evidence - top,
                        "probability": w[k],
                    }
                    for k, e in sorted(exps.items(), key=lambda kv: -kv[1].post.log_evidence)
                ],
                "model_average": _average_summary(exps, pairs, mean, cov),
            }
        )
    return out


def prior_set_members(
    fits: dict[str, dict[str, Explanation]], in_use: str
) -> tuple[dict[str, Explanation], dict[str, str]]:
    """Return the members of the model average over explanations and prior sets, and those left out.

    Every explanation under every prior set not chosen after the data
    (``model.parameters.defensible_prior_sets``), keyed ``explanation (set)``: each set equally
    likely beforehand, each explanation within it too, so ``model_average``'s evidence weights
    over the members are the joint posterior (a fit two sets share counts once per set). A fit
    under another set than ``in_use`` whose MAP leaves the plausible range of the sources' table
    (the one ``calibrate`` and ``gap`` share) is left out, with why, as the gap tool's model after
    leaves it out.
    """
    members: dict[str, Explanation] = {}
    left_out: dict[str, str] = {}
    for name in defensible_prior_sets():
        for ename, e in fits[name].items():
            key = f"{ename} ({name})"
            outside = [] if name == in_use else outside_plausible(e.values())
            if outside:
                left_out[key] = f"its fit ({', '.join(outside)}) lies outside the plausible range"
            else:
                members[key] = e
    return members, left_out


def calibrate(
    spec: CalibrationSpec,
    cfg: BridgeConfig | None = None,
    *,
    only: list[str] | None = None,
    report: Progress | None = None,
    mapper: Mapper | None = None,
    sensitivity: bool = False,
    sweeps: bool = False,
) -> CalibrationResult:
    """Run the calibration described by ``spec`` (see the module docstring).

    Args:
        spec: the calibration file's content.
        cfg: the bridge model (default ``config/bridge.yaml``).
        only: fit only these explanations (names of ``spec.explanations``).
        report: progress callback ``(fraction, label)``.
        mapper: fit the explanations with ``mapper(fn, names)`` (``bridge_shadow.engine``, e.g.
            in parallel on Dask); each then has FE solves of its own (no solution is shared
            between explanations, so more solves, the same fits). Default: one after the other,
            sharing solves.
        sensitivity: also refit under every prior set (``prior_sensitivity``; minutes more).
        sweeps: write parameter sweeps into the surrogate (``model.sweeps``; ~20 FE solves).

    """
    t0 = time.perf_counter()
    cfg = cfg if cfg is not None else load_bridge_config()
    names = list(spec.explanations) if not only else only
    unknown = [n for n in names if n not in spec.explanations]
    if unknown:
        raise CalibrationError(
            f"unknown explanation(s) {', '.join(unknown)}; have {', '.join(spec.explanations)}"
        )
    if spec.choose not in ("best", "average") and spec.choose not in names:
        names.append(spec.choose)
    table = prior_table(spec.priors)

    last = [0.0, ""]  # the stage reported last: each FE solve inside it says it again

    def tick(frac: float, label: str) -> None:
        last[:] = [frac, label]
        if report is not None:
            report(frac, label)

    store = SolutionStore(on_solve=lambda: tick(last[0], last[1]))
    sun = None
    if spec.baseline_change == "sun":
        # the sun's change between the records read through the model as built (the FE solve is
        # the one u0_built below reuses); an explanation that changes the stiffness scales it a little
        built = ForwardModel(cfg, spec.mesh, (), store).evaluate({}, derivatives=False)
        sun = SunBaseline(np.asarray(built.thermal["vertical_gradient"], float))
    pairs = measure_pairs(spec, lambda f, s: tick(0.05 * f, s), sun=sun)
    ref_level, ref_n = None, spec.reference_reactions_n
    if spec.reference_record:
        ref_level = _record_level(spec.reference_record, spec, dated=False)  # only its levels enter
        ref_n = ref_level.level_n
    explanations: dict[str, Explanation] = {}
    if mapper is None:
        span = 0.6 if sensitivity else 0.85
        for i, name in enumerate(names):
            tick(0.05 + span * i / len(names), f"explanation {name}")
            explanations[name] = fit_explanation(
                name, spec.explanations[name], cfg, spec.mesh, pairs, store, priors=table
            )
    else:
        tick(0.05, f"{len(names)} explanations")
        fit_one = partial(_fit_alone, spec=spec, cfg=cfg, pairs=pairs, priors=table)
        for name, (fit, solves, seconds) in zip(names, mapper(fit_one, names), strict=True):
            explanations[name] = fit
            store.solves += solves
            store.seconds += seconds
    chosen_name = _choose(spec, explanations)
    chosen = explanations[chosen_name]
    extra: dict[str, Any] = {}
    members: dict[str, Explanation] = explanations
    if sensitivity:
        fits = prior_set_fits(spec, cfg, pairs, explanations, store, lambda f, s: tick(0.65 + 0.25 * f, s))
        extra["prior_sensitivity"] = prior_sensitivity(spec, pairs, fits)
        if spec.choose == "average":  # the spread between the prior sets is the model's too
            members, left_out = prior_set_members(fits, spec.priors)
            extra["prior_sets_averaged"] = {"sets": defensible_prior_sets(), "left_out": left_out}
            extra["members"] = members  # (not written: the fits themselves)
    tick(0.92, f"surrogate at the MAP of {chosen_name}")
    cfg_map = cfg.with_overrides(chosen.values())
    sens_names = tuple(dict.fromkeys([*chosen.names, *SENSITIVITY_PARAMETERS]))
    run = compute_surrogate(
        cfg_map, spec.mesh, names=sens_names, sweeps=sweeps, report=lambda f, s: tick(0.92 + 0.07 * f, s)
    )
    mean, cov = model_average(members)
    extra["model_average"] = _average_summary(members, pairs, mean, cov)
    if "prior_sets_averaged" in extra:
        extra["model_average"]["prior_sets"] = extra["prior_sets_averaged"]
    sur = run.surrogate
    u0_built = ForwardModel(cfg, spec.mesh, (), store).evaluate({}, derivatives=False).u0
    if spec.choose == "average":
        a = mean[:4].reshape(2, 2)
        sur.A = 0.5 * (a + a.T)
        sur.thermal = {c: mean[6 + 2 * i : 8 + 2 * i].copy() for i, c in enumerate(THERMAL_CASES)}
        u0_mean = mean[4:6]
    else:
        cov = chosen.model_cov() if chosen.names else np.zeros((12, 12))
        u0_mean = sur.u0
    shift = np.asarray(u0_mean, float) - u0_built  # u0 as built; what moved it, as an uncertainty
    cov = cov.copy()
    cov[4:6, 4:6] += np.outer(shift, shift)
    sur.u0 = u0_built.copy() if spec.zero == "as_built" else _zero_level(pairs)
    sur.model_cov = cov
    sur.discrepancy = Discrepancy.from_steps(np.array([p.imposed_m for p in pairs]))
    result = CalibrationResult(
        spec, pairs, ref_level, ref_n, explanations, chosen_name, run, store, time.perf_counter() - t0, extra
    )
    _provenance(result, cfg)
    tick(1.0, "done")
    return result


def _shown_path(path: Path | str) -> str:
    """Return ``path`` relative to the source checkout when inside it, else absolute.

    The committed surrogate's provenance named the scratch directory the calibration ran from
    (``/tmp/new79/config/calibration.yaml``): a checkout's own file is named as the repository
    holds it, whichever clone ran it.
    """
    full = Path(path).resolve()
    root = repo_root()
    if root is not None and full.is_relative_to(root):
        return full.relative_to(root).as_posix()
    return str(full)


def _zero_level(pairs: list[PairData]) -> np.ndarray:
    """(2,) N, ``u0`` for ``zero: before``: the car-free level of the first pair's before record."""
    before = pairs[0].change.before
    if before is None:
        raise CalibrationError("zero: before needs the first pair's before record (its car-free level)")
    return np.asarray(before.level_n, float).copy()


def _provenance(result: CalibrationResult, cfg: BridgeConfig) -> None:
    """Add the calibration block to the surrogate's provenance (records, posterior, evidence, ...)."""
    spec, chosen = result.spec, result.explanations[result.chosen]
    row = next(r for r in result.table() if r["name"] == result.chosen)
    p = chosen.problem.p
    scale = chosen.problem.scale(chosen.lm.x)  # linearized at the MAP (split-normal priors)
    log_mean = chosen.problem.log_values(chosen.post.mean)
    log_cov = chosen.post.truncated_cov()[:p, :p] * np.outer(scale, scale)
    mix = result.mixture_cov()
    common, diff = common_and_differential(result.run.surrogate.A)
    prov = result.run.surrogate.provenance
    prov["model"] = "config/bridge.yaml + calibration"
    prov["calibration"] = {
        "command": "bridge-shadow calibrate",
        "file": _shown_path(spec.path) if spec.path else None,
        "file_sha256": spec.sha256,
        "bridge_model_sha256": cfg.sha256,
        "mesh": spec.mesh,
        "pairs": [
            {
                "name": ps.name,
                "before": ps.before,
                "after": ps.after,
                "imposed_m": ps.imposed_m.tolist(),
                "imposed_sd_m": ps.imposed_sd_m.tolist(),
                "measured": pd.change.to_dict(),
            }
            for ps, pd in zip(spec.pairs, result.pairs, strict=True)
        ],
        "baseline_change": spec.baseline_change,
        "zero": {
            "before": "x = 0 is the car-free state of the first pair's before record: u0 is its level",
            "as_built": "x = 0 is the as-built FE's dead-load state: u0 is its reactions",
        }[spec.zero],
        "chosen_explanation": result.chosen,
        "choice_rule": {
            "average": "model average over the explanations by their evidence (A, u0, thermal and "
            "model_uncertainty), with --prior-sensitivity under every prior set not chosen after the "
            "data (model_average.prior_sets); the FE sensitivities at the MAP of the chosen (most "
            "probable) one",
            "best": "highest Laplace evidence",
        }.get(spec.choose, "named in the calibration file"),
        "priors": spec.priors,
        "model_average": result.extra.get("model_average"),
        "prior_sensitivity": [
            {k: v for k, v in row.items() if k != "model_average"}
            | {
                "common_stiffness_n_per_m": row["model_average"]["common_stiffness_n_per_m"],
                "differential_stiffness_n_per_m": row["model_average"]["differential_stiffness_n_per_m"],
            }
            for row in result.extra.get("prior_sensitivity") or []
        ]
        or None,
        "parameters": row["map"],
        "posterior_log_mean": dict(zip(chosen.names, log_mean.tolist(), strict=True)),
        "posterior_log_cov": log_cov.tolist(),
        "imposed_error_m": row["imposed_error_m"],
        "identifiability": chosen.identifiability(),
        "in_sample": result.written_in_sample(),
        "chosen_in_sample": chosen.in_sample(),
        "fe_solution_at_chosen_map": {
            "A": result.run.base.A.tolist(),
            "u0": result.run.base.u0.tolist(),
            "thermal": {k: v.tolist() for k, v in result.run.base.thermal.items()},
        },
        "common_stiffness_n_per_m": common.tolist(),
        "differential_stiffness_n_per_m": diff,
        "evidence_table": [
            {
                k: r[k]
                for k in (
                    "name",
                    "parameters",
                    "log_evidence",
                    "delta_log_evidence",
                    "probability",
                    "chi2_data",
                    "heldout_logpdf",
                    "common_stiffness_n_per_m",
                    "differential_stiffness_n_per_m",
                    "imposed_error_m",
                    "in_sample",
                    "reference",
                )
                if k in r
            }
            | {"map": {n: v["map"] for n, v in r["map"].items()}}
            for r in result.table()
        ],
        "model_uncertainty_note": (
            f"model_uncertainty is the covariance of {list(MODEL_UNCERTAINTY_ORDER_FULL)}: with choose "
            "'average' the model average's (each explanation's parameter posterior propagated to the "
            "surrogate plus the spread between the explanations, weighted by their evidence), else "
            "the chosen explanation's own; model_uncertainty_across_explanations is the same "
            "mixture's second moment about the chosen explanation's MAP"
        ),
        "model_uncertainty_across_explanations": mix.tolist(),
        "reference": result._reference_dict(),
        "fe_solves": result.store.solves,
        "seconds": round(result.seconds, 2),
        "package_version": __version__,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }


def default_spec_path() -> Path:
    """``config/calibration.yaml``."""
    from bridge_shadow.paths import config_file

    return config_file("calibration.yaml")
