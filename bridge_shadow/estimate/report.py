"""What the shadow reports: diagnostics, events, warnings, compensation and noise, a replay's result.

Plain functions of a ``Shadow`` (SI units; text for people only in the messages). The node turns
``diagnostics`` into ``/diagnostics`` (``bridge_shadow.ros.diagnostics``); replay prints and dumps
``replay_result(...).to_json()``.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge_shadow.contract import CHANNELS, SUPPORTS
from bridge_shadow.estimate.compensation.fit import deck_sun_weight
from bridge_shadow.estimate.events.warmup import beyond_any_vehicle
from bridge_shadow.estimate.inputs.ledger import TOPIC_KEYS
from bridge_shadow.estimate.inputs.silence import MIN_SILENT_WINDOWS
from bridge_shadow.estimate.result import (
    CHI2_2DOF_95,
    ChangeRecord,
    EventRecord,
    ReplayResult,
    WindowOutput,
    rejected_window,
)
from bridge_shadow.timefmt import iso_utc

if TYPE_CHECKING:
    from bridge_shadow.estimate.shadow import Shadow

__all__ = [
    "NOISE_FULL_DAY_S",
    "diagnostics",
    "event_records",
    "gaps",
    "noise_info",
    "posterior_state",
    "prior_info",
    "replay_result",
    "spline_info",
    "unconfirmed_changes",
    "warnings",
]

#: Residual history the adaptive noise model needs before the diagnostics call its intervals
#: calibrated: one whole day (a quiet night gives intervals too narrow for the day that follows).
NOISE_FULL_DAY_S = 86_400.0
_NS = 1_000_000_000

#: The common-mode settlement (95 %, m) that the deck's sun could hide across a gap, above which a
#: change the data did not confirm there is said to be indistinguishable from the sun
#: (``sun_ambiguity_lines``): a millimetre, the order of the settlements the paper's shadow
#: resolves (its +-0.7 mm model check), a round figure, not fitted to any record.
SUN_AMBIGUITY_M = 1e-3


def _segment_change(shadow: Shadow, s: int) -> tuple[np.ndarray, np.ndarray, float, int] | None:
    """Size (2,) m and covariance (2, 2) m^2 of the change into segment ``s``, its probability, windows.

    The size is the segment's data estimate minus the chained state before it; its covariance adds
    the calibration's uncertainty of a change read through ``A`` (``u0`` cancels). The current
    segment is read from the online state, older ones from the last refresh (None before one).
    """
    f = shadow.filter
    if s <= 0 or s >= len(f.starts):
        return None
    if s == len(f.starts) - 1:
        x_d, d_cov, x_b, p_b = f.current_measurement()
        prob, n = f.change_probability, f.current_windows
    elif s < len(f.summaries):
        sm = f.summaries[s]
        x_d, d_cov, x_b, p_b = sm.x_data, sm.d_cov, sm.x_before, sm.P_before
        prob, n = sm.change_probability, sm.windows
    else:
        return None
    size = x_d - x_b
    if not np.all(np.isfinite(size)):
        return np.full(2, np.nan), np.full((2, 2), np.nan), prob, n
    return size, d_cov + p_b + shadow.surrogate.model_covariance(size, with_u0=False), prob, n


def _confirmed(shadow: Shadow, s: int) -> bool:
    """Whether provisional segment ``s``'s change is confirmed now (reported as an event)."""
    cfg = shadow.config
    h = shadow.detector.h_event
    return shadow.filter.confirms(s, cfg.change_confirm_probability, cfg.event_confirm_windows, h)


def _not_significant(shadow: Shadow, s: int) -> bool:
    """Whether a step the detector found into segment ``s`` is, as the data now say, no change.

    The detector tests windows against the estimate; the two segments' levels, each from all of
    its windows with the noise's long-run variance and the curve's error as far as the two read it
    differently (``SegmentChain.change_chi2``, as of the last refit; not the model's uncertainty of
    a change, which scales a change and cannot make one), must show the change at the same
    ``event_probability``. A step that does not (a drift the detector dated, a wander of the
    noise) is reported as a possible change, not significant; the estimate keeps its jump.
    Unknown (NaN: no refit since) keeps the event.
    """
    return bool(shadow.filter.change_chi2(s) < shadow.detector.h_event)


def _detector_steps(shadow: Shadow) -> list[tuple[dict[str, Any], int, bool]]:
    """Return the detector's steps: (its record, its segment, whether the levels show it: an event)."""
    out = []
    for i, e in enumerate(shadow.events):
        s = int(e.get("segment", i + 1))
        out.append((e, s, not _not_significant(shadow, s)))
    return out


def _provisional(shadow: Shadow) -> list[int]:
    return [s for s, pi in enumerate(shadow.filter.change_prior) if 0.0 < pi < 1.0]


def event_records(shadow: Shadow) -> list[EventRecord]:
    """Return the events: steps the detector confirmed, and changes at gaps the data confirm now.

    Each with its size and covariance as the data now say (the last refit; the current segment
    online).
    """
    out = []
    nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
    for e, s, shown in _detector_steps(shadow):
        if not shown:
            continue
        change = _segment_change(shadow, s)
        size, cov = (nan2, nan22) if change is None else change[:2]
        k = int(e["window"])
        out.append(
            EventRecord(
                k,
                k * shadow._w_ns,
                int(e["detected_window"]),
                size,
                cov,
                float(e["glr"]),
                np.asarray(e["step_n"], float),
                str(e.get("kind", "step")),
            )
        )
    f = shadow.filter
    for s in _provisional(shadow):
        change = _segment_change(shadow, s)
        if change is None or not _confirmed(shadow, s):
            continue
        size, cov = change[:2]
        k = f.starts[s]
        chi2 = float(size @ np.linalg.solve(cov, size)) if np.all(np.isfinite(cov)) else float("nan")
        detected = shadow.confirmed_at.get(k, shadow._last_judged)
        out.append(EventRecord(k, k * shadow._w_ns, detected, size, cov, chi2, shadow.A @ size, f.kinds[s]))
    return sorted(out, key=lambda e: e.window)


