"""The surrogate ``u = A x + u0`` (+ thermal sensitivities) at rest: load, save, placeholder.

``config/surrogate.yaml`` is written by ``bridge-shadow surrogate`` from the FE model. Until it
exists, ``load_surrogate`` falls back to a documented closed-form placeholder (two equal spans of a
composite beam per girder), flagged in ``provenance.solver == "closed-form placeholder"``.

Keys (DESIGN section 4): ``A`` 2x2 N/m, rows/cols [south, north]; ``u0`` [south, north] N;
``thermal`` map ``uniform``/``vertical_gradient``/``transverse_gradient`` -> [south, north] N/K;
``provenance`` dict. A calibrated surrogate also carries ``model_uncertainty``: the covariance
(6x6) of ``[A11, A12, A21, A22, u0_south, u0_north]`` implied by the parameter posterior (N/m, N),
which the shadow adds to its settlement covariance (``Surrogate.model_covariance``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.errors import ConfigError, InputError
from bridge_shadow.fileio import atomic_write_text, check_output_file, output_file
from bridge_shadow.paths import config_file

__all__ = [
    "MODEL_UNCERTAINTY_ORDER",
    "THERMAL_CASES",
    "Surrogate",
    "load_surrogate",
    "placeholder_surrogate",
    "save_surrogate",
    "surrogate_target",
]

THERMAL_CASES: tuple[str, str, str] = ("uniform", "vertical_gradient", "transverse_gradient")
#: Order of the entries of ``Surrogate.model_cov`` (A row-major, then u0).
MODEL_UNCERTAINTY_ORDER: tuple[str, ...] = ("A11", "A12", "A21", "A22", "u0_south", "u0_north")


@dataclass
class Surrogate:
    """Linear map from central-support settlements to central reactions.

    Attributes:
        A: (2, 2) N/m, generalized stiffness, symmetric positive definite; x positive upward,
            reactions positive in compression, so the diagonal is positive.
        u0: (2,) N, reactions at zero settlement (self-weight + superimposed load).
        thermal: case -> (2,) N/K, reaction change per kelvin of the thermal load case.
        provenance: where the numbers come from (model hash, mesh, solver, seconds, ...).
        model_cov: (6, 6) covariance of ``[A11, A12, A21, A22, u0_south, u0_north]`` (N/m, N) from
            a calibration's parameter posterior, or None (the model taken as exact).

    """

    A: np.ndarray
    u0: np.ndarray
    thermal: dict[str, np.ndarray] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict)
    model_cov: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.A = np.asarray(self.A, dtype=float).reshape(2, 2)
        self.u0 = np.asarray(self.u0, dtype=float).reshape(2)
        self.thermal = {k: np.asarray(v, dtype=float).reshape(2) for k, v in self.thermal.items()}
        if self.model_cov is not None:
            cov = np.asarray(self.model_cov, dtype=float).reshape(6, 6)
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
        (a step), in which ``u0`` cancels. Zero when the surrogate carries no ``model_cov``.
        """
        if self.model_cov is None:
            return np.zeros((2, 2))
        x0, x1 = np.asarray(x_m, dtype=float).reshape(2).tolist()
        u = 1.0 if with_u0 else 0.0
        # J = [kron(I2, x^T), I2], written out: this runs for every window output
        jac = np.array([[x0, x1, 0.0, 0.0, u, 0.0], [0.0, 0.0, x0, x1, 0.0, u]])
        g = np.linalg.solve(self.A, jac)  # A^-1 J
        cov = g @ self.model_cov @ g.T
        return 0.5 * (cov + cov.T)

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
            out["model_uncertainty"] = {
                "order": list(MODEL_UNCERTAINTY_ORDER),
                "covariance": self.model_cov.tolist(),
            }
        return out


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
    if not file.is_file():
        if explicit or not allow_placeholder:
            raise ConfigError(f"{file}: surrogate file not found")
        return placeholder_surrogate()
    try:
        data = yaml.safe_load(file.read_text())
        unc = data.get("model_uncertainty") or {}
        if unc and list(unc.get("order", [])) != list(MODEL_UNCERTAINTY_ORDER):
            raise ValueError(f"model_uncertainty.order must be {list(MODEL_UNCERTAINTY_ORDER)}")
        return Surrogate(
            A=data["A"],
            u0=data["u0"],
            thermal=data.get("thermal", {}),
            provenance=data.get("provenance", {}),
            model_cov=unc.get("covariance") if unc else None,
        )
    except (yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError) as err:
        raise ConfigError(f"{file}: not a valid surrogate file ({err})") from err


def save_surrogate(surrogate: Surrogate, path: str | Path, header: str = "") -> Path:
    """Write the surrogate as YAML (atomic: temp file + rename); return the path."""
    file = surrogate_target(path)
    text = "".join(f"# {line}\n" for line in header.splitlines())
    text += yaml.safe_dump(surrogate.to_dict(), sort_keys=False, default_flow_style=None)
    return atomic_write_text(file, text, "surrogate file")


def surrogate_target(path: str | Path, *, create: bool = True) -> Path:
    """Check that a surrogate may be written at ``path``; return it as a Path.

    A new file, or an existing surrogate file (keys ``A`` and ``u0``), may be written; anything
    else at that path (a directory, a parameter file, a bag's metadata) is refused with one
    InputError line, so a mistyped ``--out`` never replaces a user's file. ``create`` makes the
    file's directory (False: only check, as a command does before its work).
    """
    file = output_file(path, "surrogate file") if create else check_output_file(path, "surrogate file")
    if file.exists():
        try:
            data = yaml.safe_load(file.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            data = None
        if not (isinstance(data, dict) and "A" in data and "u0" in data):
            raise InputError(f"{file}: exists and is not a surrogate file; refusing to overwrite it")
    return file
