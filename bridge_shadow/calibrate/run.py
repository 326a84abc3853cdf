"""``calibrate``: record pairs with known imposed settlements -> posterior of FE parameters -> surrogate.

Steps (each its own module): read the records and measure the car-free change of each pair with
its covariance (:mod:`.change`); fit every candidate explanation (:mod:`.explain`: projected
Levenberg-Marquardt with FE re-solves and adjoint sensitivities, Laplace posterior and evidence);
choose one (the best evidence unless the file names one); re-solve the FE model at its MAP with the
support springs in the FE itself and write the calibrated surrogate with its sensitivities,
``model_uncertainty`` (the parameter posterior propagated to ``[A, u0]``) and provenance.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow import __version__
from bridge_shadow.calibrate.change import MeasuredChange, RecordLevel, measured_change, record_level
from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.calibrate.explain import Explanation, common_and_differential, fit_explanation
from bridge_shadow.calibrate.forward import SolutionStore
from bridge_shadow.calibrate.problem import PairData
from bridge_shadow.calibrate.records import load_record
from bridge_shadow.calibrate.spec import CalibrationSpec
from bridge_shadow.engine import Mapper
from bridge_shadow.model.config import BridgeConfig, load_bridge_config
from bridge_shadow.model.surrogate import SENSITIVITY_PARAMETERS, SurrogateRun, compute_surrogate
from bridge_shadow.model.surrogate_file import MODEL_UNCERTAINTY_ORDER

__all__ = ["CalibrationResult", "calibrate", "measure_pairs"]

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
        """(6, 6) second moment of ``[A, u0]`` about the chosen values over all explanations.

        Evidence-weighted: ``sum_k w_k (C_k + (m_k - m*)(m_k - m*)')``, so the spread between
        explanations (which the data cannot tell apart) is in it, not only each one's posterior.
        """
        chosen = self.explanations[self.chosen].evaluation
        m_star = np.concatenate([chosen.A.ravel(), chosen.u0])
        logz = np.array([e.post.log_evidence for e in self.explanations.values()])
        w = np.exp(logz - logz.max())
        w /= w.sum()
        out = np.zeros((6, 6))
        for wi, e in zip(w, self.explanations.values(), strict=True):
            d = np.concatenate([e.evaluation.A.ravel(), e.evaluation.u0]) - m_star
            out += wi * (e.model_cov() + np.outer(d, d))
        return 0.5 * (out + out.T)

    def to_dict(self) -> dict[str, Any]:
        """Return the ``--json`` object (SI): surrogate, measured changes, evidence table, posterior."""
        chosen = self.explanations[self.chosen]
        doc = self.run.document()
        return {
            "surrogate": doc,
            "chosen": self.chosen,
            "measured": {p.name: p.change.to_dict() for p in self.pairs},
            "explanations": self.table(),
            "identifiability": chosen.identifiability(),
            "in_sample": chosen.in_sample(),
            "reference": self._reference_dict(),
            "fe_solves": self.store.solves,
            "seconds": self.seconds,
        }

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


def measure_pairs(spec: CalibrationSpec, report: Progress | None = None) -> list[PairData]:
    """Read every pair's records and measure its change (car-free levels, noise, baseline change)."""
    out = []
    for i, p in enumerate(spec.pairs):
        if report is not None:
            report(i / max(len(spec.pairs), 1), f"records {p.name}")
        change: MeasuredChange = measured_change(
            _record_level(p.before, spec), _record_level(p.after, spec), spec.baseline_change
        )
        out.append(PairData(p.name, p.imposed_m, p.imposed_sd_m, change))
    return out


def _choose(spec: CalibrationSpec, explanations: dict[str, Explanation]) -> str:
    if spec.choose != "best":
        return spec.choose
    return max(explanations, key=lambda k: explanations[k].post.log_evidence)


def _fit_alone(
    name: str, spec: CalibrationSpec, cfg: BridgeConfig, pairs: list[PairData]
) -> tuple[Explanation, int, float]:
    """Fit one explanation with FE solves of its own; return it and its solves and their seconds."""
    store = SolutionStore()
    fit = fit_explanation(name, spec.explanations[name], cfg, spec.mesh, pairs, store)
    return fit, store.solves, store.seconds


def calibrate(
    spec: CalibrationSpec,
    cfg: BridgeConfig | None = None,
    *,
    only: list[str] | None = None,
    report: Progress | None = None,
    mapper: Mapper | None = None,
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

    """
    t0 = time.perf_counter()
    cfg = cfg if cfg is not None else load_bridge_config()
    names = list(spec.explanations) if not only else only
    unknown = [n for n in names if n not in spec.explanations]
    if unknown:
        raise CalibrationError(
            f"unknown explanation(s) {', '.join(unknown)}; have {', '.join(spec.explanations)}"
        )
    if spec.choose != "best" and spec.choose not in names:
        names.append(spec.choose)

    def tick(frac: float, label: str) -> None:
        if report is not None:
            report(frac, label)

    pairs = measure_pairs(spec, lambda f, s: tick(0.05 * f, s))
    ref_level, ref_n = None, spec.reference_reactions_n
    if spec.reference_record:
        ref_level = _record_level(spec.reference_record, spec, dated=False)  # only its levels enter
        ref_n = ref_level.level_n
    store = SolutionStore()
    explanations: dict[str, Explanation] = {}
    if mapper is None:
        for i, name in enumerate(names):
            tick(0.05 + 0.85 * i / len(names), f"explanation {name}")
            explanations[name] = fit_explanation(name, spec.explanations[name], cfg, spec.mesh, pairs, store)
    else:
        tick(0.05, f"{len(names)} explanations")
        for name, (fit, solves, seconds) in zip(
            names, mapper(partial(_fit_alone, spec=spec, cfg=cfg, pairs=pairs), names), strict=True
        ):
            explanations[name] = fit
            store.solves += solves
            store.seconds += seconds
    chosen_name = _choose(spec, explanations)
    chosen = explanations[chosen_name]
    tick(0.92, f"surrogate at the MAP of {chosen_name}")
    cfg_map = cfg.with_overrides(chosen.values())
    sens_names = tuple(dict.fromkeys([*chosen.names, *SENSITIVITY_PARAMETERS]))
    run = compute_surrogate(cfg_map, spec.mesh, names=sens_names)
    run.surrogate.model_cov = chosen.model_cov() if chosen.names else None
    result = CalibrationResult(
        spec, pairs, ref_level, ref_n, explanations, chosen_name, run, store, time.perf_counter() - t0
    )
    _provenance(result, cfg)
    tick(1.0, "done")
    return result


def _provenance(result: CalibrationResult, cfg: BridgeConfig) -> None:
    """Add the calibration block to the surrogate's provenance (records, posterior, evidence, ...)."""
    spec, chosen = result.spec, result.explanations[result.chosen]
    row = next(r for r in result.table() if r["name"] == result.chosen)
    p = chosen.problem.p
    log_mean = chosen.problem.mu + chosen.problem.sigma * chosen.post.mean[:p]
    log_cov = chosen.post.truncated_cov()[:p, :p] * np.outer(chosen.problem.sigma, chosen.problem.sigma)
    mix = result.mixture_cov()
    common, diff = common_and_differential(result.run.surrogate.A)
    prov = result.run.surrogate.provenance
    prov["model"] = "config/bridge.yaml + calibration"
    prov["calibration"] = {
        "command": "bridge-shadow calibrate",
        "file": str(spec.path) if spec.path else None,
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
        "chosen_explanation": result.chosen,
        "choice_rule": "highest Laplace evidence"
        if spec.choose == "best"
        else "named in the calibration file",
        "parameters": row["map"],
        "posterior_log_mean": dict(zip(chosen.names, log_mean.tolist(), strict=True)),
        "posterior_log_cov": log_cov.tolist(),
        "imposed_error_m": row["imposed_error_m"],
        "identifiability": chosen.identifiability(),
        "in_sample": chosen.in_sample(),
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
            "model_uncertainty is the chosen explanation's parameter posterior propagated to "
            f"{list(MODEL_UNCERTAINTY_ORDER)}; model_uncertainty_across_explanations adds the "
            "evidence-weighted spread between the explanations (which the data cannot tell apart)"
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