def unconfirmed_changes(shadow: Shadow) -> list[ChangeRecord]:
    """Return the possible changes not confirmed, in time order, with what each would mean.

    Provisional segments (a gap, or a held run that ended with the data or at a gap; the posterior
    weighs them by their change probability) and runs that reached ``event_max_pending`` without
    qualifying as a step (used as data of the current state; reported with their significance).
    """
    f = shadow.filter
    gap_s = {g["segment"]: (g["to_k"] - g["from_k"] - 1) * shadow.config.window_s for g in shadow.gaps}
    out = []
    for s in _provisional(shadow):
        change = _segment_change(shadow, s)
        if change is None or _confirmed(shadow, s):
            continue
        size, cov, prob, n = change
        k = f.starts[s]
        gap = gap_s.get(s, 0.0)
        nxt = f.starts[s + 1] * shadow._w_ns if s + 1 < len(f.starts) else None
        kind = f.kinds[s]
        record = ChangeRecord(k, k * shadow._w_ns, kind, float(prob), int(n), size, cov, gap, next_ns=nxt)
        if s == len(f.starts) - 1:
            record.state_if_changed_m = _state_outside(shadow, float(prob))
        out.append(record)
    for e, s, shown in _detector_steps(shadow):  # steps the levels do not show
        change = None if shown else _segment_change(shadow, s)
        if change is None:
            continue
        size, cov, _, n = change
        k = int(e["window"])
        t = k * shadow._w_ns
        out.append(ChangeRecord(k, t, "step", float("nan"), int(n), size, cov, significant=False))
    for r in shadow.unconfirmed_runs:  # runs used as data: their change read through A
        out.append(_run_in_data(shadow, r))
    # runs no vehicle makes that came back (rejected as an excursion) or states held between two
    # steps (left out): reported (a checkpoint written before the kind was kept holds excursions)
    # (one window before a gap, or a gap's first window before a drop, no heavier than any vehicle,
    # is no likely change: not a warning;
    # at the end of the data nothing after it weighs it: a warning)
    for r in shadow.excursions:
        kind = r.get("kind", "excursion")
        out.append(_run_record(shadow, r, kind, kind not in ("before_gap", "after_gap")))
    return sorted(out, key=lambda c: c.window)


def _state_outside(shadow: Shadow, probability: float) -> np.ndarray | None:
    """Return the state the current segment's undecided change would mean, if the interval misses it.

    Undecided: a change probability above 1e-3 (a merge takes it below) and at most one half (a
    likely change is warned of anyway). The state: the segment's data estimate. The posterior is
    one Gaussian over both outcomes; where the data cannot tell them apart and the change is the
    less likely one, its interval may hold the old state alone (the reference record, then 4 h on
    the same record four times back to back, 10 mm lower from the second copy: the state read at
    -8.2 mm for 36 minutes, the end's refit put the change at 0.11 and the estimate at -0.9 ±
    7.3 mm, nothing said). Returned (2,) m where a support's 95 % interval misses it, else None.
    """
    if not 1e-3 < probability <= 0.5:
        return None
    x_d = shadow.filter.current_measurement()[0]
    mean, cov = shadow.posterior
    if not np.all(np.isfinite(x_d)):
        return None
    return x_d.copy() if bool(np.any(np.abs(x_d - mean) > _half_width_95(cov))) else None


def _half_width_95(cov: np.ndarray) -> np.ndarray:
    """(2,) the 95 % half-width of each support's marginal of ``cov`` (2, 2)."""
    return 1.96 * np.sqrt(np.maximum(np.diag(cov), 0.0))


def latest_level(shadow: Shadow) -> dict[str, Any] | None:
    """Return the state the last windows used read on their own, where the posterior does not hold it.

    The last ``event_confirm_windows`` windows used as data (all of the current segment),
    compensated by the current curve and read through ``A``, against the posterior: returned when
    a support's 95 % interval misses their state and the reactions' sum between the two differs
    by more than any vehicle (``traffic_vehicle_max_n``), else None. A noise model that learned a
    settlement as noise (a vehicle over the first minutes of the data, then a lowering: the
    reference record three times back to back, 10 mm lower from the second copy, a 30 kN vehicle
    in minutes 2-4, ended at -0.97 mm ± 8.3 with its last 24 windows at -10 mm, nothing said; the
    young windows' own rules, ``Shadow._young_level``, follow its kin with 120 s windows and many
    lowerings over minutes), or a prior the data have not yet outweighed, holds the estimate away
    from what the supports show: the estimate stands, and the check says so
    (``latest_level_lines``). The comparison is
    of the same ``u0`` on both sides, so its uncertainty, in the posterior's interval, only widens
    what passes.

    Keys: ``state_m`` (2,), ``since_ns`` and ``until_ns`` (the windows' span), ``windows``,
    ``sum_change_n`` (the reactions' sum of the state less the posterior's), and the posterior it
    was read against: ``mean_m`` and ``half_width_m`` (2,) each, 95 %.
    """
    f = shadow.filter
    need = shadow.config.event_confirm_windows
    if not f.starts or len(shadow._latest) < need:
        return None
    ws = [w for w in shadow._latest if w.k >= f.starts[-1]]
    if len(ws) < need:
        return None
    force = np.array([w.force for w in ws], float).reshape(-1, 2)
    if shadow.fit is not None:
        temp = np.array([w.temp for w in ws], float).reshape(-1, 2)
        i0 = np.array([w.i0 for w in ws]).reshape(-1, 2)
        bv = np.array([w.bv for w in ws], float).reshape(len(ws), 2, -1)
        force = force - shadow.compensation.curve_rows(shadow.fit, temp, i0, bv)
    state = f.a_inv @ (force.mean(axis=0) - shadow.u0)
    mean, cov = shadow.posterior
    if not (np.all(np.isfinite(state)) and np.all(np.isfinite(mean))):
        return None
    hw = _half_width_95(cov)
    outside = np.abs(state - mean) > hw
    step = shadow.A @ (state - mean)
    if not (bool(np.any(outside)) and beyond_any_vehicle(step, shadow.config.traffic_vehicle_max_n)):
        return None
    return {
        "state_m": state,
        "since_ns": ws[0].k * shadow._w_ns,
        "until_ns": (ws[-1].k + 1) * shadow._w_ns,
        "windows": len(ws),
        "sum_change_n": float(step[0] + step[1]),
        "mean_m": mean,
        "half_width_m": hw,
    }


def latest_level_lines(shadow: Shadow) -> list[str]:
    """One warning line when the last windows read a state the posterior does not hold (``latest_level``)."""
    latest = latest_level(shadow)
    if latest is None:
        return []
    mean, hw = latest["mean_m"], latest["half_width_m"]
    state = " / ".join(f"{1e3 * x:+.2f}" for x in latest["state_m"])
    post = " / ".join(f"{1e3 * m:+.2f} ± {1e3 * h:.2f}" for m, h in zip(mean, hw, strict=True))
    return [
        f"the last {latest['windows']} windows used ({iso_utc(latest['since_ns'])} to "
        f"{iso_utc(latest['until_ns'])}) read {state} mm (south / north), outside the posterior's "
        f"95 % interval ({post} mm): the reactions' sum {1e-3 * latest['sum_change_n']:+.1f} kN "
        "from the estimate's, more than any vehicle (traffic_vehicle_max_n); a settlement the estimate "
        "has not followed (its noise model took it for noise, or the prior holds it), a load heavier "
        "than any vehicle, or sun on the deck the compensation has not taken off: the estimate may not "
        "be the supports' state now"
    ]


