"""What the shadow hands out: one output per closed window, detected events, and a replay's result."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS
from bridge_shadow.timefmt import iso_utc

__all__ = [
    "ChangeRecord",
    "EventRecord",
    "ReplayResult",
    "WindowOutput",
    "rejected_window",
    "split_rejected",
]


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


def _size_json(size_m: np.ndarray, cov: np.ndarray) -> dict[str, Any]:
    """``size_m``, its covariance, sd, 95 % interval and the supports' names (SI)."""
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return {
        "size_m": size_m.tolist(),
        "covariance_m2": cov.tolist(),
        "sigma_m": sd.tolist(),
        "interval95_m": [[float(m - 1.96 * s), float(m + 1.96 * s)] for m, s in zip(size_m, sd, strict=True)],
        "supports": list(SUPPORTS),
    }


def _chi2(size_m: np.ndarray, cov: np.ndarray) -> float:
    try:
        return float(size_m @ np.linalg.solve(cov, size_m))
    except np.linalg.LinAlgError:
        return float("nan")


@dataclass
class EventRecord:
    """A detected settlement event (a step), with its size as the data now say.

    Attributes:
        window: first window index of the new segment (the estimated change time).
        time_ns: start of that window, ns since the epoch (UTC).
        detected_window: window index at which the event was confirmed.
        size_m: (2,) m, settlement change [south, north] (the new segment's data minus the state
            before it).
        covariance_m2: (2, 2) m^2, covariance of ``size_m``.
        glr: the test statistic at confirmation (chi-square, 2 dof, without a change).
        step_n: (2,) N, the innovation step estimated at confirmation.
        kind: ``step`` (found in the data by the step detector), ``gap`` (a change across a gap
            in the data, confirmed by the record after it), ``held_run`` (an unconfirmed change
            that later data confirmed) or ``warmup`` (a step among the first windows of the data or
            after a gap, confirmed by the data after it; ``events.warmup``).

    """

    window: int
    time_ns: int
    detected_window: int
    size_m: np.ndarray
    covariance_m2: np.ndarray
    glr: float
    step_n: np.ndarray
    kind: str = "step"

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record (SI units)."""
        return {
            "time_ns": int(self.time_ns),
            "time": iso_utc(self.time_ns),
            "window": int(self.window),
            "detected_window": int(self.detected_window),
            "kind": self.kind,
            **_size_json(self.size_m, self.covariance_m2),
            "glr": float(self.glr),
            "step_n": self.step_n.tolist(),
            "size_chi2": self.size_chi2(),
            "size_significant95": bool(self.size_chi2() > CHI2_2DOF_95),
        }

    def size_chi2(self) -> float:
        """Squared Mahalanobis distance of the size from no change (chi-square, 2 dof, if none)."""
        return _chi2(self.size_m, self.covariance_m2)


@dataclass
class ChangeRecord:
    """A possible settlement change that is not confirmed: where the data cannot tell yet.

    A gap in the data (the supports may have moved while nothing was measured), or a run of held
    windows that ended (at ``event_max_pending``, a gap or the end of the data) away from the
    estimate without confirming a step. The shadow weighs both outcomes by the data; the posterior
    is their mixture.

    Attributes:
        window: first window after the possible change; time_ns: its start, ns (UTC).
        kind: ``gap``, ``held_run``, ``warmup`` (a provisional segment), ``run_in_data`` (a run that reached
            ``event_max_pending`` without a step's jump, or ended the data or met a gap with no jump
            beyond its own rate: used as ordinary data and reported) or
            ``step`` (a step the detector found whose size the data, as they now say, do not tell
            from no change at ``event_probability``: not an event; the estimate keeps its jump) or
            ``excursion`` (a run that came back after moving the reactions' sum by more than any
            vehicle: its windows rejected as outliers, its level not in the estimate, reported) or
            ``between_steps`` (a run beyond any vehicle, no state of its own, that the data left
            for another level: a support lowered and raised again minutes apart; its windows left
            out as ``step_window``, its level not in the estimate, reported) or ``before_gap`` (one
            window before a gap, no heavier than any vehicle: no state of its own, left out as
            ``step_window``, reported but not a warning; the gap's segment weighs any change) or
            ``after_gap`` (a gap's first window before a drop no heavier than any vehicle: the load
            of one that stood when the record began and left in its first minute; left out as
            ``step_window``, reported but not a warning; the gap's segment begins after it) or
            ``at_end`` (the same at the end of the data: left out, reported as a warning, since
            nothing after it can tell a vehicle that drove on from the window a step happened in).
        change_probability: posterior probability that the settlement changed there (NaN for a
            ``run_in_data``, a ``step``, an ``excursion``, a ``between_steps``, a ``before_gap``,
            an ``after_gap`` or an ``at_end``, which are not weighed).
        windows: windows since (in its segment).
        size_m: (2,) m, the change if there was one (the segment's data minus the state before).
        covariance_m2: (2, 2) m^2, its covariance.
        gap_s: length of the gap before it, s (0 for a held run).
        significant: for a ``run_in_data``: its jump is one against the rate its own windows
            show (not a drift's progress over a hole: ``ChangeDetector._drift_jump``), and its GLR
            passed the event threshold or it moved the reactions' sum by more than any vehicle
            with its size's 95 % region excluding zero; False for a ``step`` (None otherwise).
        until_ns: for a ``run_in_data``, an ``excursion``, a ``between_steps``, a ``before_gap``,
            an ``after_gap`` or an ``at_end``: the end of its last window, ns (None otherwise).
        next_ns: for a provisional segment the data left for another state (an event or a further
            possible change after it): that state's start, ns (None when the data end in it).
            ``windows`` are those before it: a change followed minutes later by a small event has
            few windows of its own and yet the data after it stayed changed.
        state_if_changed_m: for the current state's provisional segment not decided (change
            probability between 1e-3 and one half) whose data estimate, the state a change would
            mean, lies outside the posterior's 95 % interval of a support: that state (2,) m; the
            posterior, one Gaussian over both outcomes, does not hold it (a warning). None
            otherwise.

    """

    window: int
    time_ns: int
    kind: str
    change_probability: float
    windows: int
    size_m: np.ndarray
    covariance_m2: np.ndarray
    gap_s: float = 0.0
    significant: bool | None = None
    until_ns: int | None = None
    next_ns: int | None = None
    state_if_changed_m: np.ndarray | None = None

    @property
    def likely(self) -> bool:
        """Whether the warnings report it.

        A significant run; at a gap or a held run, a change more likely than not, or one the data
        have not yet decided whose size's 95 % region excludes zero (two windows of a large new
        state: too few to confirm, too large to keep quiet), or whose state lies outside the
        posterior's interval (``state_if_changed_m``).
        """
        if self.significant is not None:
            return self.significant
        if self.change_probability > 0.5 or self.state_if_changed_m is not None:
            return True
        undecided = self.change_probability > 1e-3  # a merge takes it below (change_confirm_probability)
        return bool(undecided and self.size_chi2() > CHI2_2DOF_95)

    def size_chi2(self) -> float:
        """Squared Mahalanobis distance of the size from no change (chi-square, 2 dof, if none)."""
        return _chi2(np.asarray(self.size_m), np.asarray(self.covariance_m2))

    def to_json(self) -> dict[str, Any]:
        """JSON-ready record (SI units)."""
        return {
            "time_ns": int(self.time_ns),
            "time": iso_utc(self.time_ns),
            "window": int(self.window),
            "kind": self.kind,
            "change_probability": None if np.isnan(p := self.change_probability) else float(p),
            "likely": self.likely,
            "windows": int(self.windows),
            "gap_s": float(self.gap_s),
            **({} if (u := self.until_ns) is None else {"until_ns": int(u), "until": iso_utc(u)}),
            **({} if (t := self.next_ns) is None else {"next_state_ns": int(t), "next_state": iso_utc(t)}),
            **_size_json(self.size_m, self.covariance_m2),
            "size_chi2": self.size_chi2(),
            **({} if (x := self.state_if_changed_m) is None else {"state_if_changed_m": list(map(float, x))}),
        }


def split_rejected(rejected: dict[str, int]) -> tuple[dict[str, int], dict[str, int]]:
    """Split the counts by reason into messages' (``MESSAGE_REASONS``) and windows' (the rest).

    The JSON's ``rejected`` holds both, one count per reason (a message reason counts messages,
    a window reason windows); a caller that summed it counted more rejected messages than were
    read. ``messages.rejected_by_reason`` and ``windows.rejected_by_reason`` say which is which.
    """
    messages = {k: int(v) for k, v in rejected.items() if k in MESSAGE_REASONS}
    windows = {k: int(v) for k, v in rejected.items() if k not in MESSAGE_REASONS}
    return messages, windows


def rejected_window(k: int, window_ns: int, reason: str) -> dict[str, Any]:
    """Return one rejected window as the JSON lists it: its start (ns and UTC), index and reason."""
    return {"time_ns": k * window_ns, "time": iso_utc(k * window_ns), "window": int(k), "reason": reason}


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
    stale_temperature_windows: int = 0
    changes: list[ChangeRecord] = field(default_factory=list)
    state: dict[str, Any] = field(default_factory=dict)
    gaps: list[dict[str, Any]] = field(default_factory=list)
    traffic: dict[str, Any] = field(default_factory=dict)
    #: every rejected window (``rejected_window``), from the shadow's own log (``report.rejected_list``)
    rejected_list: list[dict[str, Any]] = field(default_factory=list)

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

    def rejected_windows(self) -> list[dict[str, Any]]:
        """Every window that closed with data but did not join the estimate: its time and reason."""
        return list(self.rejected_list)

    def to_json(self) -> dict[str, Any]:
        """Return the replay JSON object (contract keys first)."""
        return {
            "posterior": {
                "mean_m": self.mean_m.tolist(),
                "covariance_m2": self.covariance_m2.tolist(),
                "sigma_m": np.sqrt(np.diag(self.covariance_m2)).tolist(),
                "supports": list(SUPPORTS),
                "state": dict(self.state),
            },
            "messages": {
                "total": self.messages,
                "used": int(sum(self.used.values())),
                "used_by_topic": dict(self.used),
                "rejected": int(sum(v for k, v in self.rejected.items() if k in MESSAGE_REASONS)),
                "rejected_by_reason": split_rejected(self.rejected)[0],
            },
            "rejected": dict(self.rejected),
            "messages_per_s": self.messages_per_s,
            "seconds": self.seconds,
            "windows": {
                "closed": self.windows,
                "updates": self.updates,
                "uncompensated": self.uncompensated_windows,
                "stale_temperature": self.stale_temperature_windows,
                "rejected_by_reason": split_rejected(self.rejected)[1],
            },
            "events": [e.to_json() for e in self.events],
            "unconfirmed_changes": [c.to_json() for c in self.changes],
            "gaps": list(self.gaps),
            "rejected_windows": self.rejected_windows(),
            "traffic": dict(self.traffic),
            "warnings": list(self.warnings),
            "prior": dict(self.prior),
            "spline": self.spline,
            "noise": self.noise,
        }
