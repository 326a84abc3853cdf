"""What the shadow reports: diagnostics, events, warnings, compensation and noise, a replay's result.

Plain functions of a ``Shadow`` (SI units; text for people only in the messages). The node turns
``diagnostics`` into ``/diagnostics`` (``bridge_shadow.ros.diagnostics``); replay prints and dumps
``replay_result(...).to_json()``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from bridge_shadow.contract import CHANNELS, SUPPORTS
from bridge_shadow.estimate.inputs import TOPIC_KEYS
from bridge_shadow.estimate.result import EventRecord, ReplayResult, WindowOutput

if TYPE_CHECKING:
    from bridge_shadow.estimate.shadow import Shadow

__all__ = [
    "NOISE_FULL_DAY_S",
    "diagnostics",
    "event_records",
    "noise_info",
    "prior_info",
    "replay_result",
    "spline_info",
    "warnings",
]

#: Residual history the adaptive noise model needs before the diagnostics call its intervals
#: calibrated: one whole day (a quiet night gives intervals too narrow for the day that follows).
NOISE_FULL_DAY_S = 86_400.0
_NS = 1_000_000_000


def event_records(shadow: Shadow) -> list[EventRecord]:
    """Return the detected events with their size and covariance as the data now say (last refit)."""
    out = []
    summaries = getattr(shadow.filter, "summaries", [])
    for i, e in enumerate(shadow.events):
        s = i + 1
        size = np.full(2, np.nan)
        cov = np.full((2, 2), np.nan)
        if s < len(summaries):
            a, b = summaries[s - 1], summaries[s]
            size = b.x_data - a.x_data
            # the data's part, and the model's: a step read through an uncertain A (u0 cancels)
            cov = a.d_cov + b.d_cov + shadow.surrogate.model_covariance(size, with_u0=False)
        out.append(
            EventRecord(
                int(e["window"]),
                int(e["window"]) * shadow._w_ns,
                int(e["detected_window"]),
                size,
                cov,
                float(e["glr"]),
                np.asarray(e["step_n"], float),
            )
        )
    return out


def warnings(shadow: Shadow) -> list[str]:
    """Problems a user must hear about (one line each): silent failures made loud."""
    out = []
    if shadow.uncompensated:
        out.append(
            f"no air temperature: {shadow.uncompensated} windows used without temperature compensation "
            f"(topic {shadow.config.topic_air_temperature} delivered no accepted reading)"
        )
    for ledger in shadow.ledgers:
        line = ledger.all_rejected_message()
        if line:
            out.append(line)
    if shadow.n_windows and not shadow.n_updates:
        out.append("no window updated the estimate: the posterior is the prior")
    return out


def spline_info(shadow: Shadow) -> dict[str, dict[str, float]]:
    """Per channel: edf, lambda, level, windows fitted, temperature range (NaN before a fit)."""
    info: dict[str, dict[str, float]] = {}
    fit = shadow.fit
    for c, ch in enumerate(CHANNELS):
        level = float("nan")
        if fit is not None and len(fit.level):
            level = float(fit.level[min(shadow.filter.segment, len(fit.level) - 1), c] + shadow.u0[c])
        info[ch] = {
            "edf": float(fit.edf[c]) if fit is not None else float("nan"),
            "lambda": float(fit.lam[c]) if fit is not None else float("nan"),
            "mean_force_n": level,
            "windows": int(shadow.sums.n + len(shadow._rows)),
            "t_min_c": float(fit.t_lo[c]) if fit is not None else float("nan"),
            "t_max_c": float(fit.t_hi[c]) if fit is not None else float("nan"),
        }
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
        "warnings": lines,
        "windows": {
            "closed": shadow.n_windows,
            "fitted": int(shadow.sums.n + len(shadow._rows)),
            "held": len(shadow._queue),
            "updates": shadow.n_updates,
            "uncompensated": shadow.uncompensated,
            "warm": shadow.warm,
        },
        "clock_ns": clock,
    }


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
    )