def _run_in_data(shadow: Shadow, run: dict[str, Any]) -> ChangeRecord:
    """Return a run used as data, significant when its GLR passed the event threshold or it moved.

    A run that jumped over a hole only as far as its own rate carried it is a drift, no change.
    Otherwise it is significant (a warning) when its GLR passed ``h_event``, or when it moved the
    reactions' sum by more than any vehicle (``traffic_vehicle_max_n``) and its size's 95 % region
    excludes zero: a settlement the detector could not confirm against a noise model that, early
    in the data, held the test car as noise (three copies of a real record back to back, 10 mm
    lower each through ``A``: -9.8 ± 5.3 mm used as data, the estimate near the old state, and
    no warning).
    """
    record = _run_record(shadow, run, "run_in_data", False)
    if run.get("drift", False):
        return record
    glr = run["glr"] > shadow.detector.h_event
    moved = beyond_any_vehicle(run["step_n"], shadow.detector.vehicle_max_n)
    record.significant = bool(glr or (moved and record.size_chi2() > CHI2_2DOF_95))
    return record


def _run_record(shadow: Shadow, run: dict[str, Any], kind: str, significant: bool) -> ChangeRecord:
    """Return a run the detector noted (``unconfirmed_runs``, ``excursions``), its step read through A."""
    a_inv = shadow.filter.a_inv
    size = a_inv @ np.asarray(run["step_n"], float)
    cov = a_inv @ np.asarray(run["step_cov_n2"], float) @ a_inv.T
    cov = cov + shadow.surrogate.model_covariance(size, with_u0=False)
    k, n, until = int(run["window"]), int(run["windows"]), (int(run["until_window"]) + 1) * shadow._w_ns
    return ChangeRecord(k, k * shadow._w_ns, kind, float("nan"), n, size, cov, 0.0, significant, until)


def gaps(shadow: Shadow) -> list[dict[str, Any]]:
    """Return the gaps in the usable windows: from, to (ISO and ns), length, what the data say since.

    ``change_probability`` is the posterior probability that the settlement changed in the gap
    (0 once merged: the data said no change), ``confirmed`` whether that is an event now. With the
    sun term: the sun covariate on either side (``sun_covariate``) and the common-mode settlement
    the sun's uncertain ``g`` could hide across the gap, 95 %, m (``sun_hidden_m``,
    ``sun_ambiguity_lines``).
    """
    return _gaps(shadow, _sun_reach(shadow))


def _gaps(shadow: Shadow, sun: tuple[float, float] | None) -> list[dict[str, Any]]:
    """``gaps`` with the sun's reach (``_sun_reach``) given."""
    out = []
    for g in shadow.gaps:
        s = g["segment"]
        start_ns, end_ns = (g["from_k"] + 1) * shadow._w_ns, g["to_k"] * shadow._w_ns
        prob = 0.0 if s < 0 else shadow.filter.segment_probability(s)[0]
        gap = {
            "from_ns": start_ns,
            "from": iso_utc(start_ns),
            "to_ns": end_ns,
            "to": iso_utc(end_ns),
            "duration_s": (end_ns - start_ns) / _NS,
            "change_probability": float(prob),
            "confirmed": bool(s >= 0 and _confirmed(shadow, s)),
            "merged": bool(s < 0),
        }
        if sun is not None and "sun_covariate" in g:
            before, after = g["sun_covariate"]
            gap["sun_covariate"] = [float(before), float(after)]
            gap["sun_hidden_m"] = 1.96 * sun[0] * abs(sun[1] * (after - before))
        out.append(gap)
    return out


def posterior_state(shadow: Shadow) -> dict[str, Any]:
    """Return which state the posterior stands for: the current segment, since when, how sure."""
    f = shadow.filter
    if not f.starts:
        return {"kind": "prior", "text": "the prior: no window has been used"}
    s = len(f.starts) - 1
    since = f.starts[s] * shadow._w_ns
    kind = f.kinds[s]
    prob = f.change_probability
    state = {"kind": kind, "since_ns": since, "since": iso_utc(since), "segment": s}
    if kind == "start":
        state["text"] = f"the state since the first window ({iso_utc(since)})"
    elif kind in ("gap", "held_run", "warmup"):
        state["change_probability"] = float(prob)
        how = "confirmed" if _confirmed(shadow, s) else "not confirmed"
        if how != "confirmed" and prob >= shadow.config.change_confirm_probability:
            how += f": too few windows yet for an event, which needs {shadow.config.event_confirm_windows}"
        if kind == "gap":
            w_h = shadow.config.window_s / 3600.0
            hours = [(g["to_k"] - g["from_k"] - 1) * w_h for g in shadow.gaps if g["segment"] == s]
            after = f"after a gap of {hours[0]:.1f} h" if hours else "after a gap"
        elif kind == "warmup":
            after = "where a step showed among its first windows (the warm-up, or those after a gap)"
        else:
            after = "where a held run ended without confirming a step"
        state["text"] = (
            f"the state since {iso_utc(since)}, {after}: changed with probability {prob:.3g} ({how}); "
            "the posterior is the mixture of both outcomes"
        )
    else:
        what = {"event": "the settlement step", "drift": "the drift block starting"}.get(kind, kind)
        if kind == "event" and _not_significant(shadow, s):
            what = "a step the detector found (its size not told from zero on the data: no event)"
        state["text"] = f"the state since {what} at {iso_utc(since)}"
    held = shadow.pending_gap_ns()
    if held is not None:
        hours = (held - (shadow._last_usable_k + 1) * shadow._w_ns) / 3.6e12  # type: ignore[operator]
        pi = shadow.config.change_prior_probability
        state["pending_gap_since_ns"] = int(held)
        state["text"] += (
            f"; the record since {iso_utc(held)}, after a gap of {hours:.1f} h, is held for the traffic "
            f"screen until it ends: whether the supports moved in the gap is open (probability {pi:.3g} "
            "before its windows are judged), and the interval is widened by what a change could be"
        )
    last = shadow._last_usable_k
    blind = [
        (a, key)
        for c, key in enumerate(CHANNELS)
        for a, _ in shadow.silence.stretches(c)
        if last is not None and a > last
    ]
    if blind:  # the data after the last used window were there, one channel was not
        a, key = min(blind)
        state["unseen_from"] = iso_utc(a * shadow._w_ns)
        state["text"] += (
            f"; from {iso_utc(a * shadow._w_ns)} on {key} delivered nothing usable and the state there "
            "is not known"
        )
    latest = latest_level(shadow)
    if latest is not None:  # the last windows read a state the posterior does not hold
        state["latest_level"] = {
            "state_m": latest["state_m"].tolist(),
            "since_ns": int(latest["since_ns"]),
            "since": iso_utc(latest["since_ns"]),
            "until_ns": int(latest["until_ns"]),
            "until": iso_utc(latest["until_ns"]),
            "windows": int(latest["windows"]),
            "sum_change_n": float(latest["sum_change_n"]),
        }
        read = " / ".join(f"{1e3 * x:+.2f}" for x in latest["state_m"])
        state["text"] += (
            f"; its last {latest['windows']} windows read {read} mm (south / north) on their own, outside "
            "its 95 % interval by more than any vehicle: it may not be the supports' state now"
        )
    return state


