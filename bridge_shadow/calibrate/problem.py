"""The calibration problem: measured changes, imposed settlements, priors -> whitened residuals.

For each record pair ``k`` with imposed settlement ``x_k`` (m, [south, north]) the model says

    dR_k = A(theta) (x_k + e_k) + thermal_uniform(theta) dT_k + noise,   noise ~ N(0, Sigma_k)

with ``Sigma_k`` the covariance of the measured change (:mod:`.change`), ``dT_k`` the change of
the air temperature between the records (the model's uniform thermal response: a modelled term,
tiny here) and ``e_k ~ N(0, diag(s_k^2))`` the error of the imposed settlement (the jacks'
accuracy), a nuisance estimated with the parameters. The parameters are ``log theta`` with the
priors of :mod:`bridge_shadow.model.parameters` (or of one of its ``PRIOR_SETS``), kept inside
their plausible ranges (the one table of ranges the gap diagnosis reads too).

Coordinates are whitened: ``log theta = mu + s(u) u`` (each parameter's split-normal prior,
``Parameter.to_log``) and ``e / s``; the residual stacks
``L_k^-1 (dR_k - model_k)`` (``Sigma_k = L_k L_k'``) and the prior rows ``u``. One pair gives two
numbers: at most two combinations of the parameters and jack errors are fixed by it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.calibrate.change import MeasuredChange
from bridge_shadow.calibrate.forward import Evaluation, ForwardModel
from bridge_shadow.model.parameters import Parameter, parameter

__all__ = ["CalibrationProblem", "PairData"]


@dataclass
class PairData:
    """One before/after record pair.

    Attributes:
        name: label. imposed_m: (2,) m, imposed settlement (positive up) [south, north].
        imposed_sd_m: (2,) m, its standard deviation (the jacks' accuracy).
        change: the measured reaction change.

    """

    name: str
    imposed_m: np.ndarray
    imposed_sd_m: np.ndarray
    change: MeasuredChange

    def __post_init__(self) -> None:
        self.imposed_m = np.asarray(self.imposed_m, float).reshape(2)
        self.imposed_sd_m = np.asarray(self.imposed_sd_m, float).reshape(2)


@dataclass
class CalibrationProblem:
    """Whitened residuals and Jacobian of the calibration (see the module docstring).

    Attributes:
        forward: the FE forward model (its ``names`` are the calibrated parameters).
        pairs: the record pairs.
        priors: parameter table (default ``model.parameters.PARAMETERS``; a ``prior_table``).
        mu: (p,) prior median of ``log theta``. lower, upper: (n,) bounds in whitened
            coordinates: the plausible ranges; jack coordinates unbounded. ``scale(u)``: the
            derivative of ``log theta`` per whitened coordinate (the prior sd on ``u``'s side).
        last: the evaluation at the last point asked for.

    """

    forward: ForwardModel
    pairs: Sequence[PairData]
    priors: Mapping[str, Parameter] | None = None
    mu: np.ndarray = field(init=False)
    lower: np.ndarray = field(init=False)
    upper: np.ndarray = field(init=False)
    _white: list[np.ndarray] = field(init=False, repr=False)
    _prior: list[Parameter] = field(init=False, repr=False)
    last: Evaluation | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        priors = [parameter(n, self.priors) for n in self.names]
        self._prior = priors
        self.mu = np.array([p.log_centre for p in priors])
        box = np.array([p.whitened_bounds() for p in priors]).reshape(-1, 2)
        free = [np.inf] * (2 * len(self.pairs))
        self.lower = np.concatenate([box[:, 0], -np.array(free)])
        self.upper = np.concatenate([box[:, 1], free])
        self._white = [np.linalg.inv(np.linalg.cholesky(pr.change.cov_n2)) for pr in self.pairs]

    @property
    def names(self) -> tuple[str, ...]:
        """Calibrated parameter names."""
        return self.forward.names

    @property
    def prior_of(self) -> list[Parameter]:
        """The prior of each calibrated parameter (in ``names`` order)."""
        return list(self._prior)

    def log_values(self, u: np.ndarray) -> np.ndarray:
        """(p,) ``log theta`` at whitened ``u`` (split-normal priors)."""
        return np.array([pr.to_log(v) for pr, v in zip(self._prior, u[: self.p], strict=True)], float)

    def scale(self, u: np.ndarray) -> np.ndarray:
        """(p,) ``d log theta / du`` at whitened ``u``."""
        return np.array([pr.log_scale(v) for pr, v in zip(self._prior, u[: self.p], strict=True)], float)

    @property
    def p(self) -> int:
        """Number of parameters."""
        return len(self.names)

    @property
    def dim(self) -> int:
        """Parameters plus two jack errors per pair."""
        return self.p + 2 * len(self.pairs)

    @property
    def n_data(self) -> int:
        """Measured numbers (two per pair)."""
        return 2 * len(self.pairs)

    def labels(self) -> list[str]:
        """Name of each coordinate."""
        return [
            *self.names,
            *[f"imposed_error_{s}[{pr.name}]" for pr in self.pairs for s in ("south", "north")],
        ]

    def values(self, u: np.ndarray) -> dict[str, float]:
        """Parameter values (SI) at whitened ``u``."""
        return {n: float(v) for n, v in zip(self.names, np.exp(self.log_values(u)), strict=True)}

    def jack_errors(self, u: np.ndarray) -> np.ndarray:
        """(pairs, 2) m, imposed-settlement errors at whitened ``u``."""
        e = u[self.p :].reshape(-1, 2)
        return e * np.array([pr.imposed_sd_m for pr in self.pairs])

    def logdet_data_cov(self) -> float:
        """``log det`` of the block-diagonal data covariance (N^2)."""
        return float(sum(np.linalg.slogdet(pr.change.cov_n2)[1] for pr in self.pairs))

    def predicted(self, ev: Evaluation, u: np.ndarray) -> np.ndarray:
        """(pairs, 2) N, the model's reaction change of each pair at ``u``."""
        out = []
        for pr, e in zip(self.pairs, self.jack_errors(u), strict=True):
            dt = pr.change.air_temp_change_k
            thermal = ev.thermal["uniform"] * dt if np.isfinite(dt) else np.zeros(2)
            out.append(ev.A @ (pr.imposed_m + e) + thermal)
        return np.array(out)

    def __call__(self, u: np.ndarray, jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Whitened residuals ``(n_data + dim,)`` and Jacobian ``(n_data + dim, dim)`` (or None) at ``u``."""
        ev = self.forward.evaluate(self.values(u), derivatives=jacobian)
        self.last = ev
        pred = self.predicted(ev, u)
        if not jacobian:
            rows = [
                w @ (pr.change.dR_n - pred[k])
                for k, (pr, w) in enumerate(zip(self.pairs, self._white, strict=True))
            ]
            return np.concatenate([*rows, u]), None
        rows, jac = [], []
        for k, (pr, w) in enumerate(zip(self.pairs, self._white, strict=True)):
            x = pr.imposed_m + self.jack_errors(u)[k]
            dt = pr.change.air_temp_change_k
            dt = dt if np.isfinite(dt) else 0.0
            d_pred = np.zeros((2, self.dim))
            d_pred[:, : self.p] = (
                np.einsum("qij,j->iq", ev.dA, x) + ev.dthermal["uniform"].T * dt
            ) * self.scale(u)
            d_pred[:, self.p + 2 * k : self.p + 2 * k + 2] = ev.A * pr.imposed_sd_m[None, :]
            rows.append(w @ (pr.change.dR_n - pred[k]))
            jac.append(-w @ d_pred)
        r = np.concatenate([*rows, u])
        J = np.vstack([*jac, np.eye(self.dim)])
        return r, J
