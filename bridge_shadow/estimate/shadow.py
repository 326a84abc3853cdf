"""The shadow pipeline: messages -> gate -> align/aggregate -> compensate -> Kalman -> outputs.

One ``Shadow`` object is driven by the live node (one message or a small batch per call) and by
offline replay (big chunks) through the same methods, so both give the same posterior:

    shadow = Shadow(config, surrogate)
    shadow.ingest_forces(0, stamp_ns, force_n, frame_id)     # channel 0 = frc_01 (south)
    shadow.ingest_temperature(stamp_ns, temp_c, frame_id)
    for out in shadow.poll():                                 # closed windows, in order
        publish(out.mean_m, out.covariance_m2, out.compensated_n)

Windows are fixed in stamp time (``[k W, (k + 1) W)``). Window ``k`` closes once every topic has
a stamp at or past its end, or the data clock (latest accepted stamp of any topic) is
``topic_timeout_s`` past its end; so results depend on the stamps, never on how messages were
chunked. The first windows are held until the spline and the noise model are warm, then
compensated with that fit and applied in order.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS, FORCE_FRAMES, SUPPORTS, TEMPERATURE_FRAME
from bridge_shadow.estimate.align import window_means
from bridge_shadow.estimate.config import ShadowConfig
from bridge_shadow.estimate.gate import MESSAGE_REASONS, REASONS, TopicGate
from bridge_shadow.estimate.kalman import SettlementFilter
from bridge_shadow.estimate.noise import WindowNoise
from bridge_shadow.estimate.spline import OnlinePSpline
from bridge_shadow.model.surrogate_file import Surrogate, load_surrogate
from bridge_shadow.series import MonitoringData

__all__ = ["NOISE_FULL_DAY_S", "TOPIC_KEYS", "ReplayResult", "Shadow", "WindowOutput"]

#: Residual history the adaptive noise model needs before the diagnostics call its intervals
#: calibrated: one whole day. Before that, a quiet night can give intervals that widen many times
#: once the sun-driven residuals arrive (bags/demo_3d: 0.0013 mm after 7 h, 0.18 mm after a day).
NOISE_FULL_DAY_S = 86_400.0
#: Keys of the three input topics in counters and diagnostics.
TOPIC_KEYS: tuple[str, str, str] = (*CHANNELS, "air_temperature")
_NS = 1_000_000_000


@dataclass
class WindowOutput:
    """What the shadow says after one closed window.

    Attributes:
        index: window number ``k`` (window ``[k W, (k + 1) W)`` in stamp ns).
        end_ns: window end stamp (ns); the stamp of the published outputs.
        samples: (2,) force samples per channel.
        temp_c: (2,) C, mean matched temperature per channel.
        force_n: (2,) N, raw window-mean force.
        compensated_n: (2,) N, ``y - g(T) + mean(y)`` (NaN when not compensated).
        mean_m: (2,) m, posterior settlement mean after this window.
        covariance_m2: (2, 2) m^2, posterior covariance after this window.
        updated: whether this window updated the filter.
        reason: ``""`` or why it did not (a key of ``REASONS``).

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