def silent_channel_lines(shadow: Shadow) -> list[str]:
    """One line per force channel that missed stretches of windows while the other delivered.

    What its messages were rejected for comes from the topic's ledger, counted over the whole run
    and said so (``out_of_range`` with the last such value: at or below zero, a bearing that
    lifted off or a dead cell). A topic whose every message was rejected has its own line
    (``all_rejected_message``).
    """
    out = []
    w = shadow._w_ns
    for c, key in enumerate(CHANNELS):
        ledger = shadow.ledgers[c]
        stretches = shadow.silence.stretches(c)
        if not stretches or ledger.all_rejected_message():
            continue
        n = sum(b - a + 1 for a, b in stretches)
        spans = ", ".join(f"{iso_utc(a * w)} .. {iso_utc((b + 1) * w)}" for a, b in stretches[:3])
        if len(stretches) > 3:
            spans += f" and {len(stretches) - 3} more"
        why = [f"{r} {m}" for r, m in ledger.rejected.most_common() if m]
        if ledger.rejected.get("out_of_range") and ledger.last_value is not None:
            lo, hi, unit = ledger.value_range
            value = f"{ledger.last_value:g} {unit}"
            why.append(f"last out-of-range value {value}, accepted {lo:g} .. {hi:g} {unit}")
        # the ledger counts the whole run, not the stretches: say so (it read as the stretches' own)
        said = (
            f"its messages rejected over the whole run: {', '.join(why)}"
            if why
            else "no message of it arrived there"
        )
        lift = (
            "; a load cell at or below zero is a bearing that lifted off its support, or a dead cell"
            if ledger.last_value is not None and ledger.last_value <= 0
            else ""
        )
        out.append(
            f"topic {key}: nothing usable in {n} windows while the other force channel delivered "
            f"({spans}; {said}): those windows were not used (missing_topic), and the estimate does "
            f"not know the state there{lift}"
        )
    return out


#: A bearing's force level below this share of its dead load (``u0``) is said out loud: near
#: lift-off the linear model does not hold (``twin.real_records.SWEEP_MIN_LOAD_SHARE``, where the
#: studies stop), and forces sent in kN where N are expected read as 0.1 % of it.
LOW_LOAD_SHARE = 0.25
#: Below this share of the dead load the line also names forces sent in kN (0.1 % of it).
KN_SHARE = 0.01


def current_level(shadow: Shadow) -> np.ndarray | None:
    """Return the current state's force level of each bearing, N (None before a fit)."""
    fit = shadow.fit
    if fit is None or not len(fit.level):
        return None
    return fit.level[min(shadow.filter.segment, len(fit.level) - 1)] + shadow.u0


def low_load_lines(shadow: Shadow) -> list[str]:
    """One line when the current state's force level of a bearing is below ``LOW_LOAD_SHARE`` of u0."""
    level = current_level(shadow)
    if level is None:
        return []
    share = level / shadow.u0
    low = [c for c in range(len(CHANNELS)) if share[c] < LOW_LOAD_SHARE]
    if not low:
        return []
    each = ", ".join(
        f"{CHANNELS[c]} {1e-3 * level[c]:.3g} kN of {1e-3 * shadow.u0[c]:.0f} kN ({100 * share[c]:.2g} %)"
        for c in low
    )
    # kN sent as N read as 0.1 % of the dead load; a bearing near lift-off (14 % at -34 mm on the
    # north support) is no unit mix-up, and the hint misled there
    units = "; forces sent in kN where N are expected look like this" if min(share[low]) < KN_SHARE else ""
    return [
        f"force level far below the dead load ({each}): near lift-off the model does not hold and the "
        f"settlements mean little{units}"
    ]


def short_window_lines(shadow: Shadow) -> list[str]:
    """One line when most windows were too sparse to use because ``window_s`` is short for the data.

    A window needs ``window_min_samples`` accepted samples of each load cell; at a window as long as
    the sample period (0.01 s at 100 Hz) almost none has them, and the counts alone
    (``sparse_window``) did not say why. Said when at least half the closed windows were sparse.
    """
    sparse = int(shadow.counts.get("sparse_window", 0))
    if not shadow.n_windows or 2 * sparse < shadow.n_windows:
        return []
    used = [shadow.ledgers[c].run_counts()[0] for c in range(len(CHANNELS))]
    per_window = min(used) / shadow.n_windows
    return [
        f"windows too short for the data: {sparse} of {shadow.n_windows} windows had fewer than "
        f"window_min_samples ({shadow.config.window_min_samples}) samples of a load cell, about "
        f"{per_window:.2g} per window of window_s {shadow.config.window_s:g} s; choose window_s so "
        "that a window holds many samples (the default 60 s)"
    ]


def dead_input_lines(shadow: Shadow) -> list[str]:
    """One line when both load cells' messages, to the end of the data, were all rejected.

    Found with the 2022-04-11 records: the 10 mm record with both cells delivering NaN (or one
    value held) throughout ended at the reference state, 0 ± 3.7 mm against -10 mm, no event, no
    warning: no window of it closed, so neither the rejected windows nor a silent channel (whose
    partner delivered) showed it, and every topic had accepted messages before. Said when both
    channels' rejected messages since their last accepted one span at least two windows (a
    stretch, as ``inputs.silence.MIN_SILENT_WINDOWS``).
    """
    span = MIN_SILENT_WINDOWS * shadow._w_ns
    tails = [shadow.ledgers[c].dead_tail(span) for c in range(len(CHANNELS))]
    if any(t is None for t in tails):
        return []
    last_ok = max(shadow.ledgers[c].last_ok_ns for c in range(len(CHANNELS)))
    first = min(t[1] for t in tails if t is not None)
    last = max(t[2] for t in tails if t is not None)
    n0, n1 = (t[0] for t in tails if t is not None)
    counts = f"{n0} messages of {CHANNELS[0]} and {n1} of {CHANNELS[1]}"
    why: Counter = Counter()
    for c in range(len(CHANNELS)):
        why.update(shadow.ledgers[c].run_counts()[1])
    reasons = ", ".join(f"{r} {n}" for r, n in why.most_common() if n)
    since = f"after {iso_utc(last_ok)}" if last_ok >= 0 else "at all"
    return [
        f"no usable load-cell message {since}: the {counts} from {iso_utc(first)} to "
        f"{iso_utc(last)} were all rejected (over the whole run: {reasons}): the settlement since is "
        "unknown, and the posterior stands for the state before them"
    ]


