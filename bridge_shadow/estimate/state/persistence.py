"""The shadow's online state as nested plain data, and back (``Shadow.state_dict`` / ``from_state_dict``).

Every part contributes its own ``state_dict``; this module gathers them, plus the windows still on
their way to an output (the queue, the detector's held windows, the warm-up) and the rows not yet
in the sums. The result holds only arrays, numbers and strings (``checkpoint.save_state`` writes it
as one ``.npz`` without pickle). A shadow restored from it continues exactly as the uninterrupted
one would (to rounding).
"""

from __future__ import annotations

import json
from collections import Counter
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge_shadow.estimate.compensation.fit import CompensationFit
from bridge_shadow.estimate.events.detector import Pending
from bridge_shadow.estimate.inputs.closed_window import Window
from bridge_shadow.estimate.inputs.gate import REASONS
from bridge_shadow.estimate.parameters.config import ShadowConfig
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import TemperatureSeries

if TYPE_CHECKING:
    from bridge_shadow.estimate.shadow import Shadow

__all__ = ["held_air_arrays", "held_air_series", "restore_shadow", "shadow_state"]

_VERSION = 5  # 5: the sun term (basis width, the FE vertical-gradient response, the fit's bbar)
_NONE = -(2**62)
_FIT_FIELDS = (
    *("beta", "lam", "edf", "level", "dof", "minv", "t_lo", "t_hi", "kappa", "mbar", "sbar"),
    *("n", "bbar", "sun_evidence"),
)


def _opt(value: int | None) -> int:
    return _NONE if value is None else int(value)


def _unopt(value: Any) -> int | None:
    v = int(value)
    return None if v == _NONE else v


def _prev_state(p: Pending | None) -> dict[str, Any]:
    """Return the jump test's reference window as plain data (floats from the fast path, or arrays)."""
    if p is None:
        return {
            "has": False,
            "k": 0,
            "lazy": False,
            "v": np.zeros(2),
            "r": np.zeros((2, 2)),
            "apa": np.zeros((2, 2)),
        }
    lazy = isinstance(p.v, tuple)

    def arr(m: Any) -> np.ndarray:
        return np.array([[m[0], m[1]], [m[1], m[2]]]) if lazy else np.asarray(m, float)

    return {
        "has": True,
        "k": p.k,
        "lazy": lazy,
        "v": np.asarray(p.v, float),
        "r": arr(p.r_window),
        "apa": arr(p.apa),
    }


def _restore_prev(state: dict[str, Any]) -> Pending | None:
    if not bool(state["has"]):
        return None
    v = np.asarray(state["v"], float).reshape(2)
    r = np.asarray(state["r"], float).reshape(2, 2)
    apa = np.asarray(state["apa"], float).reshape(2, 2)
    if bool(state["lazy"]):
        sym = lambda m: (float(m[0, 0]), float(m[0, 1]), float(m[1, 1]))  # noqa: E731
        return Pending(int(state["k"]), (float(v[0]), float(v[1])), sym(r), sym(apa), None)
    return Pending(int(state["k"]), v, r, apa, None)


def _window_state(w: Any) -> dict[str, Any]:
    """Return the last window used as plain data (or none)."""
    if w is None:
        return {"has": False}
    return {
        "has": True,
        "k": w.k,
        "samples": np.asarray(w.samples),
        "force": np.asarray(w.force, float),
        "temp": np.asarray(w.temp, float),
        "i0": np.asarray(w.i0),
        "bv": np.asarray(w.bv, float),
    }


def _windows_state(windows: list[Window], width: int) -> dict[str, Any]:
    """Return windows (the queue's, the young ones) as arrays, one row each."""
    return {
        "k": np.array([w.k for w in windows], np.int64),
        "samples": np.array([w.samples for w in windows], np.int64).reshape(-1, 2),
        "force": np.array([w.force for w in windows], float).reshape(-1, 2),
        "temp": np.array([w.temp for w in windows], float).reshape(-1, 2),
        "reason": json.dumps([w.reason for w in windows]),
        "action": json.dumps([w.action for w in windows]),
        "i0": np.array([w.i0 for w in windows], np.int64).reshape(-1, 2),
        "bv": np.array([w.bv for w in windows], float).reshape(-1, 2, width),
        "svar": np.array([w.svar for w in windows], float),
        "tvar": np.array([w.tvar for w in windows], float),
        "event_end": np.array([w.event_end for w in windows], bool),
        "seg": np.array([w.seg for w in windows], np.int64),
    }