class _Buffer:
    """Accepted samples of one topic not yet consumed: sorted stamps and values in chunks."""

    def __init__(self) -> None:
        self.stamps: list[np.ndarray] = []
        self.values: list[np.ndarray] = []

    def append(self, stamps: np.ndarray, values: np.ndarray) -> None:
        if len(stamps):
            self.stamps.append(stamps)
            self.values.append(values)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        if len(self.stamps) > 1:
            self.stamps = [np.concatenate(self.stamps)]
            self.values = [np.concatenate(self.values)]
        if not self.stamps:
            return np.empty(0, np.int64), np.empty(0)
        return self.stamps[0], self.values[0]

    def take_before(self, end_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """Remove and return the samples with stamp < end_ns."""
        s, v = self.arrays()
        i = int(np.searchsorted(s, end_ns, side="left"))
        self.stamps, self.values = ([s[i:]], [v[i:]]) if i < len(s) else ([], [])
        return s[:i], v[:i]

    def drop_before(self, index: int) -> None:
        s, v = self.arrays()
        if index > 0:
            self.stamps, self.values = [s[index:]], [v[index:]]

    def first_ns(self) -> int | None:
        return int(self.stamps[0][0]) if self.stamps else None

    def last_ns(self) -> int | None:
        return int(self.stamps[-1][-1]) if self.stamps else None


class _WindowLog:
    """Kept windows for the filter re-run: end stamps, ``z`` (N) and sample counts, as arrays.

    Stored in amortized-doubling arrays, so the Q = 0 re-run is one vectorized batch formula with
    no per-window Python (it runs whenever the noise model moves, often in the first days).
    """

    def __init__(
        self, end: np.ndarray | None = None, z: np.ndarray | None = None, m: np.ndarray | None = None
    ) -> None:
        self._set(np.zeros(0, np.int64) if end is None else end, z, m)

    def _set(self, end: np.ndarray, z: np.ndarray | None, m: np.ndarray | None) -> None:
        n = len(end)
        cap = max(64, 2 * n)
        self._end = np.zeros(cap, np.int64)
        self._z = np.zeros((cap, 2))
        self._m = np.zeros((cap, 2))
        self._n = n
        if n:
            self._end[:n], self._z[:n], self._m[:n] = end, np.reshape(z, (n, 2)), np.reshape(m, (n, 2))

    def __len__(self) -> int:
        return self._n

    def append(self, end: int, z: np.ndarray, m: np.ndarray) -> None:
        if self._n == len(self._end):
            cap = 2 * len(self._end)
            self._end = np.resize(self._end, cap)
            self._z = np.resize(self._z, (cap, 2))
            self._m = np.resize(self._m, (cap, 2))
        self._end[self._n], self._z[self._n], self._m[self._n] = end, z, m
        self._n += 1

    def arrays(self, stop: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return views of the first ``stop`` (default all) entries: end (n,), z (n, 2), m (n, 2)."""
        n = self._n if stop is None else min(stop, self._n)
        return self._end[:n], self._z[:n], self._m[:n]

    def drop_first(self, k: int) -> None:
        """Forget the oldest ``k`` entries."""
        end, z, m = (a[k:].copy() for a in self.arrays())
        self._set(end, z, m)


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
            "windows": {"closed": self.windows, "updates": self.updates},
            "spline": self.spline,
            "noise": self.noise,
        }


class Shadow:
    """The online shadow of the two central-support settlements (no ROS import).

    Attributes:
        config: the parameters (``config/shadow.yaml``).
        surrogate: ``u = A x + u0`` (A N/m, u0 N).
        splines: one ``OnlinePSpline`` per channel (force N on temperature C).
        noise: the window noise model giving R.
        filter: the settlement Kalman filter (x m, P m^2).
        counts: rejections by reason (``REASONS``).
        used: accepted messages per topic (``TOPIC_KEYS``).

    """

    def __init__(self, config: ShadowConfig | None = None, surrogate: Surrogate | None = None) -> None:
        self.config = config = config if config is not None else ShadowConfig()
        if surrogate is None:
            surrogate = load_surrogate(config.surrogate_path or None)
        self.surrogate = surrogate
        self._w_ns = round(config.window_s * _NS)
        jump_ns = round(config.clock_jump_s * _NS)
        check = config.check_frame_id
        self.gates = [
            TopicGate(
                FORCE_FRAMES[ch] if check else None,
                config.force_min_n,
                config.force_max_n,
                jump_ns,
                config.clock_jump_confirm,
            )
            for ch in CHANNELS
        ]
        self.gates.append(
            TopicGate(
                TEMPERATURE_FRAME if check else None,
                config.temp_min_c,
                config.temp_max_c,
                jump_ns,
                config.clock_jump_confirm,
            )
        )
        self.counts: Counter = Counter({r: 0 for r in REASONS})
        self.used = dict.fromkeys(TOPIC_KEYS, 0)
        self._force = [_Buffer(), _Buffer()]
        self._temp = _Buffer()
        self.splines = [
            OnlinePSpline.uniform(
                config.spline_t_min_c,
                config.spline_t_max_c,
                config.spline_segments,
                mode=config.smoothing,
                lam=config.spline_lambda,
            )
            for _ in CHANNELS
        ]
        self.noise = WindowNoise(
            config.noise_sigma_n,
            adaptive=config.noise_mode == "adaptive",
            phi_max=config.noise_phi_max,
            floor=config.noise_floor,
        )
        self.filter = SettlementFilter(
            surrogate.A,
            np.asarray(config.prior_sigma_m),
            np.asarray(config.process_noise_m2_per_s),
            config.mahalanobis_probability,
        )
        sys_sd = np.asarray(config.systematic_sigma_n, float)
        self._systematic: np.ndarray | None = None
        if np.any(sys_sd > 0):
            a_inv = np.linalg.inv(surrogate.A)
            cov = a_inv @ np.diag(sys_sd**2) @ a_inv.T
            self._systematic = 0.5 * (cov + cov.T)
        warm = [config.spline_warmup_windows if config.smoothing != "none" else 0]
        warm.append(config.noise_warmup_windows if config.noise_mode == "adaptive" else 0)
        # a spline needs one window before it can compensate, the noise model two
        warm.append(1 if config.smoothing != "none" else 0)
        warm.append(2 if config.noise_mode == "adaptive" else 0)
        self._warmup = max(warm)
        self.next_k: int | None = None
        self.n_windows = 0  # windows closed with data
        self.n_good = 0  # windows added to the splines
        self._spline_k = -1  # window index of the last spline update (forgetting)
        self._pred_ns: int | None = None  # stamp of the filter's last predict
        self._held: list[dict[str, Any]] = []
        self._ckpt_ns: int | None = None
        self._first_ns: int | None = None  # earliest accepted stamp of any topic
        self._t_ref: np.ndarray | None = None  # frozen reference temperature (warmup_mean), C
        self._outlier_run = 0  # consecutive Mahalanobis outliers
        self._zlog = _WindowLog()  # kept windows: end, z (N), m
        self._r1_ref: np.ndarray | None = None  # per-sample R of the last (re)filter, N^2
        self.n_refilters = 0
        self._base: dict[str, Any] | None = None  # filter state of the folded, oldest windows
        self.gate_resets = 0  # outlier runs accepted as a real change

    # -- input ------------------------------------------------------------------------------
    @property
    def clock_ns(self) -> int | None:
        """Data clock: the latest accepted stamp over all topics (None before any)."""
        stamps = [g.last_ns for g in self.gates if g.last_ns is not None]
        return max(stamps) if stamps else None

    def _clock_span(self) -> tuple[int, int] | None:
        if self._first_ns is None:
            return None
        return (self._first_ns, max(g.last_ns for g in self.gates if g.last_ns is not None))

    def _note_first(self, stamps: np.ndarray) -> None:
        if len(stamps) and (self._first_ns is None or int(stamps[0]) < self._first_ns):
            self._first_ns = int(stamps[0])

    def ingest_forces(
        self,
        channel: int | str,
        stamp_ns: np.ndarray | int,
        force_n: np.ndarray | float,
        frame_id: np.ndarray | str | None = None,
        log_ns: np.ndarray | int | None = None,
    ) -> int:
        """Take force messages of one channel (0/``frc_01`` south, 1/``frc_02`` north) in arrival order.

        ``frame_id`` None skips the frame check for these messages; ``log_ns`` is accepted for
        the node's convenience and not used (windows follow the header stamps). Returns the
        number of messages accepted.
        """
        c = CHANNELS.index(channel) if isinstance(channel, str) else int(channel)
        stamps = np.atleast_1d(np.asarray(stamp_ns, dtype=np.int64))
        values = np.atleast_1d(np.asarray(force_n, dtype=float))
        ok = self.gates[c](stamps, values, frame_id, self._clock_span(), self.counts)
        stamps, values = self.gates[c].with_released(stamps[ok], values[ok])  # + a held one, now taken
        self._note_first(stamps)
        if len(stamps):
            if self.next_k is None:
                self.next_k = int(stamps[0]) // self._w_ns
            late = stamps < self.next_k * self._w_ns
            if late.any():
                self.counts["late"] += int(np.count_nonzero(late))
                stamps, values = stamps[~late], values[~late]
        self._force[c].append(stamps, values)
        self.used[CHANNELS[c]] += len(stamps)
        return len(stamps)

    def ingest_temperature(
        self,
        stamp_ns: np.ndarray | int,
        temp_c: np.ndarray | float,
        frame_id: np.ndarray | str | None = None,
        log_ns: np.ndarray | int | None = None,
    ) -> int:
        """Take air-temperature messages in arrival order; return the number accepted."""
        stamps = np.atleast_1d(np.asarray(stamp_ns, dtype=np.int64))
        values = np.atleast_1d(np.asarray(temp_c, dtype=float))
        ok = self.gates[2](stamps, values, frame_id, self._clock_span(), self.counts)
        stamps, values = self.gates[2].with_released(stamps[ok], values[ok])  # + a held one, now taken
        self._note_first(stamps)
        self._temp.append(stamps, values)
        n = len(stamps)
        self.used["air_temperature"] += n
        return n

    # -- windows ----------------------------------------------------------------------------
    def _temperature_horizon_ns(self) -> int:
        """How long past a window's end its temperature may still arrive (ns).

        A window waits for an accepted reading at or past its end (a rejected NaN there cannot
        bracket the last forces), at most ``max(topic_timeout_s, temperature_stale_s)``: beyond
        that every force of the window would be stale anyway. Closing looks only at readings
        stamped before this horizon, so the result does not depend on how much later data happened
        to be ingested before the poll (chunking).
        """
        cfg = self.config
        return round(max(cfg.topic_timeout_s, cfg.temperature_stale_s) * _NS)

    def _due(self, k: int, clock: int) -> bool:
        """Whether window ``k`` is complete on the data clock (see ``_temperature_horizon_ns``)."""
        end = (k + 1) * self._w_ns
        forces_timeout = clock >= end + round(self.config.topic_timeout_s * _NS)
        forces_past = all(g.last_ns is not None and g.last_ns >= end for g in self.gates[:2])
        temp_last = self._temp.last_ns()
        temp_past = temp_last is not None and temp_last >= end
        temp_timeout = clock >= end + self._temperature_horizon_ns()
        return (forces_past or forces_timeout) and (temp_past or temp_timeout)

    def poll(self, now_ns: int | None = None) -> list[WindowOutput]:
        """Close every due window and return its outputs, in window order.

        ``now_ns`` (optional) extends the data clock for the missing-topic timeout, e.g. a node's
        wall clock when all inputs stop; leave it None to stay on stamp time (replay-exact).
        """
        outputs: list[WindowOutput] = []
        clock = self.clock_ns
        if clock is None or self.next_k is None:
            return outputs
        if now_ns is not None:
            clock = max(clock, int(now_ns))
        while self._due(self.next_k, clock):
            outputs.extend(self._close(self.next_k))
            self.next_k = self._next_window(self.next_k + 1)
        self._maybe_checkpoint()
        return outputs

    @property
    def holds_data(self) -> bool:
        """Whether forces are buffered in windows not yet closed (what ``flush`` would close)."""
        return any(b.first_ns() is not None for b in self._force)

    def flush(self) -> list[WindowOutput]:
        """Close every window that holds data (end of a replay); later data will be ``late``."""
        for c, gate in enumerate(self.gates):  # the end of the data: a message held after a gap is taken
            if gate.release_held():
                none = np.empty(0, np.int64), np.empty(0)
                self.ingest_forces(c, *none) if c < 2 else self.ingest_temperature(*none)
        outputs: list[WindowOutput] = []
        while self.next_k is not None and self.holds_data:
            outputs.extend(self._close(self.next_k))
            self.next_k = self._next_window(self.next_k + 1)
        if self._held:
            outputs.extend(self._release())
        return outputs

    def _next_window(self, k: int) -> int:
        """Skip windows that can never receive data (empty buffers, every channel past them)."""
        firsts = [b.first_ns() for b in self._force]
        if any(f is not None for f in firsts):
            return max(k, min(f for f in firsts if f is not None) // self._w_ns)
        lasts = [g.last_ns for g in self.gates[:2] if g.last_ns is not None]
        return max(k, min(lasts) // self._w_ns) if lasts else k

    def _close(self, k: int) -> list[WindowOutput]:
        end = (k + 1) * self._w_ns
        taken = [b.take_before(end) for b in self._force]
        if not any(len(s) for s, _ in taken):
            self._prune_temperature(end)
            return []
        self.n_windows += 1
        ts, tv = self._temp.arrays()
        horizon = int(np.searchsorted(ts, end + self._temperature_horizon_ns(), side="left"))
        ts, tv = ts[:horizon], tv[:horizon]
        cfg = self.config
        wm = window_means(
            [s for s, _ in taken],
            [v for _, v in taken],
            ts,
            tv,
            cfg.temperature_match,
            round(cfg.temperature_stale_s * _NS),
        )
        self._prune_temperature(end)
        reason = ""
        if np.any(wm.samples == 0):
            reason = "missing_topic"
        elif np.any(wm.samples < cfg.window_min_samples):
            reason = "sparse_window"
        elif wm.stale:
            reason = "stale_temperature"
        if reason:
            self.counts[reason] += 1
            return [self._output(k, wm.samples, wm.temp_c, wm.force_n, np.full(2, np.nan), False, reason)]
        rec = {"k": k, "samples": wm.samples, "temp_c": wm.temp_c, "force_n": wm.force_n}
        if self.n_good < self._warmup:
            self._fit_window(rec)
            self._held.append(rec)
            return self._release() if self.n_good >= self._warmup else []
        return [self._apply_online(rec)]

    def _fit_window(self, rec: dict[str, Any]) -> None:
        """Add a window to the spline sums (with forgetting)."""
        cfg = self.config
        decay = 1.0
        if cfg.spline_forgetting_s > 0 and self._spline_k >= 0:
            decay = float(np.exp(-(rec["k"] - self._spline_k) * cfg.window_s / cfg.spline_forgetting_s))
        for c in range(2):
            self.splines[c].add(rec["temp_c"][c], rec["force_n"][c], 1.0, decay)
        self._spline_k = rec["k"]
        self.n_good += 1

    def _prune_temperature(self, end: int) -> None:
        ts, _ = self._temp.arrays()
        self._temp.drop_before(int(np.searchsorted(ts, end, side="right")) - 1)

    def _curve(self, temp_c: np.ndarray, force_n: np.ndarray) -> np.ndarray:
        """Compensation curve ``g(T)`` per channel (N); with ``none`` the mean so far (compensated = y)."""
        if self.config.smoothing == "none":
            return np.array(
                [sp.fit().mean_y if sp.sw > 0 else f for sp, f in zip(self.splines, force_n, strict=True)]
            )
        return np.array([self.splines[c].predict(temp_c[c])[0] for c in range(2)])

    def _release(self) -> list[WindowOutput]:
        """Compensate the held windows with the warm fit, feed the noise model, then update in order."""
        held, self._held = self._held, []
        resid = [rec["force_n"] - self._curve(rec["temp_c"], rec["force_n"]) for rec in held]
        for rec, e in zip(held, resid, strict=True):
            # leave-one-out residuals: the same out-of-sample scatter the online windows will show
            h = np.array([sp.leverage(rec["temp_c"][c])[0] for c, sp in enumerate(self.splines)])
            self.noise.add(e / np.maximum(1.0 - h, 1e-3), rec["samples"], rec["k"])
        level = self._level()
        outs = [self._update(rec, e + level)[0] for rec, e in zip(held, resid, strict=True)]
        self._r1_ref = self.noise.R(np.ones(2))
        return outs

    def _maybe_refilter(self, out: WindowOutput) -> None:
        """Re-run the filter over all kept windows when the noise model has moved.

        The Kalman weights of early windows were set with the noise estimate of their time; when
        the per-sample-equivalent R has changed by more than ``noise_refilter_tolerance``
        (relative, any variance or the correlation), the filter restarts from the prior and
        replays every kept window with the current R, so the posterior always reflects the
        current noise model (gate decisions are kept as made).
        """
        tol = self.config.noise_refilter_tolerance
        if not self.noise.adaptive or tol <= 0:
            return
        r1 = self.noise.R(np.ones(2))
        ref = self._r1_ref
        if ref is not None:
            d_var = np.abs(np.diag(r1) / np.diag(ref) - 1.0).max()
            corr = lambda r: r[0, 1] / np.sqrt(r[0, 0] * r[1, 1])  # noqa: E731
            if d_var <= tol and abs(corr(r1) - corr(ref)) <= tol:
                return
        self._r1_ref = r1
        self.n_refilters += 1
        filt, last = self._replay_log(self._zlog.arrays(), r1)
        if last is not None and self._pred_ns is not None and self._pred_ns > last:
            filt.predict((self._pred_ns - last) / _NS)
        self.filter = filt
        out.mean_m, out.covariance_m2 = filt.x, self._published_cov(filt.P)

    def _replay_log(
        self, log: tuple[np.ndarray, np.ndarray, np.ndarray], r1: np.ndarray
    ) -> tuple[SettlementFilter, int | None]:
        """Filter ``log`` (end, z, m) from the folded base state (or prior), ``R(m) = R(1) / sqrt(m m')``."""
        cfg = self.config
        filt = SettlementFilter(
            self.surrogate.A,
            np.asarray(cfg.prior_sigma_m),
            np.asarray(cfg.process_noise_m2_per_s),
            cfg.mahalanobis_probability,
        )
        last = None
        if self._base is not None:
            filt.load_state_dict(self._base)
            last = int(self._base["end"])
        ends, z, m = log
        if len(ends) and not np.any(filt.q_rate > 0):
            # Q = 0: the sequential updates equal the information-form batch (DESIGN 2), in one shot
            sm = np.sqrt(m)
            r1_inv = np.linalg.inv(r1)
            w = (
                r1_inv[None, :, :] * sm[:, :, None] * sm[:, None, :]
            )  # R_w^-1 = diag(sqrt m) R1^-1 diag(sqrt m)
            a = self.surrogate.A
            p_inv = np.linalg.inv(filt.P) + a.T @ w.sum(axis=0) @ a
            info = np.linalg.solve(filt.P, filt.x) + a.T @ np.einsum("wij,wj->i", w, z)
            cov = np.linalg.inv(p_inv)
            filt.load_state_dict(
                {"x": cov @ info, "P": 0.5 * (cov + cov.T), "n_updates": filt.n_updates + len(ends)}
            )
            return filt, int(ends[-1])
        for end, zi, mi in zip(ends.tolist(), z, m, strict=True):
            if last is not None:
                filt.predict((end - last) / _NS)
            last = end
            filt.update(zi, r1 / np.sqrt(np.outer(mi, mi)), gate=False)
        return filt, last

    def _fold_log(self) -> None:
        """Keep memory flat: fold the older half of the kept-window log into the base state."""
        cap = self.config.noise_refilter_max_windows
        if len(self._zlog) <= cap:
            return
        half = len(self._zlog) // 2
        r1 = self._r1_ref if self._r1_ref is not None else self.noise.R(np.ones(2))
        filt, last = self._replay_log(self._zlog.arrays(half), r1)
        self._base = {**filt.state_dict(), "end": last}
        self._zlog.drop_first(half)

    def _apply_online(self, rec: dict[str, Any]) -> WindowOutput:
        """Compensate with the fit so far, gate and update; a kept window then joins the fit.

        A Mahalanobis outlier stays out of the spline and the noise model, so one wild window
        (a glitch, a heavy vehicle) cannot bend the compensation. After ``gate_max_consecutive``
        outliers in a row the change is taken as real and the window is used anyway (no lock-out).
        """
        resid = rec["force_n"] - self._curve(rec["temp_c"], rec["force_n"])
        force = self._outlier_run >= self.config.gate_max_consecutive
        level = self._level() if self.n_good else rec["force_n"]  # no fit yet: compensated = y
        # innovation of the compensated window against the prediction A x + u0 (x before update):
        # settlement changes the filter tracks (Q > 0) do not count as noise
        innovation = resid + level - self.surrogate.u0 - self.surrogate.A @ self.filter.x
        out, accepted = self._update(rec, resid + level, gate=not force)
        if accepted:
            self._outlier_run = 0
            self.gate_resets += int(force)
            self.noise.add(innovation, rec["samples"], rec["k"])
            self._fit_window(rec)
            self._maybe_refilter(out)
        else:
            self._outlier_run += 1
        return out

    def _update(
        self, rec: dict[str, Any], compensated: np.ndarray, gate: bool = True
    ) -> tuple[WindowOutput, bool]:
        """Kalman predict and update with one compensated window (R from the noise model)."""
        k, m = rec["k"], rec["samples"]
        end = (k + 1) * self._w_ns
        R = self.noise.R(m)
        if self._pred_ns is not None:
            self.filter.predict((end - self._pred_ns) / _NS)
        self._pred_ns = end
        gate = gate and self.filter.n_updates >= self.config.gate_after_updates
        res = self.filter.update(compensated - self.surrogate.u0, R, gate=gate)
        if not res.accepted:
            self.counts[res.reason] += 1
        else:
            self._zlog.append(end, compensated - self.surrogate.u0, np.asarray(m, float))
            self._fold_log()
        out = self._output(k, m, rec["temp_c"], rec["force_n"], compensated, res.accepted, res.reason)
        return out, res.accepted

    def _level(self) -> np.ndarray:
        """Level added back by compensation (N), per ``compensation_level``."""
        mode = self.config.compensation_level
        if self.config.smoothing == "none" or mode == "mean":
            return np.array([sp.fit().mean_y for sp in self.splines])
        if mode == "reference":
            t_ref = np.full(2, self.config.reference_temperature_c)
        else:
            if self._t_ref is None:
                self._t_ref = np.array([sp.mean_t for sp in self.splines])
            t_ref = self._t_ref
        return np.array([sp.predict(t_ref[c])[0] for c, sp in enumerate(self.splines)])

    def _output(
        self,
        k: int,
        m: np.ndarray,
        temp: np.ndarray,
        force: np.ndarray,
        comp: np.ndarray,
        updated: bool,
        reason: str,
    ) -> WindowOutput:
        return WindowOutput(
            k,
            (k + 1) * self._w_ns,
            np.asarray(m).copy(),
            np.asarray(temp).copy(),
            np.asarray(force).copy(),
            np.asarray(comp).copy(),
            self.filter.x,
            self._published_cov(self.filter.P),
            updated,
            reason,
        )

    # -- reporting ----------------------------------------------------------------------------
    @property
    def posterior(self) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean (2,) m and covariance (2, 2) m^2 (the filter's plus the systematic term)."""
        return self.filter.x, self._published_cov(self.filter.P)

    def _published_cov(self, P: np.ndarray) -> np.ndarray:
        """Return the filter covariance plus ``A^-1 diag(systematic_sigma_n^2) A^-T`` (0 by default)."""
        return P + self._systematic if self._systematic is not None else P

    @property
    def rejected(self) -> dict[str, int]:
        """Rejections by reason (every reason listed, zeros included)."""
        return {r: int(self.counts.get(r, 0)) for r in REASONS}

    def spline_info(self) -> dict[str, dict[str, float]]:
        """Per channel: edf, lambda, windows fitted, clamped temperatures (NaN before data)."""
        info: dict[str, dict[str, float]] = {}
        for ch, sp in zip(CHANNELS, self.splines, strict=True):
            edf = lam = level = float("nan")
            if sp.sw > 0:
                fit = sp.fit()
                edf, lam, level = fit.edf, fit.lam, fit.mean_y
            info[ch] = {
                "edf": edf,
                "lambda": lam,
                "mean_force_n": level,
                "windows": sp.n_obs,
                "clamped": sp.n_clamped,
            }
        return info

    def diagnostics(self, now_ns: int | None = None) -> dict[str, Any]:
        """Health and key values (SI): level OK/WARN/ERROR, message, posterior, counts, staleness."""
        mean, cov = self.posterior
        clock = self.clock_ns
        ref = now_ns if now_ns is not None else clock
        staleness = {
            key: (None if g.last_ns is None or ref is None else (ref - g.last_ns) / _NS)
            for key, g in zip(TOPIC_KEYS, self.gates, strict=True)
        }
        timeout = max(self.config.topic_timeout_s, self.config.window_s)
        stale = [k for k, v in staleness.items() if v is None or v > timeout]
        warm = self.n_good >= self._warmup
        if not np.all(np.isfinite(mean)) or not np.all(np.isfinite(cov)):
            level, message = "ERROR", "posterior is not finite"
        elif clock is not None and len(stale) == len(TOPIC_KEYS):
            level, message = "ERROR", "no input on any topic"
        elif stale:
            level, message = "WARN", f"stale or missing topic(s): {', '.join(stale)}"
        elif not warm:
            level, message = "WARN", f"warming up ({self.n_good}/{self._warmup} windows)"
        elif self.noise.adaptive and (seen_s := self.noise.n * self.config.window_s) < NOISE_FULL_DAY_S:
            level, message = (
                "WARN",
                f"noise model has seen {seen_s / 3600.0:.1f} h (< 24 h): intervals may be optimistic "
                "until a whole day of sun and traffic is in the residuals",
            )
        else:
            level, message = "OK", "tracking"
        sigma = np.sqrt(np.diag(cov))
        summary = ", ".join(
            f"{s} {1e3 * mu:+.3f} ± {1e3 * sd:.3f} mm"
            for s, mu, sd in zip(SUPPORTS, mean, sigma, strict=True)
        )
        return {
            "level": level,
            "message": message,
            "summary": summary,
            "mean_m": mean.tolist(),
            "covariance_m2": cov.tolist(),
            "sigma_m": sigma.tolist(),
            "used": dict(self.used),
            "rejected": self.rejected,
            "staleness_s": staleness,
            "spline": self.spline_info(),
            "noise": self.noise_info(),
            "gate_resets": self.gate_resets,
            "refilters": self.n_refilters,
            "windows": {
                "closed": self.n_windows,
                "fitted": self.n_good,
                "held": len(self._held),
                "updates": self.filter.n_updates,
                "warm": warm,
            },
            "clock_ns": clock,
        }

    def noise_info(self) -> dict[str, Any]:
        """Noise model: mode, phi per channel, per-sample-equivalent sigma (N)."""
        return {
            "mode": self.config.noise_mode,
            "phi": self.noise.phi.tolist(),
            "sigma_n": np.sqrt(np.diag(self.noise.sample_cov())).tolist(),
            "windows": self.noise.n,
        }

    # -- state ----------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """Return the whole online state as nested plain data (arrays, numbers, strings)."""
        force = [b.arrays() for b in self._force]
        temp = self._temp.arrays()
        held = self._held
        return {
            "version": 1,
            "config": json.dumps(self.config.to_params()),
            "surrogate": {"A": self.surrogate.A, "u0": self.surrogate.u0},
            "gates": [g.state_dict() for g in self.gates],
            "counts": json.dumps({k: int(v) for k, v in self.counts.items()}),
            "used": json.dumps(self.used),
            "force": [{"stamps": s, "values": v} for s, v in force],
            "temp": {"stamps": temp[0], "values": temp[1]},
            "splines": [sp.state_dict() for sp in self.splines],
            "noise": self.noise.state_dict(),
            "filter": self.filter.state_dict(),
            "zlog": dict(zip(("end", "z", "m"), (a.copy() for a in self._zlog.arrays()), strict=True)),
            "r1_ref": np.full((2, 2), np.nan) if self._r1_ref is None else self._r1_ref,
            "base": {
                "has": self._base is not None,
                **(self._base or {"x": np.zeros(2), "P": np.eye(2), "n_updates": 0, "end": 0}),
            },
            "held": {
                "k": np.array([h["k"] for h in held], dtype=np.int64),
                "samples": np.array([h["samples"] for h in held], dtype=np.int64).reshape(-1, 2),
                "temp_c": np.array([h["temp_c"] for h in held], dtype=float).reshape(-1, 2),
                "force_n": np.array([h["force_n"] for h in held], dtype=float).reshape(-1, 2),
            },
            "t_ref": np.full(2, np.nan) if self._t_ref is None else self._t_ref,
            "scalars": {
                "next_k": -(2**62) if self.next_k is None else self.next_k,
                "n_windows": self.n_windows,
                "n_good": self.n_good,
                "spline_k": self._spline_k,
                "pred_ns": -(2**62) if self._pred_ns is None else self._pred_ns,
                "ckpt_ns": -(2**62) if self._ckpt_ns is None else self._ckpt_ns,
                "first_ns": -(2**62) if self._first_ns is None else self._first_ns,
                "outlier_run": self._outlier_run,
                "gate_resets": self.gate_resets,
                "n_refilters": self.n_refilters,
            },
        }

    @classmethod
    def from_state_dict(
        cls, state: dict[str, Any], config: ShadowConfig | None = None, surrogate: Surrogate | None = None
    ) -> Shadow:
        """Rebuild a shadow from ``state_dict`` (config and surrogate default to the saved ones)."""
        if config is None:
            config = ShadowConfig.from_params(json.loads(str(state["config"])))
        if surrogate is None:
            surrogate = Surrogate(np.asarray(state["surrogate"]["A"]), np.asarray(state["surrogate"]["u0"]))
        shadow = cls(config, surrogate)
        for g, s in zip(shadow.gates, state["gates"], strict=True):
            g.load_state_dict(s)
        shadow.counts = Counter({r: 0 for r in REASONS})
        shadow.counts.update(json.loads(str(state["counts"])))
        shadow.used = {k: int(v) for k, v in json.loads(str(state["used"])).items()}
        for b, s in zip(shadow._force, state["force"], strict=True):
            b.append(np.asarray(s["stamps"], np.int64), np.asarray(s["values"], float))
        shadow._temp.append(
            np.asarray(state["temp"]["stamps"], np.int64), np.asarray(state["temp"]["values"], float)
        )
        for sp, s in zip(shadow.splines, state["splines"], strict=True):
            sp.load_state_dict(s)
        shadow.noise.load_state_dict(state["noise"])
        shadow.filter.load_state_dict(state["filter"])
        zl = state["zlog"]
        shadow._zlog = _WindowLog(
            np.asarray(zl["end"], np.int64), np.asarray(zl["z"], float), np.asarray(zl["m"], float)
        )
        base = state["base"]
        shadow._base = (
            {
                "x": np.asarray(base["x"], float),
                "P": np.asarray(base["P"], float),
                "n_updates": int(base["n_updates"]),
                "end": int(base["end"]),
            }
            if bool(base["has"])
            else None
        )
        r1 = np.asarray(state["r1_ref"], float)
        shadow._r1_ref = None if np.isnan(r1).any() else r1
        h = state["held"]
        shadow._held = [
            {
                "k": int(k),
                "samples": np.asarray(m, np.int64),
                "temp_c": np.asarray(t, float),
                "force_n": np.asarray(f, float),
            }
            for k, m, t, f in zip(
                np.asarray(h["k"]),
                np.asarray(h["samples"]).reshape(-1, 2),
                np.asarray(h["temp_c"]).reshape(-1, 2),
                np.asarray(h["force_n"]).reshape(-1, 2),
                strict=True,
            )
        ]
        t_ref = np.asarray(state["t_ref"], float)
        shadow._t_ref = None if np.isnan(t_ref).any() else t_ref
        sc = {k: int(v) for k, v in state["scalars"].items()}
        none = -(2**62)
        shadow.next_k = None if sc["next_k"] == none else sc["next_k"]
        shadow.n_windows, shadow.n_good, shadow._spline_k = sc["n_windows"], sc["n_good"], sc["spline_k"]
        shadow._pred_ns = None if sc["pred_ns"] == none else sc["pred_ns"]
        shadow._ckpt_ns = None if sc["ckpt_ns"] == none else sc["ckpt_ns"]
        shadow._first_ns = None if sc["first_ns"] == none else sc["first_ns"]
        shadow._outlier_run, shadow.gate_resets = sc["outlier_run"], sc["gate_resets"]
        shadow.n_refilters = sc["n_refilters"]
        return shadow

    def save_checkpoint(self, path: str | Path | None = None) -> Path | None:
        """Write the state atomically to ``path`` (default ``checkpoint_path``); None if disabled."""
        from bridge_shadow.estimate.checkpoint import save_state

        target = path if path is not None else self.config.checkpoint_path
        if not target:
            return None
        self._ckpt_ns = self.clock_ns
        return save_state(self.state_dict(), target)

    @classmethod
    def resume(
        cls, path: str | Path, config: ShadowConfig | None = None, surrogate: Surrogate | None = None
    ) -> Shadow:
        """Rebuild a shadow from a checkpoint file written by ``save_checkpoint``."""
        from bridge_shadow.estimate.checkpoint import restore  # refuses unusable/incompatible files

        return restore(path, config, surrogate, cls.from_state_dict)

    def _maybe_checkpoint(self) -> None:
        if not self.config.checkpoint_path or self.clock_ns is None:
            return
        if self._ckpt_ns is None:
            self._ckpt_ns = self.clock_ns
        elif self.clock_ns - self._ckpt_ns >= self.config.checkpoint_period_s * _NS:
            self.save_checkpoint()

    # -- offline ----------------------------------------------------------------------------
    def run(
        self,
        data: MonitoringData,
        chunk: int = 200_000,
        progress: Callable[[float], None] | None = None,
        flush: bool = True,
    ) -> ReplayResult:
        """Feed ``data`` in arrival (log time) order, ``chunk`` messages per call; return the result."""
        t0 = time.perf_counter()
        series = [data.forces[ch] for ch in CHANNELS]
        temp = data.temperature
        logs = [s.log_ns for s in series] + [temp.log_ns]
        sizes = [len(x) for x in logs]
        total = sum(sizes)
        topic = np.concatenate([np.full(n, i, dtype=np.int8) for i, n in enumerate(sizes)])
        pos = np.concatenate([np.arange(n) for n in sizes])
        order = np.argsort(np.concatenate(logs), kind="stable")
        topic, pos = topic[order], pos[order]
        outputs: list[WindowOutput] = []
        chunk = max(int(chunk), 1)
        for start in range(0, total, chunk):
            t_chunk, p_chunk = topic[start : start + chunk], pos[start : start + chunk]
            for i in range(3):
                sel = p_chunk[t_chunk == i]
                if not len(sel):
                    continue
                # positions of one topic are increasing, so a contiguous range is a slice
                sl = slice(int(sel[0]), int(sel[-1]) + 1) if sel[-1] - sel[0] + 1 == len(sel) else sel
                if i < 2:
                    s = series[i]
                    self.ingest_forces(i, s.stamp_ns[sl], s.force_n[sl], s.frame_id[sl])
                else:
                    self.ingest_temperature(temp.stamp_ns[sl], temp.temp_c[sl], temp.frame_id[sl])
            outputs.extend(self.poll())
            if progress is not None:
                progress(min(start + chunk, total) / max(total, 1))
        if flush:
            outputs.extend(self.flush())
            if self.config.checkpoint_path:
                self.save_checkpoint()
        mean, cov = self.posterior
        return ReplayResult(
            mean_m=mean,
            covariance_m2=cov,
            messages=total,
            used=dict(self.used),
            rejected=self.rejected,
            windows=self.n_windows,
            updates=self.filter.n_updates,
            spline=self.spline_info(),
            noise=self.noise_info(),
            outputs=outputs,
            seconds=time.perf_counter() - t0,
        )