#: An event whose reaction change on one load cell is at most this share of the other's (and within
#: two of its standard deviations of none) moved that cell alone: ``one_cell_lines``.
ONE_CELL_SHARE = 0.05


def one_cell_lines(shadow: Shadow) -> list[str]:
    """One line per event that changed one load cell's reaction alone: a sensor fault fits it too.

    A settlement moves both reactions through ``A``; the one that leaves a cell's reaction as it
    was is a particular mix of both supports (``A^-1`` times that cell's unit change; on the
    calibrated model south and north down in a ratio of about 1.4 to 1). A load cell whose offset
    or gain jumped gives exactly that signature (found with the 2022-04-11 records: +50 kN on the
    north cell of an unchanged second record read as a confirmed event of +6.2 / +8.4 mm, and a
    2 % gain change as one too, with nothing to say that one cell moved), so the event is told with
    its reaction changes and the alternative named.
    """
    out = []
    for e in event_records(shadow):
        if not (np.all(np.isfinite(e.size_m)) and np.all(np.isfinite(e.covariance_m2))):
            continue
        d = shadow.A @ e.size_m
        sd = np.sqrt(np.maximum(np.diag(shadow.A @ e.covariance_m2 @ shadow.A.T), 0.0))
        moved = int(np.argmax(np.abs(d)))
        still = 1 - moved
        # (the event is confirmed already: its size against the model's and the sun's uncertainty,
        # which a cut at 3 sd of the reaction change applied again, missed +50 kN on the south
        # cell at 2.9 sd)
        if abs(d[still]) > ONE_CELL_SHARE * abs(d[moved]) or abs(d[still]) > 2.0 * sd[still]:
            continue
        other = f"{CHANNELS[still]} {1e-3 * d[still]:+.2f} ± {1.96e-3 * sd[still]:.2f} kN"
        out.append(
            f"event at {iso_utc(e.time_ns)} changed one load cell's reaction alone: {CHANNELS[moved]} "
            f"{1e-3 * d[moved]:+.1f} kN, {other}: "
            f"a jump of {CHANNELS[moved]}'s offset or gain (a sensor fault) fits it as well as the "
            "settlement read; check that load cell"
        )
    return out


def air_jump_lines(shadow: Shadow) -> list[str]:
    """One line when the air jumped between windows more than air can (``Shadow._follow_air``)."""
    air = shadow.air
    if not air["jumps"] or air["worst"] is None:
        return []
    k0, k1, t0, t1 = air["worst"]
    hours = (k1 - k0) * shadow.config.window_s / 3600.0
    w = shadow._w_ns
    more = f"; {air['jumps']} such jumps" if air["jumps"] > 1 else ""
    return [
        f"air temperature jumped by {t1 - t0:+.1f} K within {hours:.2g} h ({iso_utc(k0 * w)} -> "
        f"{iso_utc(k1 * w)}, {t0:.1f} -> {t1:.1f} C), more than air does: a faulty sensor, or readings "
        f"in another unit (°F?), look like this, and the compensation reads them as weather{more}"
    ]


#: The level at which ``fixed_noise_lines`` rejects the fixed noise: the event detector's
#: consistency test's (``events.detector``, ``consistency_probability``).
FIXED_NOISE_PROBABILITY = 0.999


def fixed_noise_lines(shadow: Shadow) -> list[str]:
    """Say when ``noise_mode: fixed`` runs on residuals that its ``Sigma_E`` does not describe.

    Under the fixed model the window means are ``Sigma_E / m`` apart from the curve, independent:
    ``sum m e^2 / sigma^2`` is chi-square with the fit's residual degrees of freedom. Where it
    exceeds that distribution's ``FIXED_NOISE_PROBABILITY`` quantile in a channel, the intervals and
    the event tests rest on a noise the data contradict (the real pair at 100 Hz: window means
    scatter 57 / 31 times what ``noise_sigma_n`` per sample implies, and a +0.09 mm "settlement
    step" was reported with an interval of +-0.03 mm).
    """
    from scipy import stats

    noise = shadow.noise
    if noise.adaptive or not np.all(np.isfinite(noise.scatter)):
        return []
    dof = noise.dof
    ratio = noise.scatter / np.maximum(noise.sigma_e**2, 1e-300)
    bound = stats.chi2.ppf(FIXED_NOISE_PROBABILITY, dof) / dof
    if not np.any(ratio > bound):
        return []
    sd = " / ".join(f"{math.sqrt(r):.1f}" for r in ratio)
    return [
        f"noise_mode fixed: the window means scatter {sd} times (south / north, as standard deviations) "
        f"what noise_sigma_n says ({noise.n} windows; the fixed noise is rejected at "
        f"{FIXED_NOISE_PROBABILITY:g}): intervals and event tests are too narrow by about that, and "
        "small events may be the noise's; noise_mode: adaptive estimates the noise from the residuals"
    ]