def _windows_restored(q: dict[str, Any], width: int) -> list[Window]:
    """Return the windows ``_windows_state`` wrote."""
    reasons = json.loads(str(q["reason"]))
    actions = json.loads(str(q["action"]))
    out = []
    for i, k in enumerate(np.asarray(q["k"]).ravel()):
        w = Window(
            int(k),
            np.asarray(q["samples"]).reshape(-1, 2)[i],
            np.asarray(q["force"], float).reshape(-1, 2)[i],
            np.asarray(q["temp"], float).reshape(-1, 2)[i],
            reasons[i],
            np.asarray(q["i0"]).reshape(-1, 2)[i],
            np.asarray(q["bv"], float).reshape(-1, 2, width)[i],
            float(np.asarray(q["svar"], float).ravel()[i]),
            float(np.asarray(q["tvar"], float).ravel()[i]) if "tvar" in q else 0.0,
        )
        w.action = actions[i]
        w.event_end = bool(np.asarray(q["event_end"]).ravel()[i])
        w.seg = int(np.asarray(q["seg"]).ravel()[i])
        out.append(w)
    return out


def shadow_state(shadow: Shadow) -> dict[str, Any]:
    """Return the state of ``shadow`` as nested plain data."""
    queue = list(shadow._queue)
    index = {id(w): i for i, w in enumerate(queue)}
    width = shadow.compensation.width
    det = shadow.detector
    rows = shadow._rows
    fit = shadow.fit
    return {
        "version": _VERSION,
        "config": json.dumps(shadow.config.to_params()),
        "surrogate": {
            "A": shadow.surrogate.A,
            "u0": shadow.surrogate.u0,
            "uniform": shadow.surrogate.thermal.get("uniform", np.zeros(2)),
            "vertical_gradient": shadow.surrogate.thermal.get("vertical_gradient", np.zeros(2)),
        },
        "gates": [g.state_dict() for g in shadow.gates],
        "ledgers": [led.state_dict() for led in shadow.ledgers],
        "sun": shadow.sun.state_dict() if shadow.sun is not None else {},
        "counts": json.dumps({k: int(v) for k, v in shadow.counts.items()}),
        "used": json.dumps(shadow.used),
        "buffer": shadow.buffer.state_dict(),
        "sums": shadow.sums.state_dict(),
        "has_fit": fit is not None,
        "fit": {f: np.asarray(getattr(fit, f)) for f in _FIT_FIELDS} if fit is not None else {"n": 0},
        "lam": shadow.lam.copy(),
        "noise": shadow.noise.state_dict(),
        "filter": shadow.filter.state_dict(),
        "detector": {
            "n_events": det.n_events,
            "phi": det.phi.copy(),
            "inflation": det.inflation,
            "max_jump": det.max_jump,
            "max_jump_before": det.max_jump_before,
            "pending_index": np.array([index[id(p.payload)] for p in det.pending], np.int64),
            "pending_v": np.array([p.v for p in det.pending]).reshape(-1, 2),
            "pending_r": np.array([p.r_window for p in det.pending]).reshape(-1, 2, 2),
            "pending_apa": np.array([p.apa for p in det.pending]).reshape(-1, 2, 2),
            "prev": _prev_state(det.prev),
            "history": np.array(list(det.history), float).reshape(-1, 3),
            "left_k": det.left_k,
            "left_level": np.asarray(det.left_level, float).reshape(2),
        },
        "last_ok": _window_state(shadow._last_ok),
        "queue": {
            **_windows_state(queue, width),
            "warm": np.array([index[id(w)] for w in shadow._warm], np.int64),
            "fresh": np.array([index[id(w)] for w in shadow._fresh], np.int64),
        },
        "latest": _windows_state(list(shadow._latest), width),
        "young": {
            **_windows_state(shadow._young, width),
            "in_queue": np.array([index.get(id(w), -1) for w in shadow._young], np.int64),
            "done": shadow._young_done,
        },
        "rows": {
            "k": np.array([r[0] for r in rows], np.int64),
            "m": np.array([r[1] for r in rows], float).reshape(-1, 2),
            "y": np.array([r[2] for r in rows], float).reshape(-1, 2),
            "t": np.array([r[3] for r in rows], float).reshape(-1, 2),
            "i0": np.array([r[4] for r in rows], np.int64).reshape(-1, 2),
            "bv": np.array([r[5] for r in rows], float).reshape(-1, 2, width),
            "seg": np.array([r[6] for r in rows], np.int64),
            "sv": np.array([r[7] for r in rows], float),
        },
        "events": json.dumps(
            [
                {**e, "step_n": np.asarray(e["step_n"], float).tolist(), "glr": float(e["glr"])}
                for e in shadow.events
            ]
        ),
        "gaps": json.dumps(shadow.gaps),
        "last_usable_sun": json.dumps(shadow._last_usable_sun),
        "confirmed_at": json.dumps([[k, v] for k, v in shadow.confirmed_at.items()]),
        "unconfirmed_runs": json.dumps(shadow.unconfirmed_runs),
        "excursions": json.dumps(shadow.excursions),
        "recent_rejected": json.dumps(list(shadow.recent_rejected)),
        "rejected_runs": json.dumps(shadow.rejected_runs),
        "traffic_windows": json.dumps(shadow.traffic_windows),
        "parked": json.dumps(shadow.parked),
        "silence": json.dumps(shadow.silence.state_dict()),
        "relax": json.dumps(shadow._relax),
        "air": json.dumps(shadow.air),
        "taken_bags": json.dumps(shadow.taken_bags),
        **({"held_air": held_air_arrays(shadow.held_air)} if shadow.held_air is not None else {}),
        "scalars": {
            "last_usable_k": _opt(shadow._last_usable_k),
            "last_data_k": _opt(shadow._last_data_k),
            "outage_since_usable": int(shadow._outage_since_usable),
            "n_windows": shadow.n_windows,
            "uncompensated": shadow.uncompensated,
            "stale_temperature": shadow.stale_temperature,
            "warm": int(shadow.warm),
            "fresh_open": int(shadow._fresh_open),
            "n_accepted": shadow._n_accepted,
            "refit_at": shadow._refit_at,
            "lambda_at": shadow._lambda_at,
            "ckpt_ns": _opt(shadow._ckpt_ns),
            "first_ns": _opt(shadow._first_ns),
            "last_judged": shadow._last_judged,
        },
    }


