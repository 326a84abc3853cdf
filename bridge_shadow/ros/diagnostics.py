"""``/diagnostics`` for the node: the small piece of diagnostic_updater we need (not on PyPI).

``statuses`` turns ``Shadow.diagnostics()`` plus the node's own input bookkeeping into four
statuses (settlement, inputs, compensation, events; plain data, testable without DDS);
``diagnostic_array`` builds the
``diagnostic_msgs/DiagnosticArray``. Levels follow ``diagnostic_msgs/DiagnosticStatus``:
0 OK, 1 WARN, 2 ERROR. Values are text for people, so settlements are in mm and forces in kN.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from bridge_shadow.contract import CHANNELS, NODE_NAME, SUPPORTS
from bridge_shadow.ros.convert import stamp_msg
from bridge_shadow.timefmt import iso_utc

__all__ = ["LEVELS", "Status", "diagnostic_array", "event_text", "statuses"]

#: diagnostic_msgs levels by the names ``Shadow.diagnostics()`` uses.
LEVELS: dict[str, int] = {"OK": 0, "WARN": 1, "ERROR": 2}
HARDWARE_ID = "unibw_test_bridge"


@dataclass
class Status:
    """One ``DiagnosticStatus`` as plain data (level 0 OK, 1 WARN, 2 ERROR)."""

    name: str
    level: int
    message: str
    values: dict[str, str] = field(default_factory=dict)


def _num(value: Any, fmt: str) -> str:
    return "n/a" if value is None or value != value else format(value, fmt)


def _estimate(diag: Mapping[str, Any]) -> Status:
    mean = diag["mean_m"]
    sigma = diag["sigma_m"]
    cov = diag["covariance_m2"]
    values: dict[str, str] = {}
    for i, side in enumerate(SUPPORTS):
        values[f"{side} settlement [mm]"] = _num(1e3 * mean[i], "+.4f")
        values[f"{side} sigma [mm]"] = _num(1e3 * sigma[i], ".4f")
    rho = cov[0][1] / (sigma[0] * sigma[1]) if sigma[0] > 0 and sigma[1] > 0 else float("nan")
    values["correlation"] = _num(rho, "+.3f")
    windows = diag["windows"]
    for key in ("closed", "fitted", "held", "updates"):
        values[f"windows {key}"] = str(windows[key])
    values["warm"] = str(bool(windows["warm"])).lower()
    return Status(
        f"{NODE_NAME}: settlement",
        LEVELS[diag["level"]],
        f"{diag['message']}; {diag['summary']}",
        values,
    )


def _inputs(
    diag: Mapping[str, Any],
    arrival_age_s: Mapping[str, float | None],
    malformed: int,
    timeout_s: float,
    running_s: float | None = None,
) -> Status:
    values: dict[str, str] = {}
    quiet, waiting = [], []
    for topic, used in diag["used"].items():
        age = arrival_age_s.get(topic)
        values[f"{topic} used"] = str(used)
        values[f"{topic} last arrival [s ago]"] = _num(age, ".2f")
        values[f"{topic} stamp lag [s]"] = _num(diag["staleness_s"].get(topic), ".2f")
        if age is None and running_s is not None and running_s <= timeout_s:
            waiting.append(topic)  # not heard from yet, but the node has not waited timeout_s
        elif age is None or age > timeout_s:
            quiet.append(topic)
    rejected = diag["rejected"]
    for reason, count in rejected.items():
        values[f"rejected {reason}"] = str(count)
    values["rejected malformed"] = str(malformed)
    n_rejected = sum(rejected.values()) + malformed
    if len(quiet) == len(diag["used"]):
        level, message = LEVELS["ERROR"], f"no input for {timeout_s:g} s on any topic"
    elif quiet:
        level, message = LEVELS["WARN"], f"no input for {timeout_s:g} s: {', '.join(quiet)}"
    elif len(waiting) == len(diag["used"]):
        level, message = LEVELS["OK"], f"waiting for input (started {running_s:.0f} s ago)"
    elif waiting:
        level, message = LEVELS["OK"], f"receiving; waiting for {', '.join(waiting)}"
    else:
        level, message = LEVELS["OK"], "receiving"
    if n_rejected:
        top = sorted(((c, r) for r, c in rejected.items() if c), reverse=True)[:3]
        message += f"; {n_rejected} rejected ({', '.join(f'{r} {c}' for c, r in top) or 'malformed'})"
    lost = [w for w in diag.get("warnings", []) if w.startswith("topic ")]
    if lost:  # a topic whose every message was rejected: name it, the reason and what was expected
        level = max(level, LEVELS["WARN"])
        message += "; " + "; ".join(lost)
    return Status(f"{NODE_NAME}: inputs", level, message, values)


def _compensation(diag: Mapping[str, Any]) -> Status:
    values: dict[str, str] = {}
    for ch in CHANNELS:
        sp = diag["spline"][ch]
        # no temperature fitted yet (none came, or no fit): no curve, no range ('inf', 'inf .. -inf')
        lo, hi = sp["t_min_c"], sp["t_max_c"]
        curve = bool(sp["windows"]) and lo is not None and hi is not None and lo <= hi
        values[f"{ch} edf"] = _num(sp["edf"], ".2f")
        values[f"{ch} lambda [C^3]"] = _num(sp["lambda"] if curve else None, ".4g")
        values[f"{ch} mean force [kN]"] = _num(1e-3 * sp["mean_force_n"], ".3f")
        values[f"{ch} windows"] = str(sp["windows"])
        span = f"{_num(lo, '.1f')} .. {_num(hi, '.1f')}" if curve else "n/a"
        values[f"{ch} temperature range [C]"] = span
        if "sun_gradient_k" in sp:  # the sun term (sun_gradient): its difference at full sun
            values[f"{ch} sun term [K]"] = _num(sp["sun_gradient_k"], ".2f")
            values[f"{ch} sun term sd [K]"] = _num(sp["sun_gradient_sd_k"], ".2f")
            values[f"{ch} sun term used"] = str(bool(sp.get("sun_gradient_used", True))).lower()
            log_bf = sp.get("sun_gradient_log_bf", float("nan"))
            values[f"{ch} sun term log Bayes factor"] = _num(log_bf, ".2f")
            if "sun_gradient_weight" in sp:  # average: the deck's g in with this probability
                values[f"{ch} sun term probability"] = _num(sp["sun_gradient_weight"], ".2f")
    noise = diag["noise"]
    values["noise mode"] = str(noise["mode"])
    for ch, phi, sd in zip(CHANNELS, noise["phi"], noise["sigma_n"], strict=True):
        values[f"{ch} noise phi"] = _num(phi, ".3f")
        values[f"{ch} noise sigma [kN]"] = _num(1e-3 * sd, ".4f")
    values["uncompensated windows"] = str(diag["windows"].get("uncompensated", 0))
    values["stale temperature windows"] = str(diag["windows"].get("stale_temperature", 0))
    warm = bool(diag["windows"]["warm"])
    uncompensated = int(diag["windows"].get("uncompensated", 0))
    stale = int(diag["windows"].get("stale_temperature", 0))
    if uncompensated:
        level, message = LEVELS["WARN"], f"no air temperature: {uncompensated} windows used uncompensated"
    elif stale:
        level, message = LEVELS["WARN"], f"stale air temperature: {stale} windows used, compensation widened"
    elif warm:
        level, message = LEVELS["OK"], "warm"
    else:
        level, message = LEVELS["WARN"], f"warming up ({diag['windows']['fitted']} windows fitted)"
    return Status(f"{NODE_NAME}: compensation", level, message, values)


def event_text(e: Mapping[str, Any]) -> str:
    """One event of the JSON as text for people: kind, time, size per support in mm (95 %)."""
    size = ", ".join(
        f"{side} {1e3 * m:+.3f} ± {1.96e3 * sd:.3f}"
        for side, m, sd in zip(SUPPORTS, e["size_m"], e["sigma_m"], strict=True)
    )
    note = "" if e.get("size_significant95", True) else "; region holds zero"
    return f"{e.get('kind', 'step')} at {iso_utc(e['time_ns'])}: {size} mm (95 %{note})"


def _events(diag: Mapping[str, Any]) -> Status:
    """Build the events status: the last one in the message, each in the values (mm)."""
    events = diag.get("events", [])
    values: dict[str, str] = {"events": str(len(events))}
    for i, e in enumerate(events):
        values[f"event {i + 1}"] = event_text(e)
    changes = diag.get("unconfirmed_changes", [])
    for i, c in enumerate(changes):
        if all(math.isfinite(v) for v in (*c["size_m"], *c["sigma_m"])):
            size = (
                ", ".join(
                    f"{side} {1e3 * m:+.3f} ± {1.96e3 * sd:.3f}"
                    for side, m, sd in zip(SUPPORTS, c["size_m"], c["sigma_m"], strict=True)
                )
                + " mm (95 %"
            )
        else:  # a gap whose record is still held (the traffic screen): no window measured it yet
            size = "size not measured yet, no window since (95 % interval: none"
        p = c.get("change_probability")
        unweighed = {
            "step": "not significant",
            "excursion": "rejected",
            "between_steps": "left out",
            "before_gap": "left out",
            "after_gap": "left out",
            "at_end": "left out",
        }.get(c["kind"], "used as data")
        how = unweighed if p is None else f"probability {p:.3g}"
        values[f"unconfirmed {i + 1}"] = f"{c['kind']} at {c['time']}: {size}; {how})"
    state = diag.get("state", {})
    if state.get("text"):
        values["posterior stands for"] = state["text"]
    likely = [c for c in changes if c.get("likely")]
    if not events and not likely:
        return Status(f"{NODE_NAME}: events", LEVELS["OK"], "no settlement event", values)
    parts = []
    if events:
        parts.append(f"{len(events)} settlement event(s); last: {values[f'event {len(events)}']}")
    if likely:
        parts.append(f"{len(likely)} unconfirmed change(s); last at {likely[-1]['time']}")
    return Status(f"{NODE_NAME}: events", LEVELS["WARN"], "; ".join(parts), values)


def statuses(
    diag: Mapping[str, Any],
    arrival_age_s: Mapping[str, float | None],
    malformed: int = 0,
    timeout_s: float = 60.0,
    running_s: float | None = None,
) -> list[Status]:
    """Build the node's statuses: settlement, inputs, compensation, events.

    Args:
        diag: ``Shadow.diagnostics()`` (SI units).
        arrival_age_s: per topic key, wall seconds since the last message arrived (None: never).
        malformed: raw messages the node could not decode.
        timeout_s: an input quiet for longer is stale (WARN; ERROR when every topic is).
        running_s: wall seconds since the node started (None: unknown): a topic never heard
            from is quiet only once the node has run ``timeout_s``.

    """
    return [
        _estimate(diag),
        _inputs(diag, arrival_age_s, malformed, timeout_s, running_s),
        _compensation(diag),
        _events(diag),
    ]


def diagnostic_array(items: Sequence[Status], stamp_ns: int) -> DiagnosticArray:
    """Build a ``DiagnosticArray`` stamped ``stamp_ns`` from plain statuses."""
    msg = DiagnosticArray()
    msg.header.stamp = stamp_msg(stamp_ns)
    msg.status = [
        DiagnosticStatus(
            level=bytes([s.level]),
            name=s.name,
            message=s.message,
            hardware_id=HARDWARE_ID,
            values=[KeyValue(key=k, value=v) for k, v in s.values.items()],
        )
        for s in items
    ]
    return msg