def warnings(shadow: Shadow) -> list[str]:
    """Problems a user must hear about (one line each): silent failures made loud."""
    out = []
    if shadow.checkpoint_failure is not None:
        at, why = shadow.checkpoint_failure
        out.append(
            f"checkpoint not written at {iso_utc(at)} ({why}): a restart would resume from an older "
            f"state; tried again every {shadow.config.checkpoint_period_s:g} s of data"
        )
    if shadow.uncompensated:
        air = shadow.ledgers[2]
        refused = sum(air.rejected.values())
        lo, hi, unit = air.value_range
        why = (  # readings the gate refused may be why (temp_min_c above a cold morning's air)
            f"; {refused} of its readings were rejected: "
            + ", ".join(f"{r} {n}" for r, n in air.rejected.most_common() if n)
            + (f" (accepted {lo:g} .. {hi:g} {unit})" if air.rejected.get("out_of_range") else "")
            if refused
            else ""
        )
        out.append(
            f"no air temperature: {shadow.uncompensated} windows used without temperature compensation "
            + (
                f"(before the first accepted reading of {shadow.config.topic_air_temperature}{why})"
                if shadow.buffer.temp_seen
                else f"(topic {shadow.config.topic_air_temperature} delivered no accepted reading{why})"
            )
        )
    if shadow.stale_temperature:
        out.append(
            f"stale air temperature: {shadow.stale_temperature} windows used with a temperature interpolated "
            f"or held from a reading more than {shadow.config.temperature_stale_s:g} s away (their "
            "compensation widened by what the air can do in that time)"
        )
    for ledger in shadow.ledgers:
        line = ledger.all_rejected_message() or ledger.old_stamps_message()
        if line:
            out.append(line)
        line = None if ledger.all_rejected_message() else ledger.bad_values_message()
        if line:
            out.append(line)
    out.extend(low_load_lines(shadow))
    heard = [used + sum(rejected.values()) for used, rejected in (led.run_counts() for led in shadow.ledgers)]
    # the air came (twice: a live feed's first message may be the air's, the forces' a moment later)
    # and no load cell: no window ever closes
    if heard[2] >= 2 and not heard[0] and not heard[1]:
        forces = " and ".join(shadow.config.input_topics()[:2])
        out.append(
            f"no load cell message: {forces} delivered nothing, while "
            f"{shadow.config.topic_air_temperature} delivered {heard[2]} (the shadow reads the load cells)"
        )
    out.extend(silent_channel_lines(shadow))
    out.extend(short_window_lines(shadow))
    out.extend(dead_input_lines(shadow))
    out.extend(one_cell_lines(shadow))
    out.extend(air_jump_lines(shadow))
    out.extend(fixed_noise_lines(shadow))
    out.extend(sun_ambiguity_lines(shadow))
    out.extend(latest_level_lines(shadow))
    if shadow.n_windows and not shadow.n_updates:
        out.append("no window updated the estimate: the posterior is the prior")
    last = shadow._last_data_k
    for p in parked_loads(shadow):
        if last is not None and last > p["until_ns"] // shadow._w_ns:
            continue  # data came after that record: the next record has shown what it was
        if p["load_n"] is None:
            size = "their load not measured (no kept sample before them)"
        else:
            load = " / ".join(f"{1e-3 * x:+.1f}" for x in p["load_n"])
            change = " / ".join(f"{1e3 * x:+.2f}" for x in p["as_change_m"])
            size = f"{load} kN (south / north); were it a change of the supports, {change} mm"
        out.append(
            f"vehicles parked at the end of a record from {p['since']} until it ended at {p['until']}, "
            f"cut as traffic: {size}, which the next record will show"
        )
    for c in unconfirmed_changes(shadow):
        if not c.likely:
            continue
        where = {
            "gap": f"after a gap of {c.gap_s / 3600.0:.1f} h",
            "held_run": (
                "a run of held windows that stayed away: at the end of the data, before a gap or "
                "another state, or for event_max_pending windows"
            ),
            "warmup": "a step among the first windows (the warm-up, or those after a gap)",
            "run_in_data": "a run that stayed away without a step's jump",
            "excursion": "a run that came back, heavier than any vehicle on the supports' sum",
            "between_steps": "a state held between two steps, heavier than any vehicle on the supports' sum",
            "before_gap": "one window before a gap, no heavier than any vehicle",
            "after_gap": "a gap's first window before a drop no heavier than any vehicle",
            "at_end": "the data's last window, no heavier than any vehicle",
        }[c.kind]
        size = ", ".join(
            f"{side} {1e3 * m:+.2f} ± {1.96e3 * sd:.2f} mm"
            for side, m, sd in zip(SUPPORTS, c.size_m, np.sqrt(np.diag(c.covariance_m2)), strict=True)
        )
        windows = f"{c.windows} window{'s' if c.windows != 1 else ''}"
        if c.kind == "run_in_data":
            until = iso_utc(c.until_ns or c.time_ns)
            how = f"{windows} until {until}, used as data of the current state"
        elif c.kind == "excursion":
            until = iso_utc(c.until_ns or c.time_ns)
            how = f"{windows} until {until}, rejected as an excursion: not in the estimate"
        elif c.kind == "between_steps":
            until = iso_utc(c.until_ns or c.time_ns)
            how = f"{windows} until {until}, left out as a moving support's: not in the estimate"
        elif c.kind == "before_gap":
            how = "left out: not in the estimate; the gap's segment weighs any change"
        elif c.kind == "after_gap":
            how = "left out as a vehicle's that left: not in the estimate; the gap's segment begins after it"
        elif c.kind == "at_end":
            how = (
                "left out: not in the estimate; one window cannot tell a vehicle that drove on "
                "from the window a step happened in, the next data will"
            )
        else:
            since = "since" if c.next_ns is None else f"before the next state from {iso_utc(c.next_ns)}"
            how = (
                f"probability {c.change_probability:.3g}, {windows} {since}; "
                "the posterior weighs it by that probability"
            )
            if c.state_if_changed_m is not None:
                state = " / ".join(f"{1e3 * x:+.2f}" for x in c.state_if_changed_m)
                how += (
                    f"; the posterior's 95 % interval does not hold the state it would mean, {state} mm "
                    "(south / north): the data cannot tell the two apart"
                )
            if c.change_probability >= shadow.config.change_confirm_probability:
                # likely enough, too few windows: say what an event waits for (it read as a
                # contradiction, "probability 1 (not confirmed)", where the records are short)
                need = shadow.config.event_confirm_windows
                how += f"; an event needs {need} windows that stay with it (event_confirm_windows)"
        out.append(f"unconfirmed settlement change at {iso_utc(c.time_ns)} ({where}): {size} ({how})")
    return out


def _sun_reach(shadow: Shadow) -> tuple[float, float] | None:
    """Return the sun term's ``g`` sd now (K) and ``A^-1`` of its force per kelvin (m/K, common mode).

    The sd is ``spline_info``'s. None without a sun term, a fit, or a gap with the sun covariate
    on both sides.
    """
    if (
        not shadow.compensation.sun
        or shadow.fit is None
        or not any("sun_covariate" in g for g in shadow.gaps)
    ):
        return None
    info = spline_info(shadow)
    sd_k = float(np.mean([info[ch].get("sun_gradient_sd_k", np.nan) for ch in CHANNELS]))
    per_k = float(np.mean(shadow.filter.a_inv @ np.asarray(shadow.compensation.sun_slope, float)))
    return (sd_k, per_k) if np.isfinite(sd_k) and np.isfinite(per_k) else None


