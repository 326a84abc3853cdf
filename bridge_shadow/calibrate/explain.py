"""One candidate explanation: fit its parameters (with the imposed-settlement errors), evidence, implications.

An explanation is a set of named parameters; all others keep the bridge model's values. Its fit is
the Levenberg-Marquardt MAP of :class:`.problem.CalibrationProblem`, its score the Laplace evidence
(:mod:`.posterior`), and, with two or more record pairs, a held-out score: the log predictive
density of each pair from a fit to the others. What it implies is read off its MAP surrogate: the
common-mode stiffness per bearing ``(A11 + A12, A21 + A22)``, the differential-mode stiffness
``(A11 - A12 - A21 + A22) / 2``, the in-sample settlement ``x = A^-1 dR`` of each pair, and the
settlements ``x = A^-1 (R - u0)`` a reference record's reactions imply.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from bridge_shadow.calibrate.forward import Evaluation, ForwardModel, SolutionStore
from bridge_shadow.calibrate.identifiability import identifiability
from bridge_shadow.calibrate.lm import LMResult, levenberg_marquardt
from bridge_shadow.calibrate.posterior import Laplace, laplace
from bridge_shadow.calibrate.problem import CalibrationProblem, PairData
from bridge_shadow.model.config import BridgeConfig
from bridge_shadow.model.parameters import Parameter, parameter
from bridge_shadow.model.surrogate_file import THERMAL_CASES

__all__ = [
    "MISFIT_PROBABILITY",
    "Explanation",
    "common_and_differential",
    "data_misfit",
    "data_misfit_text",
    "fit_explanation",
    "fit_problem",
    "in_sample_readings",
    "model_vector",
]


def model_vector(ev: Evaluation) -> np.ndarray:
    """(12,) ``[A (row-major), u0, thermal per THERMAL_CASES]`` of an evaluation (N/m, N, N/K)."""
    return np.concatenate([ev.A.ravel(), ev.u0, *(ev.thermal[c] for c in THERMAL_CASES)])


def in_sample_readings(a: np.ndarray, pairs: Sequence[PairData]) -> list[dict[str, Any]]:
    """Per pair: ``x = A^-1 dR`` (m) through ``a`` (2, 2) N/m against the imposed settlement."""
    out = []
    for pr in pairs:
        x = np.linalg.solve(a, pr.change.dR_n)
        common, imposed = float(x.mean()), float(pr.imposed_m.mean())
        out.append(
            {
                "pair": pr.name,
                "x_m": x.tolist(),
                "imposed_m": pr.imposed_m.tolist(),
                "common_m": common,
                "common_error_rel": (common - imposed) / imposed if imposed else float("nan"),
                "differential_m": float(x[0] - x[1]),
            }
        )
    return out


def common_and_differential(a: np.ndarray) -> tuple[np.ndarray, float]:
    """Common-mode stiffness per bearing ``(2,)`` (row sums) and differential-mode stiffness, N/m."""
    return a.sum(axis=1), float((a[0, 0] - a[0, 1] - a[1, 0] + a[1, 1]) / 2.0)


@dataclass
class Explanation:
    """A fitted explanation.

    Attributes:
        name: label. problem: its calibration problem. lm: the optimizer's result. post: the
        Laplace posterior. evaluation: the surrogate and its derivatives at the MAP.
        heldout_logpdf: sum over pairs of the held-out log predictive density (None with one pair).

    """

    name: str
    problem: CalibrationProblem
    lm: LMResult
    post: Laplace
    evaluation: Evaluation
    heldout_logpdf: float | None = None

    @property
    def names(self) -> tuple[str, ...]:
        """Calibrated parameters."""
        return self.problem.names

    def values(self) -> dict[str, float]:
        """MAP parameter values (SI)."""
        return self.problem.values(self.lm.x)

    def model_vector(self) -> np.ndarray:
        """(12,) the MAP surrogate as ``[A11, A12, A21, A22, u0 (2), thermal (3 x 2)]`` (SI)."""
        return model_vector(self.evaluation)

    def model_cov(self) -> np.ndarray:
        """(12, 12) covariance of ``model_vector`` from the parameter posterior.

        Order ``MODEL_UNCERTAINTY_ORDER_FULL``: ``[A11, A12, A21, A22, u0_s, u0_n]`` and the three
        thermal cases. Linearized at the MAP: ``G C G'`` with ``G`` the derivatives per whitened
        parameter and ``C`` the posterior covariance of the parameters (imposed-settlement errors
        marginalized; a parameter held at its bound contributes its truncated spread,
        ``Laplace.truncated_cov``).
        """
        p = self.problem.p
        if p == 0:
            return np.zeros((12, 12))
        ev = self.evaluation
        rows = [ev.dA.reshape(p, 4).T, ev.du0.T, *(ev.dthermal[c].T for c in THERMAL_CASES)]
        g = np.vstack(rows) * self.problem.scale(self.lm.x)[None, :]
        cov = self.post.truncated_cov()[:p, :p]
        out = g @ cov @ g.T
        return 0.5 * (out + out.T)

    def in_sample(self) -> list[dict[str, Any]]:
        """Per pair: ``x = A^-1 dR`` (m) against the imposed settlement, common and differential."""
        return in_sample_readings(self.evaluation.A, self.problem.pairs)

    def implied(self, reactions_n: np.ndarray) -> dict[str, Any]:
        """Settlements ``x = A^-1 (R - u0)`` (m) that reactions ``R`` (2,) N imply; half their difference."""
        x = np.linalg.solve(self.evaluation.A, np.asarray(reactions_n, float) - self.evaluation.u0)
        return {"x_m": x.tolist(), "half_difference_m": float((x[0] - x[1]) / 2.0)}

    def summary(self, reference_n: np.ndarray | None = None) -> dict[str, Any]:
        """One row of the evidence table (SI units)."""
        ev, post, prob = self.evaluation, self.post, self.problem
        common, diff = common_and_differential(ev.A)
        data_rows = prob.n_data
        params = {}
        for i, n in enumerate(prob.names):
            pr = parameter(n, prob.priors)
            to_value = lambda u, i=i: float(np.exp(prob.prior_of[i].to_log(u)))  # noqa: E731
            params[n] = {
                "map": to_value(post.mode[i]),
                "median": to_value(post.q500[i]),
                "low95": to_value(post.lo95[i]),
                "high95": to_value(post.hi95[i]),
                "prior_centre": pr.centre,
                "prior_range": [pr.low, pr.high],
                "plausible_range": list(pr.bounds),
                "posterior_to_prior_sd": float(post.sd[i]),
                "at_bound": bool(post.active[i]),
                "unit": pr.unit,
            }
        jack = prob.jack_errors(self.lm.x)
        jack_sd = post.sd[prob.p :].reshape(-1, 2) * np.array([pr.imposed_sd_m for pr in prob.pairs])
        row: dict[str, Any] = {
            "name": self.name,
            "parameters": list(prob.names),
            "log_evidence": post.log_evidence,
            "evidence_parts": post.parts,
            "chi2_data": float(self.lm.r[:data_rows] @ self.lm.r[:data_rows]),
            "prior_penalty": float(0.5 * self.lm.x @ self.lm.x),
            "heldout_logpdf": self.heldout_logpdf,
            "A": ev.A.tolist(),
            "u0": ev.u0.tolist(),
            "common_stiffness_n_per_m": common.tolist(),
            "differential_stiffness_n_per_m": diff,
            "map": params,
            "imposed_error_m": {
                pr.name: {"map": j.tolist(), "sd": s.tolist()}
                for pr, j, s in zip(prob.pairs, jack, jack_sd, strict=True)
            },
            "in_sample": self.in_sample(),
            "converged": bool(self.lm.converged),
            "iterations": int(self.lm.iterations),
            "evaluations": int(self.lm.evaluations),
        }
        if reference_n is not None:
            row["reference"] = self.implied(reference_n)
        return row

    def identifiability(self) -> dict[str, Any]:
        """SVD report of the whitened data Jacobian at the MAP (see :mod:`.identifiability`)."""
        n = self.problem.n_data
        return identifiability(self.lm.J[:n], self.problem.labels(), self.post.cov)


def _fit(problem: CalibrationProblem) -> tuple[LMResult, Laplace, Evaluation]:
    res = levenberg_marquardt(problem, np.zeros(problem.dim), lower=problem.lower, upper=problem.upper)
    problem(res.x, True)
    ev = problem.last
    assert ev is not None
    post = laplace(
        res.r, res.J, res.x, problem.upper, problem.n_data, problem.logdet_data_cov(), lower=problem.lower
    )
    return res, post, ev


#: Builds the forward model of an explanation from its parameter names (FE by default).
MakeForward = Callable[[tuple[str, ...]], Any]


def _heldout(
    make_forward: MakeForward,
    names: Sequence[str],
    pairs: Sequence[PairData],
    priors: Mapping[str, Parameter] | None = None,
) -> float:
    """Sum over pairs of ``log N(dR_k; prediction from a fit to the other pairs, its covariance)``."""
    total = 0.0
    for k, pr in enumerate(pairs):
        rest = [p for i, p in enumerate(pairs) if i != k]
        prob = CalibrationProblem(make_forward(tuple(names)), rest, priors)
        res, post, ev = _fit(prob)
        x = pr.imposed_m
        dt = pr.change.air_temp_change_k if np.isfinite(pr.change.air_temp_change_k) else 0.0
        mean = ev.A @ x + ev.thermal["uniform"] * dt
        g = (np.einsum("qij,j->iq", ev.dA, x) + ev.dthermal["uniform"].T * dt) * prob.scale(res.x)[None, :]
        cov = pr.change.cov_n2 + ev.A @ np.diag(pr.imposed_sd_m**2) @ ev.A.T
        if prob.p:
            cov = cov + g @ post.truncated_cov()[: prob.p, : prob.p] @ g.T
        resid = pr.change.dR_n - mean
        sign, logdet = np.linalg.slogdet(2 * np.pi * cov)
        total += -0.5 * (logdet + resid @ np.linalg.solve(cov, resid))
        del res, sign
    return float(total)


def fit_problem(name: str, problem: CalibrationProblem, heldout_logpdf: float | None = None) -> Explanation:
    """Fit one explanation given its calibration problem (any forward model with ``evaluate``)."""
    res, post, ev = _fit(problem)
    return Explanation(name, problem, res, post, ev, heldout_logpdf)


def fit_explanation(
    name: str,
    names: Sequence[str],
    cfg: BridgeConfig,
    level: str,
    pairs: Sequence[PairData],
    store: SolutionStore | None = None,
    heldout: bool = True,
    report: Callable[[str], None] | None = None,
    priors: Mapping[str, Parameter] | None = None,
    make_forward: MakeForward | None = None,
) -> Explanation:
    """Fit one explanation (MAP, Laplace posterior and evidence; held-out score with 2+ pairs).

    ``priors``: the parameter table (a ``prior_table``; default the sources). ``make_forward``:
    names -> forward model (default the FE ``ForwardModel`` on ``cfg`` at ``level``, sharing ``store``).
    """
    store = store if store is not None else SolutionStore()
    if make_forward is None:

        def make_forward(n: tuple[str, ...]) -> ForwardModel:
            return ForwardModel(cfg, level, n, store)

    problem = CalibrationProblem(make_forward(tuple(names)), pairs, priors)
    out = fit_problem(name, problem)
    if report is not None:
        report(f"{name}: log evidence {out.post.log_evidence:.2f} after {out.lm.iterations} iterations")
    if heldout and len(pairs) > 1:
        out.heldout_logpdf = _heldout(make_forward, names, pairs, priors)
    return out


#: The probability at which the data's own fit rejects an explanation: one chi-square test of all
#: the whitened measured changes, at the family-wise level of the jacks' test in ``gap.levels``
#: (``MISFIT_SD``: under 1e-3 that any of a few pairs' numbers is so far by chance). Its degrees of
#: freedom are the data's count, not less the fitted parameters: the bound is the looser one.
MISFIT_PROBABILITY = 0.999


def data_misfit(effect: str, chi2_data: float, n_data: int) -> dict[str, Any] | None:
    """Whether explanation ``effect`` leaves the measured changes beyond their uncertainty.

    None when ``chi2_data`` (the whitened data residual's sum of squares at the MAP) is within the
    chi-square bound of ``n_data`` numbers at ``MISFIT_PROBABILITY``. A step given as the total
    since the reference where the change from the record before was meant, or with its sign
    wrong, was "explained" at probability 0.97 with chi2 24.7 on 6 numbers (0.4 with the steps
    right), its posterior's interval missing the truth; in ``calibrate`` a 20 mm pair given as
    +20 mm left chi2 112.7 on 6 and was written as the model.
    """
    from scipy import stats

    bound = float(stats.chi2.ppf(MISFIT_PROBABILITY, max(int(n_data), 1)))
    if not chi2_data > bound:
        return None
    return {
        "effect": effect,
        "kind": "data",
        "chi2_data": float(chi2_data),
        "n_data": int(n_data),
        "bound": bound,
    }


def data_misfit_text(bad: dict[str, Any]) -> str:
    """Return the sentence for ``data_misfit``: what it found and what to check."""
    return (
        f"no explanation fits the measured changes with the imposed steps as given: even {bad['effect']} "
        f"leaves chi2 {bad['chi2_data']:.1f} on {bad['n_data']} numbers (the {MISFIT_PROBABILITY:g} "
        f"bound is {bad['bound']:.1f}). Check each step's sign and size (the change between the records "
        "it lies between, in metres, negative down) and its time before using a model written from it."
    )
