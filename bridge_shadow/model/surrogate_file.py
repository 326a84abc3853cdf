"""The surrogate ``u = A x + u0`` (+ thermal sensitivities) at rest: load, save, placeholder.

``config/surrogate.yaml`` is written by ``bridge-shadow surrogate`` from the FE model. Until it
exists, ``load_surrogate`` falls back to a documented closed-form placeholder (two equal spans of a
composite beam per girder), flagged in ``provenance.solver == "closed-form placeholder"``.

Keys (DESIGN section 4): ``A`` 2x2 N/m, rows/cols [south, north]; ``u0`` [south, north] N;
``thermal`` map ``uniform``/``vertical_gradient``/``transverse_gradient`` -> [south, north] N/K;
``provenance`` dict. A calibrated surrogate also carries ``model_uncertainty``: the covariance of
``[A11, A12, A21, A22, u0_south, u0_north]`` (6x6, N/m, N) or of those and the three thermal
cases (12x12, ``MODEL_UNCERTAINTY_ORDER_FULL``, N/K) implied by the calibration's posterior over
its explanations, which the shadow adds to its settlement covariance
(``Surrogate.model_covariance``); and ``discrepancy``: a model discrepancy in the sense of
Kennedy and O'Hagan (2001) that is zero on the settlements the calibration saw and grows with the
distance from them (``Discrepancy``), for a model calibrated on one step and used on larger ones.

A file is checked where it is loaded (``load_surrogate`` -> ``check_surrogate``), so every command
and the node refuse a bad one with one line before any work: every number finite, ``A``
symmetric within ``SYMMETRY_RTOL``, positive definite, and conditioned at most ``MAX_CONDITION``
(its condition number is reported: ``Surrogate.condition_number``, the replay JSON, the node's
start-up line); no unknown key.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.errors import ConfigError, InputError
from bridge_shadow.fileio import atomic_write_text, check_output_file, load_yaml, output_file, yaml_problem
from bridge_shadow.keys import check_keys
from bridge_shadow.paths import config_file

__all__ = [
    "DISCREPANCY_CORRELATION",
    "DISCREPANCY_RELATIVE_SD",
    "FILE_KEYS",
    "MAX_CONDITION",
    "MODEL_UNCERTAINTY_ORDER",
    "MODEL_UNCERTAINTY_ORDER_FULL",
    "SYMMETRY_RTOL",
    "THERMAL_CASES",
    "Discrepancy",
    "ModelCovariance",
    "Surrogate",
    "check_surrogate",
    "describe_surrogate",
    "load_surrogate",
    "placeholder_surrogate",
    "read_surrogate_document",
    "save_surrogate",
    "surrogate_target",
]

THERMAL_CASES: tuple[str, str, str] = ("uniform", "vertical_gradient", "transverse_gradient")
#: The top-level keys of a surrogate file (DESIGN 4; ``sensitivities`` from ``model.surrogate``).
FILE_KEYS: tuple[str, ...] = (
    "A",
    "u0",
    "thermal",
    "provenance",
    "model_uncertainty",
    "discrepancy",
    "sensitivities",
    "sweeps",
)
#: The keys ``load_surrogate`` reads (the rest are ``model.sensitivities``' and ``model.sweeps``').
LOADED_KEYS: tuple[str, ...] = ("A", "u0", "thermal", "provenance", "model_uncertainty", "discrepancy")
#: Largest relative asymmetry ``|A12 - A21| / max|A_ij|`` taken as symmetric. ``A`` is a Schur
#: complement of a symmetric stiffness matrix; the FE solves give it symmetric to 3e-13 (the
#: committed surrogates) and the Schur check holds them to 1e-8. An edited or foreign matrix is
#: off by far more (a typo in one off-diagonal digit: 1e-3 or more); 1e-6 is the line between.
SYMMETRY_RTOL = 1.0e-6
#: Largest condition number of ``A`` taken: solving ``x = A^-1 (y - u0)`` loses ``cond * eps``
#: (2.2e-16) of relative accuracy, and at 1e11 that is 2.2e-5, four times finer than the load
#: cells' own resolution (0.02 kN in 234 kN: 8.5e-5). The committed surrogates have 2.0 and 5.2;
#: a spring a thousand times softer than plausible (5e3 N/m) under one bearing gives 1.9e3.
MAX_CONDITION = 1.0e11
#: Order of the entries of ``Surrogate.model_cov`` (A row-major, then u0).
MODEL_UNCERTAINTY_ORDER: tuple[str, ...] = ("A11", "A12", "A21", "A22", "u0_south", "u0_north")
#: The same followed by the thermal cases [south, north] each (``THERMAL_CASES`` order), N/K.
MODEL_UNCERTAINTY_ORDER_FULL: tuple[str, ...] = MODEL_UNCERTAINTY_ORDER + tuple(
    f"{case}_{side}" for case in THERMAL_CASES for side in ("south", "north")
)
#: Relative sd of the response beyond the calibrated settlements (``Discrepancy``). Derivation:
#: a support seats like a Hertzian contact, tangent stiffness ~ R^(1/3) (Johnson, *Contact
#: Mechanics*, 1985, 4.2): from the calibrated state (north reaction 192 kN after 10 mm) to a step
#: three times larger (107 kN after 30 mm) it falls by 1 - (107/192)^(1/3) = 18 %; with the support
#: carrying about half of the compliance (the support-spring explanation of the calibration), the
#: effective stiffness of the extrapolated part changes by ~9 %: 0.10 is that, rounded up.
DISCREPANCY_RELATIVE_SD = 0.10
#: Correlation of the discrepancy between the two supports: one construction (shared seating law)
#: at different loads (the north reaction changes about twice as much): half the variance shared.
DISCREPANCY_CORRELATION = 0.5


@functools.lru_cache(maxsize=8)
def _parsed(path: str, mtime_ns: int, size: int) -> Any:
    return load_yaml(Path(path).read_text(encoding="utf-8"))


def read_surrogate_document(path: str | Path, keys: tuple[str, ...] | None = None) -> Any:
    """Return the parsed YAML of a surrogate file, parsed once per version of the file.

    The surrogate, its ``sensitivities`` and its ``sweeps`` are read from one file by several
    callers; the parse is cached by path, modification time and size, and a deep copy returned
    (callers may change what they get). With ``keys``, a mapping's other top-level entries are
    ``None`` and only those keys' values are copied: ``load_surrogate`` reads six small entries
    beside the sweeps and sensitivities, whose copy was most of a load's time. Raises OSError and
    yaml.YAMLError as reading would.
    """
    import copy

    st = Path(path).stat()
    data = _parsed(str(Path(path).resolve()), st.st_mtime_ns, st.st_size)
    if keys is None or not isinstance(data, dict):
        return copy.deepcopy(data)
    return {k: copy.deepcopy(v) if k in keys else None for k, v in data.items()}


@dataclass(frozen=True)
class Discrepancy:
    """Model discrepancy beyond the calibrated settlements (Kennedy and O'Hagan 2001).

    The surrogate was calibrated on settlements ``x`` with ``low_m <= x <= high_m`` per support
    (0 and the imposed steps of the calibration pairs). Inside that range the secant ``A`` is pinned
    by the data; beyond it the true response may bend (seating, contact, slipping joints). The
    discrepancy of the settlement read from the reactions is ``d = diag(e(x)) rho`` with
    ``e(x) = x - clip(x, low, high)`` the distance beyond the calibrated range (m) and
    ``rho ~ N(0, sd^2 [[1, c], [c, 1]])`` the relative error of the extrapolated part, i.e. a
    Gaussian process with a linear-spline kernel anchored at the calibrated states:
    ``Cov d = diag(e) Sigma_rho diag(e)``.

    Attributes:
        low_m, high_m: (2,) calibrated range per support [south, north], m.
        relative_sd: sd of ``rho`` (``DISCREPANCY_RELATIVE_SD``).
        correlation: correlation of ``rho`` between the supports.

    """

    low_m: tuple[float, float]
    high_m: tuple[float, float]
    relative_sd: float = DISCREPANCY_RELATIVE_SD
    correlation: float = DISCREPANCY_CORRELATION

    def __post_init__(self) -> None:
        lo, hi = np.asarray(self.low_m, float), np.asarray(self.high_m, float)
        if lo.shape != (2,) or hi.shape != (2,) or np.any(lo > hi) or not np.all(np.isfinite([*lo, *hi])):
            raise ConfigError("surrogate discrepancy: need finite low_m <= high_m, [south, north] each")
        if not (self.relative_sd >= 0 and -1 <= self.correlation <= 1):
            raise ConfigError("surrogate discrepancy: relative_sd >= 0 and -1 <= correlation <= 1")

    @classmethod
    def from_steps(cls, steps_m: np.ndarray, **kw: float) -> Discrepancy:
        """Return the calibrated range spanned by 0 and the imposed settlements ``steps_m`` (k, 2) m."""
        x = np.vstack([np.zeros((1, 2)), np.asarray(steps_m, float).reshape(-1, 2)])
        return cls(tuple(x.min(axis=0).tolist()), tuple(x.max(axis=0).tolist()), **kw)  # type: ignore[arg-type]

    def beyond(self, x_m: np.ndarray) -> np.ndarray:
        """(2,) m, ``e(x)``: how far each support's settlement lies beyond the calibrated range."""
        x = np.asarray(x_m, float).reshape(2)
        return x - np.clip(x, self.low_m, self.high_m)

    def covariance(self, x_m: np.ndarray) -> np.ndarray:
        """(2, 2) m^2, ``Cov d`` at settlement ``x_m``."""
        e = self.beyond(x_m)
        sd, c = self.relative_sd, self.correlation
        rho = sd**2 * np.array([[1.0, c], [c, 1.0]])
        return rho * np.outer(e, e)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (SI) for the surrogate file."""
        return {
            "kind": "linear spline beyond the calibrated settlements (Kennedy-O'Hagan)",
            "low_m": list(self.low_m),
            "high_m": list(self.high_m),
            "relative_sd": self.relative_sd,
            "correlation": self.correlation,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Discrepancy:
        """Inverse of ``to_dict``."""
        return cls(
            tuple(float(v) for v in data["low_m"]),  # type: ignore[arg-type]
            tuple(float(v) for v in data["high_m"]),  # type: ignore[arg-type]
            float(data.get("relative_sd", DISCREPANCY_RELATIVE_SD)),
            float(data.get("correlation", DISCREPANCY_CORRELATION)),
        )


@dataclass
class Surrogate:
    """Linear map from central-support settlements to central reactions.

    Attributes:
        A: (2, 2) N/m, generalized stiffness, symmetric positive definite; x positive upward,
            reactions positive in compression, so the diagonal is positive.
        u0: (2,) N, reactions at zero settlement (self-weight + superimposed load).
        thermal: case -> (2,) N/K, reaction change per kelvin of the thermal load case.
        provenance: where the numbers come from (model hash, mesh, solver, seconds, ...).
        model_cov: (6, 6) covariance of ``[A11, A12, A21, A22, u0_south, u0_north]`` (N/m, N), or
            (12, 12) with the thermal cases too (``MODEL_UNCERTAINTY_ORDER_FULL``), from a
            calibration's posterior, or None (the model taken as exact).
        discrepancy: the model discrepancy beyond the calibrated settlements, or None.

    """

    A: np.ndarray
    u0: np.ndarray
    thermal: dict[str, np.ndarray] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    model_cov: np.ndarray | None = None
    discrepancy: Discrepancy | None = None

    def __post_init__(self) -> None:
        self.A = np.asarray(self.A, dtype=float).reshape(2, 2)
        self.u0 = np.asarray(self.u0, dtype=float).reshape(2)
        self.thermal = {k: np.asarray(v, dtype=float).reshape(2) for k, v in self.thermal.items()}
        if self.model_cov is None and self.discrepancy is not None:
            self.model_cov = np.zeros((6, 6))  # the shadow adds model_covariance when model_cov is set
        if self.model_cov is not None:
            cov = np.asarray(self.model_cov, dtype=float)
            n = 12 if cov.size == 144 else 6
            cov = cov.reshape(n, n)
            if not np.all(np.isfinite(cov)) or np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() < -1e-9 * max(
                float(np.abs(cov).max()), 1e-300
            ):
                raise ConfigError("surrogate model_uncertainty: covariance must be finite and PSD")
            self.model_cov = 0.5 * (cov + cov.T)

    def model_covariance(self, x_m: np.ndarray, with_u0: bool = True) -> np.ndarray:
        """Settlement covariance (2, 2) m^2 from the model's own uncertainty at settlement ``x_m``.

        Linearized: ``x = A^-1 (y - u0)``, so ``dx = -A^-1 (dA x + du0) = -A^-1 J dtheta`` with
        ``J = [kron(I2, x^T), I2]`` (2 x 6) and ``dtheta`` the perturbation of
        ``[A11, A12, A21, A22, u0_south, u0_north]``; the result is ``A^-1 J C J^T A^-T``.
        ``with_u0=False`` leaves ``du0`` out: the uncertainty of a *change* of settlement ``x_m``
        (a step), in which ``u0`` cancels. Plus the ``discrepancy`` beyond the calibrated
        settlements (a step read as a change from 0). Zero when the surrogate carries neither.
        """
        cov = np.zeros((2, 2))
        if self.model_cov is not None:
            x0, x1 = np.asarray(x_m, dtype=float).reshape(2).tolist()
            u = 1.0 if with_u0 else 0.0
            # J = [kron(I2, x^T), I2], written out: this runs for every window output
            jac = np.array([[x0, x1, 0.0, 0.0, u, 0.0], [0.0, 0.0, x0, x1, 0.0, u]])
            g = np.linalg.solve(self.A, jac)  # A^-1 J
            cov = g @ self.model_cov[:6, :6] @ g.T
        if self.discrepancy is not None:
            cov = cov + self.discrepancy.covariance(np.asarray(x_m, dtype=float).reshape(2))
        return 0.5 * (cov + cov.T)

    def thermal_covariance(self, case: str) -> np.ndarray:
        """(2, 2) (N/K)^2, the covariance of ``thermal[case]`` (zeros when the file has none)."""
        if self.model_cov is None or self.model_cov.shape[0] < 12 or case not in THERMAL_CASES:
            return np.zeros((2, 2))
        i = 6 + 2 * THERMAL_CASES.index(case)
        return self.model_cov[i : i + 2, i : i + 2].copy()

    @property
    def condition_number(self) -> float:
        """2-norm condition number of ``A`` (largest over smallest singular value); inf if singular."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return float(np.linalg.cond(self.A)) if np.all(np.isfinite(self.A)) else float("nan")

    def summary(self) -> dict[str, Any]:
        """Return what a result says of its model: ``A`` (N/m), ``u0`` (N), solver, condition number."""
        return {
            "A": self.A.tolist(),
            "u0": self.u0.tolist(),
            "solver": self.provenance.get("solver", ""),
            "condition_number": self.condition_number,
        }

    def reactions(self, x_m: np.ndarray) -> np.ndarray:
        """Return ``A x + u0`` for settlements ``x_m`` of shape (..., 2) in m; N."""
        return np.asarray(x_m, float) @ self.A.T + self.u0

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form with the contract keys (lists, SI units)."""
        out = {
            "A": self.A.tolist(),
            "u0": self.u0.tolist(),
            "thermal": {k: v.tolist() for k, v in self.thermal.items()},
            "provenance": dict(self.provenance),
        }
        if self.model_cov is not None:
            order = MODEL_UNCERTAINTY_ORDER_FULL if self.model_cov.shape[0] == 12 else MODEL_UNCERTAINTY_ORDER
            out["model_uncertainty"] = {"order": list(order), "covariance": self.model_cov.tolist()}
        if self.discrepancy is not None:
            out["discrepancy"] = self.discrepancy.to_dict()
        return out


class ModelCovariance:
    """``Surrogate.model_covariance(x)`` (with ``u0``) on plain floats: the per-window hot path.

    The covariance is a quadratic form in ``v = (x_s, x_n, 1)``: with ``A^-1 J = [G_0 v; G_1 v]``
    (``G_i`` 6 x 3, fixed by ``A^-1``), ``cov_ij = v' G_i' C G_j v`` and the three 3 x 3 matrices
    ``G_i' C G_j`` are computed once. The discrepancy term is added on floats. The surrogate must
    not change afterwards (the shadow holds one for its lifetime); ``test_model_uncertainty``
    checks it against ``Surrogate.model_covariance``.
    """

    def __init__(self, surrogate: Surrogate) -> None:
        self._forms: tuple[tuple[float, ...], ...] | None = None
        if surrogate.model_cov is not None:
            a_inv = np.linalg.inv(surrogate.A)
            g = np.zeros((2, 6, 3))
            for i in range(2):
                g[i, 0, 0] = g[i, 1, 1] = g[i, 4, 2] = a_inv[i, 0]
                g[i, 2, 0] = g[i, 3, 1] = g[i, 5, 2] = a_inv[i, 1]
            c = surrogate.model_cov[:6, :6]
            q = [g[i].T @ c @ g[j] for i, j in ((0, 0), (0, 1), (1, 1))]
            self._forms = tuple(tuple(float(v) for v in np.ravel(0.5 * (m + m.T))) for m in q)
        d = surrogate.discrepancy
        self._disc: tuple[float, ...] | None = None
        if d is not None:
            rho = d.relative_sd**2
            self._disc = (*map(float, d.low_m), *map(float, d.high_m), rho, rho * d.correlation)

    def __call__(self, x0: float, x1: float) -> tuple[float, float, float]:
        """``(c00, c01, c11)`` m^2 at settlement ``(x0, x1)`` m."""
        c00 = c01 = c11 = 0.0
        if self._forms is not None:
            v = (x0, x1, 1.0)
            out = []
            for f in self._forms:
                out.append(
                    v[0] * (f[0] * v[0] + f[1] * v[1] + f[2] * v[2])
                    + v[1] * (f[3] * v[0] + f[4] * v[1] + f[5] * v[2])
                    + v[2] * (f[6] * v[0] + f[7] * v[1] + f[8] * v[2])
                )
            c00, c01, c11 = out
        if self._disc is not None:
            lo0, lo1, hi0, hi1, rho, rho_c = self._disc
            e0 = x0 - min(max(x0, lo0), hi0)
            e1 = x1 - min(max(x1, lo1), hi1)
            c00 += rho * e0 * e0
            c01 += rho_c * e0 * e1
            c11 += rho * e1 * e1
        return c00, c01, c11


def placeholder_surrogate() -> Surrogate:
    """Closed-form stand-in used only while no FE surrogate file exists.

    Each girder is two equal spans ``L = 15 m`` with a composite bending stiffness
    ``EI = 3.0e9 N m^2`` (HEB1000, I = 6.447e-3 m^4, E = 210 GPa, times about 2.2 for the
    composite deck; an assumption). Raising one central bearing by ``x`` adds ``6 EI x / L^3`` to
    its reaction; the deck couples the girders so that the differential mode is 1.5 times stiffer
    than the common mode (assumption), which makes ``A_12`` negative. ``u0 = 5/4 w L`` with
    ``w = 12.5 kN/m`` per girder (DESIGN section 3). A top-warmer gradient of 1 K over the depth
    ``h = 1.2 m`` changes each central reaction by ``-3 EI alpha / (h L)``; the transverse case
    (south girder 1 K warmer than north) is modelled as half that effect with opposite signs.
    """
    ei, span, depth, alpha = 3.0e9, 15.0, 1.2, 1.2e-5
    k_common = 6.0 * ei / span**3
    k_diff = 1.5 * k_common
    a_matrix = 0.5 * np.array(
        [[k_common + k_diff, k_common - k_diff], [k_common - k_diff, k_common + k_diff]]
    )
    w = 12.5e3
    u0 = np.full(2, 1.25 * w * span)
    grad = -3.0 * ei * alpha / (depth * span)
    thermal = {
        "uniform": np.zeros(2),
        "vertical_gradient": np.full(2, grad),
        "transverse_gradient": np.array([-0.5 * grad, 0.5 * grad]),
    }
    provenance = {
        "solver": "closed-form placeholder",
        "note": "two-span beam formulas; run `bridge-shadow surrogate` for the FE surrogate",
    }
    return Surrogate(a_matrix, u0, thermal, provenance)


def load_surrogate(path: str | Path | None = None, *, allow_placeholder: bool = True) -> Surrogate:
    """Load a surrogate YAML file (default ``config/surrogate.yaml``).

    Falls back to ``placeholder_surrogate()`` when the default file does not exist and
    ``allow_placeholder`` is set; an explicit path that does not exist is an error.
    """
    explicit = path is not None
    file = Path(path) if explicit else config_file("surrogate.yaml")
    if file.is_dir():
        raise ConfigError(f"{file}: is a directory, not a surrogate file")
    if file.exists() and not file.is_file():  # /dev/null, a pipe: there, but no surrogate file
        raise ConfigError(f"{file}: not a regular file, so not a surrogate file")
    if not file.is_file():
        if explicit or not allow_placeholder:
            # a relative path (surrogate_path in a parameter file) is read from the working directory
            where = "" if file.is_absolute() else f" (a relative path, read from {Path.cwd()})"
            raise ConfigError(f"{file}: surrogate file not found{where}")
        return placeholder_surrogate()
    try:
        data = read_surrogate_document(file, LOADED_KEYS)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as err:
        raise ConfigError(f"{file}: not a valid surrogate file ({yaml_problem(err)})") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: not a valid surrogate file (expected a mapping with A and u0)")
    check_keys(data, FILE_KEYS, f"{file}")
    check_keys(data.get("thermal") or {}, THERMAL_CASES, f"{file}: thermal")
    try:
        unc = data.get("model_uncertainty") or {}
        orders = (list(MODEL_UNCERTAINTY_ORDER), list(MODEL_UNCERTAINTY_ORDER_FULL))
        if unc and list(unc.get("order", [])) not in orders:
            raise ValueError(f"model_uncertainty.order must be {orders[0]} or {orders[1]}")
        disc = data.get("discrepancy")
        surrogate = Surrogate(
            A=data["A"],
            u0=data["u0"],
            thermal=data.get("thermal", {}),
            provenance=data.get("provenance", {}),
            model_cov=unc.get("covariance") if unc else None,
            discrepancy=Discrepancy.from_dict(disc) if disc else None,
        )
    except (KeyError, TypeError, ValueError, AttributeError) as err:
        raise ConfigError(f"{file}: not a valid surrogate file ({err})") from None
    check_surrogate(surrogate, str(file))
    return surrogate


def describe_surrogate(surrogate: Surrogate, path: str | Path | None = None) -> str:
    """Say for people which surrogate is in use: its file (``path``, else the default), solver, condition.

    ``path`` is what ``load_surrogate`` was given (None: ``config/surrogate.yaml``, or the
    closed-form placeholder when that file does not exist).
    """
    if path:
        source = str(path)
    elif config_file("surrogate.yaml").is_file():
        source = str(config_file("surrogate.yaml"))
    else:
        source = "none found: the closed-form placeholder"
    solver = surrogate.provenance.get("solver", "")
    cond = f"condition number of A {surrogate.condition_number:.3g}"
    return f"{source} ({solver + ', ' if solver else ''}{cond})"


def check_surrogate(surrogate: Surrogate, where: str = "surrogate") -> float:
    """Check that a surrogate can carry an estimate; return the condition number of ``A``.

    Raises ConfigError (one line naming ``where`` and the problem) when a number is not finite,
    ``A`` is not symmetric within ``SYMMETRY_RTOL``, not positive definite (a settlement that
    changes no reaction, or lifts one by pushing down), or conditioned worse than
    ``MAX_CONDITION``.
    """
    a = surrogate.A
    numbers = {"A": a, "u0": surrogate.u0, **{f"thermal.{k}": v for k, v in surrogate.thermal.items()}}
    for name, value in numbers.items():
        if not np.all(np.isfinite(value)):
            raise ConfigError(f"{where}: {name} must be finite, not {np.asarray(value).tolist()}")
    scale = float(np.abs(a).max())
    asym = abs(float(a[0, 1] - a[1, 0])) / scale if scale > 0 else 0.0
    if asym > SYMMETRY_RTOL:
        raise ConfigError(
            f"{where}: A must be symmetric (a Schur complement of a stiffness matrix): A12 {a[0, 1]:.6g} "
            f"and A21 {a[1, 0]:.6g} N/m differ by {asym:.1e} of max|A|, more than {SYMMETRY_RTOL:g}"
        )
    low, high = np.linalg.eigvalsh(0.5 * (a + a.T))
    if not low > 0:
        raise ConfigError(
            f"{where}: A must be positive definite; its eigenvalues are {low:.6g} and {high:.6g} N/m "
            "(a settlement mode that no reaction feels, or one that lifts a reaction by lowering it)"
        )
    cond = high / low
    if cond > MAX_CONDITION:
        raise ConfigError(
            f"{where}: A is too ill-conditioned to solve for settlements: condition number {cond:.3g} "
            f"(at most {MAX_CONDITION:g}; eigenvalues {low:.6g} and {high:.6g} N/m)"
        )
    return float(cond)


def save_surrogate(
    surrogate: Surrogate,
    path: str | Path,
    header: str = "",
    *,
    force: bool = False,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Write the surrogate as YAML (atomic: temp file + rename); return the path.

    Checked first (``check_surrogate``): a surrogate that could not be loaded is never written.
    ``header`` lines become comments on top; ``extra`` adds keys of ``FILE_KEYS`` (the FE run's
    ``sensitivities``); ``force`` replaces an existing surrogate file (see ``surrogate_target``).
    """
    check_surrogate(surrogate, f"{path}: refusing to write a surrogate whose")
    file = surrogate_target(path, force=force)
    text = "".join(line if line.startswith("#") else f"# {line}" for line in header.splitlines(True))
    if text and not text.endswith("\n"):
        text += "\n"
    text += yaml.safe_dump({**surrogate.to_dict(), **(extra or {})}, sort_keys=False, default_flow_style=None)
    return atomic_write_text(file, text, "surrogate file")


def surrogate_target(path: str | Path, *, create: bool = True, force: bool = False) -> Path:
    """Check that a surrogate may be written at ``path``; return it as a Path.

    A new file may be written; an existing surrogate file (keys ``A`` and ``u0``) only with
    ``force`` (``--force``); anything else at that path (a directory, a parameter file, a bag's
    metadata) never: one InputError line, so a mistyped ``--out`` never replaces a user's file.
    ``create`` makes the file's directory (False: only check, as a command does before its work).
    """
    file = output_file(path, "surrogate file") if create else check_output_file(path, "surrogate file")
    if file.exists():
        try:
            data = load_yaml(file.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            data = None
        if not (isinstance(data, dict) and "A" in data and "u0" in data):
            raise InputError(f"{file}: exists and is not a surrogate file; refusing to overwrite it")
        if not force:
            raise InputError(f"{file}: exists already; pass --force to replace it")
    return file