def sun_ambiguity_lines(shadow: Shadow) -> list[str]:
    """One line per gap whose change the data did not confirm while the sun could have hidden one.

    The deck's sun-driven vertical temperature difference ``g s(t)`` and a settlement of both
    supports move the bearings in one ratio (the surrogate's ``vertical_gradient`` and ``A [1, 1]``),
    so across a gap between records at different hours of sun the data cannot tell a common-mode
    change from a sun ``g`` off by a few kelvin, until more records fix ``g``. A record 1.25 h after
    the reference, lowered 3 mm, ended at +1.2 mm with its interval short of the truth and no word
    (``docs/limitations.md``). This says it: the gap's sun covariates (before, after; ``gaps``), the
    sun term's ``g`` sd now (``spline_info``), ``A^-1`` of its force per kelvin, common mode: the
    95 % settlement the sun could hide there. Said from ``SUN_AMBIGUITY_M`` on, for a gap merged
    (no change) or still provisional with a change probability below one half (the posterior
    leaning to no change); a change the data confirmed is an event. Nothing estimated changes.
    """
    sun = _sun_reach(shadow)
    if sun is None:
        return []
    out = []
    for g in _gaps(shadow, sun):
        hidden, p = g.get("sun_hidden_m", 0.0), g["change_probability"]
        # a change the data confirmed is an event; one they favour (not yet confirmed) no misreading
        if g["confirmed"] or p >= 0.5 or hidden < SUN_AMBIGUITY_M:
            continue
        before, after = g["sun_covariate"]
        judged = (
            "judged no change" if g["merged"] else f"a change weighed at probability {p:.2f}, not confirmed"
        )
        out.append(
            f"a settlement across the gap {g['from']} .. {g['to']} ({judged}) cannot be told "
            f"from the deck's sun: its covariate went from {before:.2f} to {after:.2f}, and with the sun's "
            f"g known to ± {1.96 * sun[0]:.1f} K (95 %) a settlement of both supports "
            f"of up to {hidden * 1e3:.1f} mm reads as sun there and the posterior as no change; records at "
            "other hours of sun fix g"
        )
    return out


def spline_info(shadow: Shadow) -> dict[str, dict[str, Any]]:
    """Per channel: edf, lambda, level, windows fitted, temperature range (NaN before a fit).

    With the sun term (``sun_gradient``) also its vertical temperature difference at a covariate of
    1, K (``sun_gradient_k``: the bearing's own ``g``, or with ``sun_gradient_fit: deck`` the deck's
    one, 0 where the last fit left the term out), its sd (``sun_gradient_sd_k``: from the noise's
    long-run variance, or the deck's posterior from both bearings, the prior's before any; what a
    misread sky adds is not in it), whether the last fit used it (``sun_gradient_used``; ``deck``:
    the evidence carried it, ``Compensation._sun_carried``), ``ln`` of the Bayes factor of one ``g``
    of the deck against no term (``sun_gradient_log_bf``) and of a ``g`` of each bearing's own
    against none (``sun_gradient_log_bf_per_bearing``: above the first, ``deck`` leaves it out),
    and which fit it is (``sun_gradient_fit``); with ``average`` (shipped) the probability of one
    ``g`` of the deck among no term, it and a ``g`` of each bearing's own (``sun_gradient_weight``:
    ``sun_gradient_k`` and its sd are the average's).
    """
    info: dict[str, dict[str, Any]] = {}
    fit = shadow.fit
    levels = current_level(shadow)
    for c, ch in enumerate(CHANNELS):
        level = float("nan") if levels is None else float(levels[c])
        info[ch] = {
            "edf": float(fit.edf[c]) if fit is not None else float("nan"),
            "lambda": float(fit.lam[c]) if fit is not None else float("nan"),
            "mean_force_n": level,
            "windows": int(shadow.sums.n + len(shadow._rows)),
            "t_min_c": float(fit.t_lo[c]) if fit is not None else float("nan"),
            "t_max_c": float(fit.t_hi[c]) if fit is not None else float("nan"),
        }
        comp = shadow.compensation
        if comp.sun and fit is not None:  # the sun term's difference at a covariate of 1, K
            slope = float(comp.sun_slope[c])
            info[ch]["sun_gradient_k"] = float(fit.beta[c, -1]) / slope + 0.0  # (no -0.0 at the bound)
            if comp.sun_fit == "deck":  # one g from both bearings
                sd = fit.sun_evidence[3] if np.isfinite(fit.sun_evidence[3]) else comp.sun_prior_k[1]
            elif comp.sun_fit == "average" and np.all(np.isfinite(fit.sun_evidence)):  # the mixture's
                sd = comp.averaged_sun(fit.sun_evidence)[1] * float(fit.sun_evidence[3])
            else:  # the bearing's own, with the noise's long-run (AR(1)) variance, as the levels take it
                var = float(shadow.noise.long_run_cov()[c, c]) * float(fit.minv[c, -1, -1])
                sd = float(np.sqrt(max(var, 0.0))) / abs(slope)
            info[ch]["sun_gradient_sd_k"] = float(sd)
            info[ch]["sun_gradient_fit"] = comp.sun_fit
            info[ch]["sun_gradient_used"] = fit.sun_used
            info[ch]["sun_gradient_log_bf"] = fit.sun_log_bf
            info[ch]["sun_gradient_log_bf_per_bearing"] = float(fit.sun_evidence[1])
            if comp.sun_fit == "average":  # the deck's g in with this probability (``deck_sun_weight``)
                info[ch]["sun_gradient_weight"] = deck_sun_weight(fit.sun_evidence)
    return info


def noise_info(shadow: Shadow) -> dict[str, Any]:
    """Noise model: mode, phi per channel, per-sample-equivalent sigma (N), windows behind it."""
    return {
        "mode": shadow.config.noise_mode,
        "phi": shadow.noise.phi.tolist(),
        "sigma_n": shadow.noise.sample_sigma.tolist(),
        "windows": shadow.noise.n,
    }


def prior_info(shadow: Shadow) -> dict[str, Any]:
    """Return the prior in use: sigma per support (m), its source, and an event's opening (m)."""
    return {
        "sigma_m": shadow.prior_sigma_m.tolist(),
        "source": shadow.prior_source,
        "event_jump_sigma_m": shadow.jump_sigma_m.tolist(),
    }