def held_air_arrays(t: TemperatureSeries) -> dict[str, np.ndarray]:
    """Return the air messages a checkpoint holds unfed (frame ids as strings: no pickle in the file)."""
    return {
        "stamp_ns": t.stamp_ns,
        "temp_c": t.temp_c,
        "variance": np.asarray(t.variance, float),
        "frame_id": np.asarray(t.frame_id, dtype=str),
        "log_ns": np.asarray(t.log_ns, np.int64),
    }


def held_air_series(d: dict[str, Any]) -> TemperatureSeries:
    """Return the air messages ``held_air_arrays`` wrote, as a ``TemperatureSeries``."""
    frames = np.asarray(d["frame_id"]).ravel().astype(object)
    arrays = [np.asarray(d[k]).ravel() for k in ("stamp_ns", "temp_c", "variance")]
    return TemperatureSeries(*arrays, frames, np.asarray(d["log_ns"]).ravel())


def restore_shadow(
    cls: type[Shadow], state: dict[str, Any], config: ShadowConfig | None, surrogate: Surrogate | None
) -> Shadow:
    """Rebuild a shadow of class ``cls`` from ``shadow_state`` output."""
    if int(state.get("version", 1)) != _VERSION:
        from bridge_shadow.errors import InputError

        raise InputError(f"checkpoint version {state.get('version', 1)} is not {_VERSION}: start without it")
    if config is None:
        config = ShadowConfig.from_params(json.loads(str(state["config"])))
    if surrogate is None:
        s = state["surrogate"]
        thermal = {k: np.asarray(s[k]) for k in ("uniform", "vertical_gradient")}
        surrogate = Surrogate(np.asarray(s["A"]), np.asarray(s["u0"]), thermal)
    shadow = cls(config, surrogate)
    width = shadow.compensation.width
    for g, s in zip(shadow.gates, state["gates"], strict=True):
        g.load_state_dict(s)
    for led, s in zip(shadow.ledgers, state["ledgers"], strict=True):
        led.load_state_dict(s)
    shadow.counts = Counter(dict.fromkeys(REASONS, 0))
    shadow.counts.update(json.loads(str(state["counts"])))
    shadow.used = {k: int(v) for k, v in json.loads(str(state["used"])).items()}
    shadow.buffer.load_state_dict(state["buffer"])
    shadow.sums.load_state_dict(state["sums"])
    if shadow.sun is not None:
        shadow.sun.load_state_dict(state["sun"])
    if bool(state["has_fit"]):
        f = state["fit"]
        # (a checkpoint from before the sun evidence has none: the field's default)
        evidence = {"sun_evidence": np.asarray(f["sun_evidence"], float)} if "sun_evidence" in f else {}
        shadow.fit = CompensationFit(
            *(np.asarray(f[name], float) for name in _FIT_FIELDS[:-3]),
            int(f["n"]),  # type: ignore[arg-type]
            np.asarray(f["bbar"], float),
            shadow.compensation.sun,
            **evidence,
        )
    shadow.lam = np.asarray(state["lam"], float).reshape(2)
    shadow.noise.load_state_dict(state["noise"])
    shadow.filter.load_state_dict(state["filter"])
    if shadow.fit is not None:
        shadow.filter.use_noise(shadow.noise)
    q = state["queue"]
    queue = _windows_restored(q, width)
    shadow._queue.extend(queue)
    shadow._warm = [queue[int(i)] for i in np.asarray(q["warm"]).ravel()]
    shadow._fresh = [queue[int(i)] for i in np.asarray(q["fresh"]).ravel()] if "fresh" in q else []
    if "young" in state:  # (a checkpoint from before the young noise model's check: done)
        y = state["young"]
        own = _windows_restored(y, width)
        at = np.asarray(y["in_queue"], np.int64).ravel()
        shadow._young = [queue[int(i)] if i >= 0 else w for i, w in zip(at, own, strict=True)]
        shadow._young_done = bool(y["done"])
    else:
        shadow._young, shadow._young_done = [], True
    shadow._latest.clear()
    if "latest" in state:  # (a checkpoint from before the latest level's check: filled by new windows)
        shadow._latest.extend(_windows_restored(state["latest"], width))
    d = state["detector"]
    det = shadow.detector
    det.n_events = int(d["n_events"])
    det.phi = np.asarray(d["phi"], float).reshape(2)
    det.inflation = float(d["inflation"])
    det.max_jump = float(d["max_jump"])
    det.max_jump_before = float(d.get("max_jump_before", det.max_jump))
    det.prev = _restore_prev(d["prev"])
    det.history.clear()
    for k, v0, v1 in np.asarray(d.get("history", np.zeros((0, 3))), float).reshape(-1, 3):
        det.history.append((int(k), float(v0), float(v1)))
    det.left_k = int(d.get("left_k", -2))
    det.left_level = np.asarray(d.get("left_level", np.zeros(2)), float).reshape(2)
    lw = state["last_ok"]
    if bool(lw["has"]):
        shadow._last_ok = Window(
            int(lw["k"]),
            np.asarray(lw["samples"]).reshape(2),
            np.asarray(lw["force"], float).reshape(2),
            np.asarray(lw["temp"], float).reshape(2),
            "",
            np.asarray(lw["i0"]).reshape(2),
            np.asarray(lw["bv"], float).reshape(2, width),
        )
    if shadow.fit is not None:
        shadow._set_range(shadow.fit)
    det.pending = [
        Pending(int(queue[int(i)].k), v, r, a, queue[int(i)])
        for i, v, r, a in zip(
            np.asarray(d["pending_index"]).ravel(),
            np.asarray(d["pending_v"], float).reshape(-1, 2),
            np.asarray(d["pending_r"], float).reshape(-1, 2, 2),
            np.asarray(d["pending_apa"], float).reshape(-1, 2, 2),
            strict=True,
        )
    ]
    r = state["rows"]
    n_rows = len(np.asarray(r["k"]).ravel())
    shadow._rows = [
        (
            int(np.asarray(r["k"]).ravel()[i]),
            np.asarray(r["m"], float).reshape(-1, 2)[i],
            np.asarray(r["y"], float).reshape(-1, 2)[i],
            np.asarray(r["t"], float).reshape(-1, 2)[i],
            np.asarray(r["i0"]).reshape(-1, 2)[i],
            np.asarray(r["bv"], float).reshape(-1, 2, width)[i],
            int(np.asarray(r["seg"]).ravel()[i]),
            float(np.asarray(r["sv"], float).ravel()[i]),
        )
        for i in range(n_rows)
    ]
    shadow.events = [
        {**e, "step_n": np.asarray(e["step_n"], float)} for e in json.loads(str(state["events"]))
    ]
    shadow.gaps = [
        {k: [float(x) for x in v] if k == "sun_covariate" else int(v) for k, v in g.items()}
        for g in json.loads(str(state["gaps"]))
    ]
    if "last_usable_sun" in state:  # checkpoints written before the gaps' sun was kept have none
        sun = json.loads(str(state["last_usable_sun"]))
        shadow._last_usable_sun = None if sun is None else float(sun)
    shadow.confirmed_at = {int(k): int(v) for k, v in json.loads(str(state["confirmed_at"]))}
    shadow.unconfirmed_runs = list(json.loads(str(state["unconfirmed_runs"])))
    if "excursions" in state:  # checkpoints written before excursions were reported have none
        shadow.excursions = list(json.loads(str(state["excursions"])))
    shadow.recent_rejected.extend((int(k), str(r)) for k, r in json.loads(str(state["recent_rejected"])))
    if "rejected_runs" in state:  # checkpoints written before every rejected window was kept have none
        runs = json.loads(str(state["rejected_runs"]))
        shadow.rejected_runs = [[int(a), int(b), str(r)] for a, b, r in runs]
    shadow.traffic_windows = [[int(v) for v in row] for row in json.loads(str(state["traffic_windows"]))]
    if "parked" in state:  # checkpoints written before vehicles parked at a record's end were cut have none
        shadow.parked = [
            [int(t), int(e), float(a), float(b)] for t, e, a, b in json.loads(str(state["parked"]))
        ]
    if "silence" in state:  # checkpoints written before the silence was followed have none
        shadow.silence.load_state_dict(json.loads(str(state["silence"])))
    if "relax" in state:  # checkpoints written before the relaxation allowance have none
        rl = json.loads(str(state["relax"]))
        shadow._relax = None if rl is None else (int(rl[0]), float(rl[1]), float(rl[2]))
    if "air" in state:  # checkpoints written before the air's jumps were followed have none
        shadow.air = json.loads(str(state["air"]))
    if "taken_bags" in state:  # checkpoints written before the bags taken were recorded have none
        shadow.taken_bags = list(json.loads(str(state["taken_bags"])))
    if "held_air" in state:
        shadow.held_air = held_air_series(state["held_air"])
    sc = state["scalars"]
    shadow._last_usable_k = _unopt(sc["last_usable_k"])
    # checkpoints written before logger outages were marked have neither
    shadow._last_data_k = _unopt(sc["last_data_k"]) if "last_data_k" in sc else shadow._last_usable_k
    shadow._outage_since_usable = bool(int(sc.get("outage_since_usable", 0)))
    shadow.n_windows = int(sc["n_windows"])
    shadow.uncompensated = int(sc["uncompensated"])
    shadow.stale_temperature = int(sc["stale_temperature"]) if "stale_temperature" in sc else 0
    shadow.warm = bool(int(sc["warm"]))
    shadow._fresh_open = bool(int(sc["fresh_open"])) if "fresh_open" in sc else False
    shadow._n_accepted = int(sc["n_accepted"])
    shadow._refit_at = int(sc["refit_at"])
    shadow._lambda_at = int(sc["lambda_at"])
    shadow._ckpt_ns = _unopt(sc["ckpt_ns"])
    shadow._first_ns = _unopt(sc["first_ns"])
    shadow._last_judged = int(sc["last_judged"])
    return shadow
