"""What the shadow hands out: one output per closed window, detected events, and a replay's result."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.estimate.gate import MESSAGE_REASONS

__all__ = ["EventRecord", "ReplayResult", "WindowOutput"]


@dataclass
class WindowOutput:
    """What the shadow says after one closed window.

    Attributes:
        index: window number ``k`` (window ``[k W, (k + 1) W)`` in stamp ns).
        end_ns: window end stamp (ns); the stamp of the published outputs.
        samples: (2,) force samples per channel.
        temp_c: (2,) C, mean matched temperature per channel (NaN when unknown).
        force_n: (2,) N, raw window-mean force.
        compensated_n: (2,) N, ``y - g(T) + mean(y)`` with the centred curve (NaN when unused).
        mean_m: (2,) m, posterior settlement mean after this window.
        covariance_m2: (2, 2) m^2, published posterior covariance after this window.
        updated: whether this window joined the estimate.
        reason: ``""`` or why it did not (a key of ``REASONS``).
        event: whether a settlement event starts at this window.

    """

    index: int
    end_ns: int
    samples: np.ndarray
    temp_c: np.ndarray
    force_n: np.ndarray
    compensated_n: np.ndarray
    mean_m: np.ndarray
    covariance_m2: np.ndarray
    updated: bool
    reason: str = ""
    event: bool = False


#: 95 % quantile of the chi-square distribution with 2 degrees of freedom (-2 ln 0.05).
CHI2_2DOF_95 = 5.991464547107979


@dataclass
class EventRecord:
    """A detected settlement event (a step), with its size as the data now say.

    Attributes:
        window: first window index of the new segment (the estimated change time).
        time_ns: start of that window, ns since the epoch (UTC).
        detected_window: window index at which the event was confirmed.
        size_m: (2,) m, settlement change [south, north] (new segment minus the previous one).
        covariance_m2: (2, 2) m^2, covariance of ``size_m``.
        glr: the detector's test statistic at confirmation (chi-square, 2 dof, without a change).
        step_n: (2,) N, the innovation step estimated at confirmation.

    """

    window: int
    time_ns: int
    detected_window: int
    size_m: np.ndarray
    covariance_m2: np.ndarray
    glr: float
    step_n: np.ndarray

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record (SI units)."""
        sd = np.sqrt(np.clip(np.diag(self.covariance_m2), 0.0, None))
        return {
            "time_ns": int(self.time_ns),
            "window": int(self.window),
            "detected_window": int(self.detected_window),
            "size_m": self.size_m.tolist(),
            "covariance_m2": self.covariance_m2.tolist(),
            "sigma_m": sd.tolist(),
            "interval95_m": [
                [float(m - 1.96 * s), float(m + 1.96 * s)] for m, s in zip(self.size_m, sd, strict=True)
            ],
            "supports": list(SUPPORTS),
            "glr": float(self.glr),
            "step_n": self.step_n.tolist(),
            "size_chi2": self.size_chi2(),
            "size_significant95": bool(self.size_chi2() > CHI2_2DOF_95),
        }

    def size_chi2(self) -> float:
        """Squared Mahalanobis distance of the size from no change (chi-square, 2 dof, if none)."""
        try:
            return float(self.size_m @ np.linalg.solve(self.covariance_m2, self.size_m))
        except np.linalg.LinAlgError:
            return float("nan")


@dataclass
class ReplayResult:
    """Result of an offline run (``Shadow.run``); ``to_json`` gives the replay JSON (SI units)."""

    mean_m: np.ndarray
    covariance_m2: np.ndarray
    messages: int
    used: dict[str, int]
    rejected: dict[str, int]
    windows: int
    updates: int
    spline: dict[str, dict[str, float]]
    noise: dict[str, Any]
    outputs: list[WindowOutput] = field(default_factory=list)
    seconds: float = 0.0
    events: list[EventRecord] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    prior: dict[str, Any] = field(default_factory=dict)
    uncompensated_windows: int = 0

    @property
    def messages_per_s(self) -> float:
        """Input messages processed per wall-clock second."""
        return self.messages / self.seconds if self.seconds > 0 else float("inf")

    def history(self) -> dict[str, np.ndarray]:
        """Per-window arrays: end_ns (n,), mean_m (n, 2), covariance_m2 (n, 2, 2), ..."""
        outs = self.outputs
        return {
            "end_ns": np.array([o.end_ns for o in outs], dtype=np.int64),
            "samples": np.array([o.samples for o in outs], dtype=np.int64).reshape(-1, 2),
            "temp_c": np.array([o.temp_c for o in outs]).reshape(-1, 2),
            "force_n": np.array([o.force_n for o in outs]).reshape(-1, 2),
            "compensated_n": np.array([o.compensated_n for o in outs]).reshape(-1, 2),
            "mean_m": np.array([o.mean_m for o in outs]).reshape(-1, 2),
            "covariance_m2": np.array([o.covariance_m2 for o in outs]).reshape(-1, 2, 2),
            "updated": np.array([o.updated for o in outs], dtype=bool),
        }

    def to_json(self) -> dict[str, Any]:
        """Return the replay JSON object (contract keys first)."""
        return {
            "posterior": {
                "mean_m": self.mean_m.tolist(),
                "covariance_m2": self.covariance_m2.tolist(),
                "sigma_m": np.sqrt(np.diag(self.covariance_m2)).tolist(),
                "supports": list(SUPPORTS),
            },
            "messages": {
                "total": self.messages,
                "used": int(sum(self.used.values())),
                "used_by_topic": dict(self.used),
                "rejected": int(sum(v for k, v in self.rejected.items() if k in MESSAGE_REASONS)),
            },
            "rejected": dict(self.rejected),
            "messages_per_s": self.messages_per_s,
            "seconds": self.seconds,
            "windows": {
                "closed": self.windows,
                "updates": self.updates,
                "uncompensated": self.uncompensated_windows,
            },
            "events": [e.to_json() for e in self.events],
            "warnings": list(self.warnings),
            "prior": dict(self.prior),
            "spline": self.spline,
            "noise": self.noise,
        }