def diagnostics(shadow: Shadow, now_ns: int | None = None) -> dict[str, Any]:
    """Health and key values (SI): level OK/WARN/ERROR, message, posterior, counts, events."""
    mean, cov = shadow.posterior
    clock = shadow.clock_ns
    ref = now_ns if now_ns is not None else clock
    staleness = {
        key: (None if g.last_ns is None or ref is None else (ref - g.last_ns) / _NS)
        for key, g in zip(TOPIC_KEYS, shadow.gates, strict=True)
    }
    timeout = max(shadow.config.topic_timeout_s, shadow.config.window_s)
    stale = [k for k, v in staleness.items() if v is None or v > timeout]
    lines = warnings(shadow)
    if not np.all(np.isfinite(mean)) or not np.all(np.isfinite(cov)):
        level, message = "ERROR", "posterior is not finite"
    elif clock is not None and len(stale) == len(TOPIC_KEYS):
        level, message = "ERROR", "no input on any topic"
    elif lines:
        level, message = "WARN", "; ".join(lines)
    elif stale:
        level, message = "WARN", f"stale or missing topic(s): {', '.join(stale)}"
    elif not shadow.warm and shadow.buffer.held_since_ns is not None:
        level, message = "OK", "waiting for the first record to end"
    elif not shadow.warm:
        level, message = "WARN", f"warming up ({len(shadow._warm)}/{shadow.config.warmup_windows} windows)"
    elif shadow.noise.adaptive and (seen_s := shadow.noise.n * shadow.config.window_s) < NOISE_FULL_DAY_S:
        level, message = (
            "WARN",
            f"noise model has seen {seen_s / 3600.0:.1f} h (< 24 h): intervals may be optimistic "
            "until a whole day of sun and traffic is in the residuals",
        )
    else:
        level, message = "OK", "tracking"
    if (held := shadow.buffer.held_since_ns) is not None:  # the posterior follows at the record's end
        message += f"; holding the record since {iso_utc(held)} for the traffic screen"
    sigma = np.sqrt(np.diag(cov))
    summary = ", ".join(
        f"{s} {1e3 * mu:+.3f} ± {1e3 * sd:.3f} mm" for s, mu, sd in zip(SUPPORTS, mean, sigma, strict=True)
    )
    return {
        "level": level,
        "message": message,
        "summary": summary,
        "mean_m": mean.tolist(),
        "covariance_m2": cov.tolist(),
        "sigma_m": sigma.tolist(),
        "used": dict(shadow.used),
        "rejected": shadow.rejected,
        "staleness_s": staleness,
        "spline": spline_info(shadow),
        "noise": noise_info(shadow),
        "prior": prior_info(shadow),
        "events": [e.to_json() for e in event_records(shadow)],
        "unconfirmed_changes": [c.to_json() for c in unconfirmed_changes(shadow)],
        "gaps": gaps(shadow),
        "state": posterior_state(shadow),
        "recent_rejected_windows": [rejected_window(k, shadow._w_ns, r) for k, r in shadow.recent_rejected],
        "warnings": lines,
        "traffic": traffic_info(shadow),
        "windows": {
            "closed": shadow.n_windows,
            "fitted": int(shadow.sums.n + len(shadow._rows)),
            "held": len(shadow._queue),
            "updates": shadow.n_updates,
            "uncompensated": shadow.uncompensated,
            "stale_temperature": shadow.stale_temperature,
            "warm": shadow.warm,
        },
        "clock_ns": clock,
    }


def traffic_info(shadow: Shadow) -> dict[str, Any]:
    """Return what the traffic screen cut: samples per channel; per window its time, cut and kept.

    ``held_since`` names the record held for the screen now (None: nothing held).
    """
    rows = shadow.traffic_windows
    w = shadow._w_ns
    held = shadow.buffer.held_since_ns
    return {
        "samples_cut": [int(sum(r[1] for r in rows)), int(sum(r[2] for r in rows))],
        "windows_cut": len(rows),
        "hold_s": float(shadow.config.traffic_hold_s),
        "held_since_ns": held,
        "held_since": None if held is None else iso_utc(held),
        "windows": [
            {"time_ns": r[0] * w, "time": iso_utc(r[0] * w), "window": r[0], "cut": r[1:3], "kept": r[3:5]}
            for r in rows
        ],
        "parked": parked_loads(shadow),
        # records longer than the hold: passed unscreened (a test car parked in them is data)
        "released_unscreened": [
            {"since_ns": a, "since": iso_utc(a), "past_hold_ns": b, "past_hold": iso_utc(b)}
            for a, b in shadow.buffer.released
        ],
    }


def parked_loads(shadow: Shadow) -> list[dict[str, Any]]:
    """Vehicles parked at a record's end, cut from their arrival on (``inputs.traffic.parked_start``).

    Per record: when they arrived and when the record ended, their load per channel (N), and the
    change of the supports (m) that would put the same load on the bearings (``A^-1`` load): the
    screen cannot tell the two apart at a record's end, and takes the load as vehicles. Both None
    where the record kept no sample before them to measure the load from.
    """
    out = []
    for since, until, a, b in shadow.parked:
        load = np.array([a, b], float)
        known = bool(np.all(np.isfinite(load)))
        out.append(
            {
                "since_ns": int(since),
                "since": iso_utc(int(since)),
                "until_ns": int(until),
                "until": iso_utc(int(until)),
                "load_n": load.tolist() if known else None,
                "as_change_m": np.linalg.solve(shadow.A, load).tolist() if known else None,
            }
        )
    return out


def replay_result(shadow: Shadow, outputs: list[WindowOutput], messages: int, seconds: float) -> ReplayResult:
    """Return the replay result of what this shadow has seen."""
    mean, cov = shadow.posterior
    return ReplayResult(
        mean_m=mean,
        covariance_m2=cov,
        messages=messages,
        used=dict(shadow.used),
        rejected=shadow.rejected,
        windows=shadow.n_windows,
        updates=shadow.n_updates,
        spline=spline_info(shadow),
        noise=noise_info(shadow),
        outputs=outputs,
        seconds=seconds,
        events=event_records(shadow),
        warnings=warnings(shadow),
        prior=prior_info(shadow),
        uncompensated_windows=shadow.uncompensated,
        stale_temperature_windows=shadow.stale_temperature,
        changes=unconfirmed_changes(shadow),
        state=posterior_state(shadow),
        gaps=gaps(shadow),
        traffic=traffic_info(shadow),
        rejected_list=rejected_list(shadow),
    )


def rejected_list(shadow: Shadow) -> list[dict[str, Any]]:
    """Every window the shadow rejected, in order: start time, window and reason (``rejected_runs``).

    From the shadow's own log, so that the replay JSON lists every one whatever window outputs
    the caller kept (a replay streams them to ``--out`` and keeps none, or a decimated history
    for ``--plots``; it listed none, or a sample).
    """
    return [
        rejected_window(k, shadow._w_ns, reason)
        for first, last, reason in shadow.rejected_runs
        for k in range(first, last + 1)
    ]
