"""The shadow pipeline: messages -> gate -> windows -> event detector -> compensation + settlement.

One ``Shadow`` object is driven by the live node (one message or a small batch per call) and by
offline replay (big chunks) through the same methods, so both give the same posterior:

    shadow = Shadow(config, surrogate)
    shadow.ingest_forces(0, stamp_ns, force_n, frame_id)     # channel 0 = frc_01 (south)
    shadow.ingest_temperature(stamp_ns, temp_c, frame_id)
    for out in shadow.poll():                                 # closed windows, in order
        publish(out.mean_m, out.covariance_m2, out.compensated_n)

It composes small parts, one idea each, from the subpackages of ``estimate``:

- ``inputs``: ``gate.TopicGate`` per topic (drop and count bad messages), ``ledger.TopicLedger``
  (say which topic lost what), and ``windows.WindowBuffer``: buffered samples -> closed 60 s
  windows, many at once (``closed_window.Window`` on its way to an output);
- ``events``: ``detector.ChangeDetector``, a GLR test for a settlement step on each window's
  innovation; it holds suspicious windows until it knows whether they are a passing load, an
  outlier or an event;
- ``compensation``: ``sums.FitSums``, the sufficient statistics of every accepted window;
  ``fit.Compensation``, the temperature curve fitted jointly with the segment levels (it cannot
  absorb a step), refitted every ``refit_windows`` windows, ``lambda`` reselected on a geometric
  schedule; ``noise.NoiseModel``, R from the residuals of that fit (AR(1), long-run variance);
- ``settlement``: ``segments.SegmentChain``, the settlement posterior over segments of constant
  settlement, with the paper's prior (``prior.prior_sigma``); an event opens the covariance by the
  prior's, and with a random walk (``process_noise_m2_per_s`` > 0) a new segment starts every
  ``drift_block_s`` with the covariance opened by ``Q`` times its duration (a piecewise-constant
  random walk);
- ``state``: the whole online state as plain data (``persistence``) and checkpoint files
  (``checkpoint``); ``parameters``: ``config.ShadowConfig`` and the table of specs.

Windows are fixed in stamp time, so results depend on the stamps, never on how messages were
chunked. The first ``warmup_windows`` are held until the curve and the noise model have data,
then applied in order. ``flush`` (end of a record) refits with a fresh ``lambda``: without events,
the posterior then equals the paper's batch method on the whole record
(``estimate.settlement.batch``).
"""

from __future__ import annotations

import math
import time
from collections import Counter, deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS, FORCE_FRAMES
from bridge_shadow.estimate import report
from bridge_shadow.estimate.compensation.fit import Compensation, CompensationFit
from bridge_shadow.estimate.compensation.noise import NoiseModel
from bridge_shadow.estimate.compensation.sums import FitSums, WindowRows, residual_moments
from bridge_shadow.estimate.compensation.sunlight import SunCovariate
from bridge_shadow.estimate.events.detector import ChangeDetector, Decision
from bridge_shadow.estimate.events.warmup import (
    MIN_DIFFERENCES,
    RAMP_HOLD_FACTOR,
    beyond_any_vehicle,
    jump_goes_on,
    level_beyond_vehicle_at_last,
    level_unsettled_at_last,
    lone_windows_beyond_vehicle,
    moved_not_still,
    moved_then_still,
    moving_on_known_noise,
    new_state_at_last,
    ramp_beyond_vehicle_at_last,
    ramp_in_progress,
    ramp_windows,
    step_windows,
)
from bridge_shadow.estimate.inputs.closed_window import Window
from bridge_shadow.estimate.inputs.gate import FROZEN_S, REASONS, TopicGate
from bridge_shadow.estimate.inputs.ledger import TOPIC_KEYS, TopicLedger
from bridge_shadow.estimate.inputs.silence import ChannelSilence
from bridge_shadow.estimate.inputs.windows import WindowBatch, WindowBuffer, stale_variance
from bridge_shadow.estimate.parameters.config import ShadowConfig
from bridge_shadow.estimate.report import NOISE_FULL_DAY_S
from bridge_shadow.estimate.result import ChangeRecord, EventRecord, ReplayResult, WindowOutput
from bridge_shadow.estimate.settlement.prior import configured_prior_sigma, prior_sigma
from bridge_shadow.estimate.settlement.relaxation import relaxation_variance
from bridge_shadow.estimate.settlement.segments import SegmentChain
from bridge_shadow.estimate.small import Sym, Vec, congruence, quad_inv
from bridge_shadow.estimate.state.checkpoint import CheckpointError, restore, save_state
from bridge_shadow.estimate.state.persistence import restore_shadow, shadow_state
from bridge_shadow.model.surrogate_file import ModelCovariance, Surrogate, load_surrogate
from bridge_shadow.series import MonitoringData, TemperatureSeries

#: An air temperature that moves between windows by more than ``AIR_JUMP_K`` plus
#: ``AIR_RATE_K_PER_H`` per hour between them is no air (``Shadow._follow_air``): the largest
#: hourly changes of air temperature at a station are of the order of 10 K (a cold front's passage),
#: and 5 K covers a sensor's and the temperature match's scatter over a window. The real day of
#: 2022-04-11 warmed 12 K in 9 h; readings in °F of a day at 5-15 C read 36 K warmer.
AIR_JUMP_K, AIR_RATE_K_PER_H = 5.0, 10.0

__all__ = ["NOISE_FULL_DAY_S", "TOPIC_KEYS", "ReplayResult", "Shadow", "WindowOutput"]

_NS = 1_000_000_000
#: Windows whose curve values are computed together after a refit (the next refit is at least
#: ``refit_windows`` accepted windows away).
_CURVE_BLOCK = 64
#: The slope and sun priors are weighed as data against the noise model's variance, and the noise
#: is re-estimated from that fit's residuals: a refit whose noise moved by more than this factor
#: (either way) fits again with it, so that the priors are weighed on the noise the estimate is read
#: with (a prior's weight off by 2 moves the sd of what only it decides by at most sqrt(2)).
_NOISE_CONSISTENT = 2.0
#: Fits at most while the noise settles, in a refit and after each merge (the first and three more).
_NOISE_PASSES = 4
#: Segment kinds that begin with a change of the supports (the reactions may relax after it).
_CHANGES = frozenset({"event", "gap", "held_run", "warmup"})
#: A refit comes early when a window's temperature lies this far outside the fitted range (K).
_RANGE_MARGIN_K = 0.5
#: Rejected windows (time and reason) kept for ``/diagnostics``; replay lists every one.
RECENT_REJECTED = 50


def _sun_var(w: Window) -> float:
    """Return the variance of window ``w``'s sun covariate (0 without temperature: no curve, no sun term)."""
    return w.svar if w.i0[0] >= 0 else 0.0


def _rows_of(rows: list[tuple[Any, ...]]) -> WindowRows:
    """Return the sums' rows (``Shadow._row`` each, at least one) as arrays."""
    k, m, y, t, i0, bv, seg, sv = zip(*rows, strict=True)
    return WindowRows(
        np.asarray(k, np.int64),
        np.asarray(m, float),
        np.asarray(y, float),
        np.asarray(t, float),
        np.asarray(i0, np.int64),
        np.asarray(bv, float),
        np.asarray(seg, np.int64),
        np.asarray(sv, float),
    )


class Shadow:
    """The online shadow of the two central-support settlements (no ROS import).

    Attributes:
        config: the parameters (``config/shadow.yaml``).
        surrogate: ``u = A x + u0`` (A N/m, u0 N), thermal sensitivities, model uncertainty.
        prior_sigma_m: (2,) m, the prior standard deviation in use (paper's rule by default).
        gates, ledgers: per input topic, the message gate and its bookkeeping.
        counts: rejections by reason (``REASONS``); used: accepted messages per topic.
        buffer: the window buffer; sums: the sufficient statistics; fit: the current curve.
        compensation, noise, detector: the parts (see the module docstring).
        filter: the settlement estimator (``SegmentChain``).
        events: detected events (window, detected_window, glr, step_n).
        n_windows: windows closed with data; uncompensated: windows used without temperature;
            stale_temperature: windows used with a stale one (``inputs.windows.stale_variance``).

    """

    def __init__(self, config: ShadowConfig | None = None, surrogate: Surrogate | None = None) -> None:
        self.config = config = config if config is not None else ShadowConfig()
        if surrogate is None:
            surrogate = load_surrogate(config.surrogate_path or None)
        self.surrogate = surrogate
        self.A, self.u0 = surrogate.A, surrogate.u0
        self._w_ns = round(config.window_s * _NS)
        self.prior_sigma_m = configured_prior_sigma(config.prior_sigma_m, config.prior_rule, self.A, self.u0)
        self.prior_source = (
            "prior_sigma_m" if max(config.prior_sigma_m) > 0 else f"paper's rule ({config.prior_rule})"
        )
        jump_ns = round(config.clock_jump_s * _NS)
        check = config.check_frame_id
        frames = [FORCE_FRAMES[ch] for ch in CHANNELS] + [config.temperature_frame_id]
        ranges = [(config.force_min_n, config.force_max_n, "N")] * 2 + [
            (config.temp_min_c, config.temp_max_c, "C")
        ]
        frozen = [round(FROZEN_S * _NS)] * 2 + [None]  # the air's readings repeat as a matter of course
        self.gates = [
            TopicGate(frame if check and frame else None, lo, hi, jump_ns, config.clock_jump_confirm, fz)
            for frame, (lo, hi, _), fz in zip(frames, ranges, frozen, strict=True)
        ]
        self.ledgers = [
            TopicLedger(key, gate.frame_id, rng)
            for key, gate, rng in zip(TOPIC_KEYS, self.gates, ranges, strict=True)
        ]
        self.counts: Counter = Counter(dict.fromkeys(REASONS, 0))
        self.used = dict.fromkeys(TOPIC_KEYS, 0)
        self.buffer = WindowBuffer(
            config.window_s,
            config.topic_timeout_s,
            config.temperature_stale_s,
            config.temperature_match,
            config.window_min_samples,
            config.gap_s,
            config.traffic_hold_s,
            config.traffic_threshold_n,
            config.traffic_margin_s,
            config.traffic_vehicle_max_n,
        )
        # the FE response to a vertical temperature difference (Compensation refuses a missing one)
        vertical = surrogate.thermal.get("vertical_gradient", np.zeros(2))
        self.compensation = Compensation(
            config.spline_t_min_c,
            config.spline_t_max_c,
            config.spline_segments,
            mode=config.smoothing,
            lam=config.spline_lambda,
            slope_fe=surrogate.thermal.get("uniform", np.zeros(2)),
            slope_sd=config.thermal_prior_sd_n_per_k,
            sun_slope=vertical if config.sun_gradient else None,
            sun_prior_k=(config.sun_gradient_prior_mean_k, config.sun_gradient_prior_sd_k),
            sun_min_bf=config.sun_gradient_min_bayes_factor,
            sun_fit=config.sun_gradient_fit,
        )
        self.sums = FitSums(self.compensation.q, self.compensation.width)
        self.sun = SunCovariate() if config.sun_gradient else None
        self.noise = NoiseModel(
            config.noise_sigma_n, config.noise_mode == "adaptive", config.noise_phi_max, config.noise_floor
        )
        prior_cov = np.diag(self.prior_sigma_m**2)
        q_rate = np.asarray(config.process_noise_m2_per_s, float)
        self.drifting = bool(np.any(q_rate > 0))
        self._block_k = max(1, round(config.drift_block_s / config.window_s))  # windows per block
        self._block_jump = np.diag(q_rate * self._block_k * config.window_s)  # Q dt of one block, m^2
        jump_sd = (
            self.prior_sigma_m
            if config.event_jump_rule == "prior"
            else prior_sigma(self.A, self.u0, config.event_jump_rule)
        )
        self.jump_sigma_m = jump_sd
        self.filter = SegmentChain(self.A, prior_cov, np.diag(jump_sd**2), config.traffic_vehicle_max_n)
        self.detector = ChangeDetector(
            config.event_trigger_probability,
            config.event_probability,
            config.mahalanobis_probability,
            config.event_confirm_windows,
            config.event_max_pending,
            window_s=config.window_s,
            relaxation_phi0=config.relaxation_phi0,
            relaxation_horizon_s=config.relaxation_horizon_s,
            vehicle_max_n=config.traffic_vehicle_max_n,
        )
        self.fit: CompensationFit | None = None
        self._fit_id = 0
        self._range = ((-np.inf, -np.inf), (np.inf, np.inf))
        self.lam = np.full(2, np.nan)
        self._af = (float(self.A[0, 0]), float(self.A[0, 1]), float(self.A[1, 0]), float(self.A[1, 1]))
        self._u0f = (float(self.u0[0]), float(self.u0[1]))
        sys_sd = np.asarray(config.systematic_sigma_n, float)
        a_inv = np.linalg.inv(self.A)
        self._systematic = a_inv @ np.diag(sys_sd**2) @ a_inv.T
        self._model_cov = ModelCovariance(surrogate) if surrogate.model_cov is not None else None
        self.events: list[dict[str, Any]] = []
        self.unconfirmed_runs: list[dict[str, Any]] = []  # runs at event_max_pending, used as data
        self.excursions: list[dict[str, Any]] = []  # runs no vehicle makes that came back: rejected
        self.recent_rejected: deque[tuple[int, str]] = deque(maxlen=RECENT_REJECTED)  # (window, reason)
        #: every rejected window, as runs ``[first, last, reason]`` of consecutive windows of one
        #: reason (the replay JSON's ``rejected_windows``, whatever outputs a caller keeps)
        self.rejected_runs: list[list[Any]] = []
        self.confirmed_at: dict[int, int] = {}  # provisional segment start -> window that confirmed it
        #: {"from_k", "to_k", "segment"} (ints) and "sun_covariate" [before, after]: gaps in usable windows
        self.gaps: list[dict[str, Any]] = []
        self._gap_k = max(1, round(config.gap_s / config.window_s))  # missing windows that make a gap
        self._last_usable_k: int | None = None
        #: the sun covariate of that window (None: no sun term, or its air temperature unknown)
        self._last_usable_sun: float | None = None
        self._last_data_k: int | None = None  # the last window with force data (usable or not)
        self._outage_since_usable = False  # a window without any force data since the last usable one
        self.n_windows = 0
        self.uncompensated = 0
        self.stale_temperature = 0  # windows used with a stale air temperature (widened, see windows)
        #: the air between consecutive windows with a temperature: the last one ``[k, C]`` and the
        #: jumps no air makes (``AIR_JUMP_K`` + ``AIR_RATE_K_PER_H`` per hour between them): their
        #: count and the largest against its bound ``[k_from, k_to, C_from, C_to]``
        self.air: dict[str, Any] = {"last": None, "jumps": 0, "worst": None, "excess": 0.0}
        # windows the traffic screen cut samples from: [k, cut south, cut north, kept south, kept north]
        self.traffic_windows: list[list[int]] = []
        # records that ended with vehicles parked on the bridge (``WindowBatch.parked``), cut from
        # their arrival on: [cut from (ns), the record's end (ns), load S, load N (N)]
        self.parked: list[list[float]] = []
        self.silence = ChannelSilence()  # stretches of windows one force channel missed alone
        self.warm = False
        self._queue: deque[Window] = deque()
        self._warm: list[Window] = []
        #: the windows since the data began while the noise model is young (``_young_step``)
        self._young: list[Window] = []
        self._young_done = False
        #: the first windows after a gap, held until ``warmup_windows`` of them (or the next gap, or
        #: the end of the data) so that a step among them is searched for like the warm-up's
        self._fresh: list[Window] = []
        self._fresh_open = False
        self._rows: list[tuple[Any, ...]] = []
        #: the last windows used as data (``report.latest_level``: the state they read on their own)
        self._latest: deque[Window] = deque(maxlen=config.event_confirm_windows)
        self._n_accepted = 0
        self._refit_at = 0
        self._pending_refit: bool | None = None  # a scheduled refit not yet run: reselect lambda?
        self._lambda_at = 0
        self._ckpt_ns: int | None = None
        #: no periodic checkpoint write while True (``replay_bag`` feeding the air past a bag's last
        #: force after its checkpoint was written without it)
        self.checkpoints_paused = False
        #: air messages not yet fed, kept in the checkpoint: the air past the last force of the bag
        #: whose replay wrote it (``replay.air_tail``); the next bag's replay merges them in
        self.held_air: TemperatureSeries | None = None
        #: the bags replays with a checkpoint took whole, by signature (``replay.taken``): known
        #: again when one is replayed after the checkpoint its own run wrote
        self.taken_bags: list[dict[str, Any]] = []
        #: the last periodic checkpoint write that failed (data clock ns, why); None after a success
        self.checkpoint_failure: tuple[int, str] | None = None
        self._first_ns: int | None = None
        self._last_judged = -1
        self._last_ok: Window | None = None  # the last window used (the jump test's reference)
        #: the change that began the current state: (its first window, A dx south, north in N)
        self._relax: tuple[int, float, float] | None = None

    # -- input ------------------------------------------------------------------------------
    @property
    def clock_ns(self) -> int | None:
        """Data clock: the latest accepted stamp over all topics (None before any)."""
        stamps = [g.last_ns for g in self.gates if g.last_ns is not None]
        return max(stamps) if stamps else None

    @property
    def next_k(self) -> int | None:
        """The first window not closed yet (None before the first force sample)."""
        return self.buffer.next_k

    @property
    def holds_data(self) -> bool:
        """Whether forces are buffered in windows not yet closed (what ``flush`` would close)."""
        return self.buffer.holds_data

    @property
    def n_updates(self) -> int:
        """Windows that joined the estimate."""
        return self.filter.n_updates

    def _clock_span(self) -> tuple[int, int] | None:
        if self._first_ns is None:
            return None
        return (self._first_ns, max(g.last_ns for g in self.gates if g.last_ns is not None))

    def _gate(
        self, i: int, stamp_ns: np.ndarray | int, value: np.ndarray | float, frame_id: np.ndarray | str | None
    ) -> tuple[np.ndarray, np.ndarray]:
        stamps = np.atleast_1d(np.asarray(stamp_ns, dtype=np.int64))
        values = np.atleast_1d(np.asarray(value, dtype=float))
        gate = self.gates[i]
        if gate.take_regular(stamps, values, frame_id):  # a live drain's batch: every message taken
            # what the general lines below do with an all-accepting mask (copies, as ``stamps[ok]``)
            self.ledgers[i].note_taken(len(stamps), int(stamps[-1]))
            if self._first_ns is None or int(stamps[0]) < self._first_ns:
                self._first_ns = int(stamps[0])
            return stamps.copy(), values.copy()
        local: Counter = Counter()
        ok = gate(stamps, values, frame_id, self._clock_span(), local, try_regular=False)  # (just tested)
        for since, until in self.gates[i].pop_frozen_heads():
            ok = self._take_back_frozen_head(i, stamps, ok, since, until, local)
        if local:
            self.counts.update(local)
        self.ledgers[i].note(ok, values, frame_id, Counter(), local, stamps)
        n_ok = int(np.count_nonzero(ok))
        # the gate holds a large forward step for one message (one wild stamp costs only itself):
        # a message it held earlier and now takes joins this batch
        stamps, values = self.gates[i].with_released(stamps[ok], values[ok])
        self.ledgers[i].used += len(stamps) - n_ok
        if len(stamps) and (self._first_ns is None or int(stamps[0]) < self._first_ns):
            self._first_ns = int(stamps[0])
        return stamps, values

    def _take_back_frozen_head(
        self, c: int, stamps: np.ndarray, ok: np.ndarray, since: int, until: int, local: Counter
    ) -> np.ndarray:
        """Reject the head of a run found frozen: in this batch, and in the windows still open.

        A channel that stopped holds its last value; the gate takes the run's first ``frozen_ns``
        before it can tell, and those samples made a window of the old value beside the other
        cell's new one. Samples of windows already closed stay (with the default 30 s topic
        timeout against the 10 s hold the head's windows are always open).
        """
        head = ok & (stamps >= since) & (stamps < until)
        n = int(np.count_nonzero(head))
        ok = ok & ~head
        dropped = self.buffer.force[c].drop_between(since, until)
        if dropped:
            self.used[CHANNELS[c]] -= dropped
            self.ledgers[c].used -= dropped
        if n + dropped:
            local["frozen"] += n + dropped
        return ok

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
        stamps, values = self._gate(c, stamp_ns, force_n, frame_id)
        late = self.buffer.add_forces(c, stamps, values)
        if late:
            self.counts["late"] += late
            self.ledgers[c].rejected["late"] += late
            self.ledgers[c].used -= late  # taken by the gate, refused by the windows
        n = len(stamps) - late
        self.used[CHANNELS[c]] += n
        return n

    def ingest_temperature(
        self,
        stamp_ns: np.ndarray | int,
        temp_c: np.ndarray | float,
        frame_id: np.ndarray | str | None = None,
        log_ns: np.ndarray | int | None = None,
    ) -> int:
        """Take air-temperature messages in arrival order; return the number accepted."""
        stamps, values = self._gate(2, stamp_ns, temp_c, frame_id)
        self.buffer.add_temperature(stamps, values)
        self.used["air_temperature"] += len(stamps)
        return len(stamps)

    # -- windows ----------------------------------------------------------------------------
    def poll(self, now_ns: int | None = None) -> list[WindowOutput]:
        """Close every due window and return the outputs that are decided, in window order.

        ``now_ns`` (optional) extends the data clock for the missing-topic timeout, e.g. a node's
        wall clock when all inputs stop; leave it None to stay on stamp time (replay-exact).
        """
        outputs = self._process(self.close_windows(now_ns))
        outputs.extend(self._decide_before_gap(self.buffer.next_k))
        self._maybe_checkpoint()
        return outputs

    def _follow_air(self, w: Window) -> None:
        """Note an air temperature that jumped more than air does since the last window with one.

        A later record whose logger wrote °F (53.6 for 12 C) passed the range check: the sun term
        and the curve read 40 K of warming in 3 h, and an event became an unconfirmed change with
        nothing said. The bound is ``AIR_JUMP_K`` (a sensor's and the match's scatter) plus
        ``AIR_RATE_K_PER_H`` per hour between the windows (report.air_jump_lines).
        """
        known = [t for t in w.temp.tolist() if math.isfinite(t)]  # floats: a live window's few
        if not known:
            return
        t = sum(known) / len(known)
        last = self.air["last"]
        self.air["last"] = [int(w.k), t]
        if last is None:
            return
        hours = (w.k - last[0]) * self.config.window_s / 3600.0
        excess = abs(t - last[1]) - (AIR_JUMP_K + AIR_RATE_K_PER_H * hours)
        if excess > 0:
            self.air["jumps"] += 1
            if excess > self.air["excess"]:
                self.air["excess"] = excess
                self.air["worst"] = [int(last[0]), int(w.k), float(last[1]), t]

    def _decide_before_gap(self, next_k: int | None) -> list[WindowOutput]:
        """Decide what is held once every window that could follow without a gap has closed.

        The next usable window will open a gap (``_open_gap``), and what the gap decides of the
        windows before it (the held windows after the gap before, ``_release_fresh``; the
        detector's run, ``close_run``) needs nothing after it. Decided only when that window came,
        a load-test day's record was decided when the next record had *ended* (its windows are
        held for the traffic screen until then): the engineer saw the 10 mm state hours late, and
        in between the posterior of the gap before it (windows 0, the jump prior's width, 18 mm).
        The same calls ``_open_gap`` makes, on the same held windows and state, only earlier: the
        results are the same; ``_open_gap`` then finds nothing held. ``next_k``: the first window
        not yet judged (``poll``: the buffer's next; ``_process``: the window about to be judged).
        """
        last = self._last_usable_k
        if last is None or next_k is None or next_k < last + 1 + self._gap_k:
            return []
        outputs: list[WindowOutput] = []
        if not self.warm:
            # the first record, shorter than the warm-up (the test car cut from it): fitted now, as
            # the next record's first windows would leave it (``_finish_warmup`` holds them fresh)
            if len(self._warm) <= MIN_DIFFERENCES or any(w.seg != self.filter.segment for w in self._warm):
                return []
            self._leave_out_lone_warm()
            self._finish_warmup()
            outputs.extend(self._drain())
        if not self._fresh_open and not self.detector.pending:
            return outputs
        self.settle()
        outputs.extend(self._release_fresh(at_gap=True))
        outputs.extend(self._close_run(self.detector.close_run(at_gap=True)))
        outputs.extend(self._drain())
        return outputs

    # -- the archive's two halves of ``poll`` (bridge_shadow.archive, issue 21) ----------------
    def close_windows(self, now_ns: int | None = None) -> WindowBatch:
        """Close every due window and return it unprocessed: the gate-and-window half of ``poll``.

        A shadow that only reduces one bag of an archive calls this instead of ``poll``; the
        shadow that estimates over the whole stream processes the batch with ``take_windows``.
        """
        clock = self.clock_ns
        if clock is None or self.buffer.next_k is None:
            return WindowBatch.empty()
        if now_ns is not None:
            clock = max(clock, int(now_ns))
        lasts = [g.last_ns for g in self.gates[:2]]
        return self.buffer.close_until(self.buffer.due_end(clock, lasts), lasts)

    def take_windows(self, batch: WindowBatch) -> list[WindowOutput]:
        """Process windows closed by ``close_windows`` (of this or another shadow), in window order.

        The sequential half of ``poll``: event detector, compensation refits, settlement chain.
        ``batch`` must follow the windows this shadow has processed (``k`` increasing); returns
        the outputs decided so far, as ``poll`` does.
        """
        return self._process(batch)

    def flush(self) -> list[WindowOutput]:
        """Close every window that holds data and decide on held ones (end of a record).

        Then refit with a freshly selected ``lambda`` (the batch-equivalent posterior); the last
        output carries it.
        """
        self.settle()
        for c, gate in enumerate(self.gates):  # the end of the data: a message held after a gap is taken
            if gate.release_held():
                none = np.empty(0, np.int64), np.empty(0)
                self.ingest_forces(c, *none) if c < 2 else self.ingest_temperature(*none)
        outputs = self._process(self.buffer.flush([g.last_ns for g in self.gates[:2]]))
        outputs.extend(self._release_fresh())
        outputs.extend(self._close_run(self.detector.flush()))
        if not self.warm and self._warm:
            self._finish_warmup()
            outputs.extend(self._drain())
            outputs.extend(self._release_fresh())  # the windows after a gap it left held
            outputs.extend(self._close_run(self.detector.flush()))
        outputs.extend(self._drain())
        if self.warm and self.sums.n + len(self._rows) > 0:
            self._refit(reselect=True)
            if outputs:
                last = outputs[-1]
                last.mean_m, last.covariance_m2 = self.posterior
        return outputs

    def _process(self, batch: WindowBatch) -> list[WindowOutput]:
        """Turn closed windows into ``Window`` records, judge the usable ones, return decided outputs."""
        n = len(batch)
        if not n:
            return []
        self.n_windows += n
        if batch.cut.any():  # (counts: a row sums to more than 0 where any is)
            for j in np.flatnonzero(batch.cut.sum(axis=1) > 0):
                row = [int(batch.k[j]), *map(int, batch.cut[j]), *map(int, batch.samples[j])]
                self.traffic_windows.append(row)
        self.parked.extend([int(t), int(end), float(a), float(b)] for _, t, end, a, b in batch.parked)
        sun, svar = None, np.zeros(n)
        if n == 1:  # a live window: the sun covariate and the basis in Python numbers, the same values
            temps = batch.temp_c[0].tolist()
            sun_one = 0.0
            if self.sun is not None:
                mid = int(batch.k[0]) * self._w_ns + self._w_ns // 2
                t = temps[0] if math.isfinite(temps[0]) else temps[1]
                sun_one, var_one = self.sun.value_one(mid, t, self._w_ns)
                svar = np.array([var_one])
            one = self.compensation.basis_one(temps, sun_one)
            i0, bv = np.array([one[0]], dtype=np.int64), np.array([one[1]])
        else:
            if self.sun is not None:  # one air temperature for both channels: the first one known
                temp = np.where(np.isfinite(batch.temp_c[:, 0]), batch.temp_c[:, 0], batch.temp_c[:, 1])
                sun, svar = self.sun.values(batch.k * self._w_ns + self._w_ns // 2, temp, self._w_ns)
            i0, bv = self.compensation.basis_rows(batch.temp_c, sun)
        windows = [
            Window(
                int(batch.k[j]),
                batch.samples[j],
                batch.force_n[j],
                batch.temp_c[j],
                str(batch.reason[j]),
                i0[j],
                bv[j],
                float(svar[j]),
                stale_variance(float(batch.temp_age_s[j]), self.config.temperature_stale_s),
            )
            for j in range(n)
        ]
        outputs: list[WindowOutput] = []
        for j, w in enumerate(windows):
            # what ``poll`` decides once the gap is certain, decided at the same window whatever
            # the batch: a batch that runs over the gap (the archive's join, a chunk holding both
            # records) decides it before its first window after the gap, as polls between would
            outputs.extend(self._decide_before_gap(w.k))
            self.settle()  # the state this window is judged against
            self.silence.note(w.k, w.samples)
            if self._last_data_k is not None and w.k - self._last_data_k > 1:
                self._outage_since_usable = True
            self._last_data_k = w.k
            if w.reason:
                self.counts[w.reason] += 1
            elif not math.isfinite(w.temp[0]):
                self.uncompensated += 1
            elif w.tvar > 0:
                self.stale_temperature += 1
            self._queue.append(w)
            self._follow_air(w)
            if w.reason:
                continue
            if not self.filter.starts:
                self.filter.start(w.k)
            elif self._last_usable_k is not None and w.k - self._last_usable_k - 1 >= self._gap_k:
                outputs.extend(self._open_gap(w))
            self._last_usable_k = w.k
            self._last_usable_sun = self._window_sun(w)
            if self._outage_since_usable:  # (a gap's first window too: kind "gap" says it already)
                self.filter.mark_outage(w.k)
                self._outage_since_usable = False
            if not self.warm:
                w.seg = self.filter.segment
                self._warm.append(w)
                if len(self._warm) < self.config.warmup_windows:
                    continue
                self._leave_out_lone_warm()
                alone = self._last_warm_alone()
                self._finish_warmup()
                # the warm windows update the estimate before the next window is judged against
                # it, whether that window comes in the same batch or later (chunking-exact)
                outputs.extend(self._drain())
                if not alone:
                    continue
            self._take_back_lone(w)
            self._note_young(w)
            young = None if self._fresh_open else self._young_run(w)
            late = self._n_accepted >= self._young_count
            # a level the young windows hold first: read on all of them, it places the change where
            # it began (a spike's fall into w is no new state's start when w goes on a level that
            # began windows before it)
            level = young is not None and self._young_level(w, *young, raises=not late)
            moved = None if young is None or late or level else self._young_step(w, *young)
            if moved is not None:
                self._leave_out_moved(moved)  # a ramp's windows taken as data hold neither state
                outputs.extend(self._open_young(w))  # w is held as the first of the new state's
            if self._fresh_open:
                self._fresh.append(w)
                if len(self._fresh) >= self.config.warmup_windows and not self._ramp_going_on():
                    outputs.extend(self._release_fresh())
                continue
            if w.g_fit != self._fit_id:
                stop = j + _CURVE_BLOCK
                self._precompute_curve(windows[j:stop], batch.temp_c[j:stop], i0[j:stop], bv[j:stop])
            outputs.extend(self._judge(w))
            outputs.extend(self._drain())
        outputs.extend(self._drain())
        return outputs

    def _take_back_lone(self, w: Window) -> None:
        """Take the last young window back as an outlier: alone beyond any vehicle, ``w`` back.

        While the state is young its estimate's uncertainty is wide, and the detector took a load
        of 60 kN over one window as data (the reference record raised 15 mm at minute 16.4, the
        load over the 120 s window after the next: 17.7 mm for 15 at the end); the noise model
        grew with it. Once ``w`` shows it came back (``events.warmup.lone_windows_beyond_vehicle``
        on it, the window before and ``w``) its rows leave the sums (``FitSums.remove_last``), its
        jump leaves the detector's bound (``ChangeDetector.take_back``), and it is counted and
        listed as an outlier (its output went out as an update). Before the young rules read
        ``w``: the fall from the load is no jump into ``w``.
        """
        prev = self.detector.prev
        if self._young_done or self.detector.pending or self._fresh_open or not self.filter.starts:
            return
        if prev is None or prev.k != w.k - 1:  # the window before ``w`` was not taken as data at once
            return
        data = self._young_data(self.filter.starts[-1], w.k)
        if len(data) < 2:
            return
        q, p = data[-2], data[-1]
        if p.action != "accept" or prev.k != p.k or not q.k + 1 == p.k == w.k - 1:
            return
        y, _ = self._compensated([q, p, w])
        if lone_windows_beyond_vehicle(y, self.config.traffic_vehicle_max_n) != [1]:
            return
        self.detector.take_back(p.k)
        self._leave_out_moved([p], "outlier")

    def _young_run(self, w: Window) -> tuple[list[Window], np.ndarray, np.ndarray] | None:
        """Return the current segment's young data windows and ``w``, compensated, or None.

        None once the noise model is no longer young, while the detector holds a run, or before
        any young window: the young rules (``_young_step``, ``_young_level``) then read nothing.
        """
        if self._young_done or self.detector.pending or not self._young or not self.filter.starts:
            return None
        run = self._young_with(w)
        y, ks = self._compensated(run)
        return run, y, ks

    def _young_step(self, w: Window, run: list[Window], y: np.ndarray, ks: np.ndarray) -> list[Window] | None:
        """Return the windows a new state from ``w`` leaves out, if the young noise model cannot see it.

        None: no new state begins at ``w``; ``[]``: a jump into ``w``; else a ramp's moving windows
        before ``w`` that were taken as data (``_leave_out_moved``). See ``_open_young``.

        While the noise model rests on fewer than ``RAMP_HOLD_FACTOR * warmup_windows`` accepted
        windows (30: three warm-ups), the current segment's windows among the last as many and
        ``w`` are searched for a jump into ``w`` on their own scale
        (``events.warmup.new_state_at_last``: the successive differences' robust scale, so a load
        that stood over most of the warm-up does not set it) that moves the reactions' sum beyond
        any vehicle (``traffic_vehicle_max_n``), and that the detector would take as data at once
        (``ChangeDetector.takes_as_data``): no vehicle makes such a jump, so the young noise model
        that let it through is not its judge. Where the detector would hold the window its run
        decides, as before: opening the segment there too, a vehicle parked minutes after the step
        among the windows held after the jump took the new state's level with it (a reviewing
        helper's 180 such streams: covered 177 before the rule, 143 with it there, 168 as it is,
        9 of those 12 warned; -2.6 mm ± 5.9 for -10, silent, on the worst with it there).
        A support lowered over minutes makes no such jump: a ramp going on at ``w`` on the same
        scale that has moved the reactions' sum beyond any vehicle
        (``events.warmup.ramp_beyond_vehicle_at_last``) begins a new state there too, and its
        moving windows taken as data are left out (the reference record three times from the
        data's start, lowered 10 mm over its minutes 8-13, no vehicle: every window was taken as
        data, the noise model grew with them, and the stream ended at -1.4 mm ± 8.1 for -10, no
        event).
        """
        if len(run) <= MIN_DIFFERENCES + 1:
            return None
        probability, vehicle = self.detector.false_trigger, self.config.traffic_vehicle_max_n
        if new_state_at_last(y, ks, probability, vehicle):
            moved: list[Window] = []
        else:
            first = ramp_beyond_vehicle_at_last(y, ks, probability, vehicle)
            if first is None:
                return None
            moved = run[first:-1]
        return moved if self.detector.takes_as_data(w.k, *self._judge_terms(w)) else None

    def _open_young(self, w: Window) -> list[WindowOutput]:
        """Open a provisional segment at ``w`` and hold the windows from it as after a gap.

        The warm-up's noise model rests on ten windows: a vehicle parked over six of them (20 kN,
        continuous data, unscreened) read as a window sd of 20 kN with a lag-one correlation of
        0.9, and a 20 mm settlement minutes later passed the detector's trigger window by window
        as data; the refit then took the step for noise, and the stream ended at -2.6 mm for
        -20, nothing said. A jump beyond any vehicle found on the windows' own scale
        (``_young_step``) opens a provisional segment (``kind: warmup``, as a step among the
        warm-up windows does), which the data after it decide, and its windows are held and read
        as the first windows after a gap are (``_release_fresh``): the window the step happened
        in holds both states and is left out there, as a ramp's moving windows are.
        """
        outputs = self._drain()
        prior = self.config.change_prior_probability
        self.filter.open_segment(w.k, self._drift_jump(w.k), kind="warmup", change_prior=prior)
        self.detector.prev = None  # innovations after it refer to a new estimate
        self._fresh_open = True
        return outputs

    def _young_first(self, fresh: list[Window], y: np.ndarray, ks: np.ndarray) -> str | None:
        """Return what the first held window of a young jump is (``_open_young``): mixed, odd or None.

        ``mixed``: the jump happened inside it, and the next difference goes on the same way beyond
        the trigger on the windows' own scale (``events.warmup.jump_goes_on``, with the old state's
        last windows before them). Kept as the new state's first window, a third of the old level
        stayed in it, the segment's level moved, the detector held the next window as a change of
        its own, and neither was confirmed (the 10 mm record three times, 4 h after the first, 10
        mm lower at each seam). ``odd``: the window after it came back from it by more than any
        vehicle and is no new state beyond any vehicle from the old one (``new_state_at_last`` on
        the old windows and it): a spike that came back, an outlier, as the detector rejects one
        (both forces +40 kN for one minute). A window after it that stayed at its level is no
        return: a vehicle parked on a new state among the young windows, leaving, is such a jump,
        and the first car-free window of the new state was rejected as an outlier (a reviewing
        helper's family M: the lowered record, 10 mm more at the first seam, 25 kN over minutes
        14-21).
        """
        f = self.filter
        if not fresh or f.kinds[-1] != "warmup" or f.starts[-1] != fresh[0].k or len(fresh) < 2:
            return None
        old = self._young_data(f.starts[-2] if len(f.starts) > 1 else 0, fresh[0].k)
        if not old:
            return None
        y_old, k_old = self._compensated(old)
        probability = self.detector.false_trigger
        if jump_goes_on(np.vstack([y_old, y[:2]]), np.concatenate([k_old, ks[:2]]), probability):
            return "mixed"
        vehicle = self.config.traffic_vehicle_max_n
        came_back = beyond_any_vehicle(y[1] - y[0], vehicle)
        if came_back and not new_state_at_last(
            np.vstack([y_old, y[1:2]]), np.append(k_old, ks[1]), probability, vehicle
        ):
            return "odd"
        return None

    @property
    def _young_count(self) -> int:
        """Accepted windows below which the noise model is young (``RAMP_HOLD_FACTOR * warmup_windows``)."""
        return RAMP_HOLD_FACTOR * self.config.warmup_windows

    def _young_with(self, w: Window) -> list[Window]:
        """Return the current segment's young data windows before ``w``, and ``w``."""
        return [*self._young_data(self.filter.starts[-1], w.k), w]

    def _young_data(self, lo: int, hi: int) -> list[Window]:
        """Return the young windows of indices ``[lo, hi)`` that are data (taken or warm-up)."""
        return [x for x in self._young if lo <= x.k < hi and x.action in ("accept", "warm")]

    def _leave_out_moved(self, moved: list[Window], reason: str = "step_window") -> None:
        """Take a young ramp's windows out of the estimate: they hold neither state (``_young_step``).

        They were taken as data of the current segment (its last ones) and each went out as an
        update; their rows leave the sums (``FitSums.remove_last``), they are counted and listed as
        ``reason`` (``step_window``; a lone load's ``outlier``: ``_take_back_lone``), and the
        curve, the noise model and the chain are refitted without them.
        """
        if not moved:
            return
        self._flush_rows()
        seg = self.filter.segment
        gone = {w.k for w in moved}
        kept = [x for x in self._young_data(self.filter.starts[-1], moved[0].k) if x.k not in gone]
        before = self._window_rows(kept[-1:], seg) if kept else None
        self.sums.remove_last(self._window_rows(moved, seg), before)
        self._take_back(moved, reason)
        if kept:
            self._last_ok = kept[-1]
        self._refit()

    def _take_back(self, windows: list[Window], reason: str = "step_window") -> None:
        """Leave out windows taken as data whose rows have left the sums: counted, listed, not latest."""
        gone = {w.k for w in windows}
        for w in windows:
            self._leave_out(w, reason)
            self._note_rejected(w.k, w.reason)
        latest = [x for x in self._latest if x.k not in gone]
        self._latest.clear()
        self._latest.extend(latest)

    def _young_level(
        self, w: Window, run: list[Window], y: np.ndarray, ks: np.ndarray, raises: bool = True
    ) -> bool:
        """Move the windows of a new level the young noise model took as data into a segment of their own.

        A support lowered over minutes at a pace the test car's moves break makes neither a jump
        nor a ramp on the windows' own scale (``_young_step``), and a young noise model takes every
        window as data and grows with them (the reference record three times from the data's
        start, lowered 10 mm over its minutes 8-18: the stream ended at -1.2 mm ± 8.1 for -10, no
        event). Where the last windows and ``w`` hold a level beyond twice any vehicle from the
        windows before them (``events.warmup.level_beyond_vehicle_at_last`` with
        ``2 * traffic_vehicle_max_n``) and the detector takes ``w`` as data, the windows of the new
        level leave the current segment's sums and open a provisional one (``kind: warmup``,
        decided by the data as after a gap), and everything is refitted; ``w`` is then judged
        against it. Their outputs went out as they were. Twice: a vehicle over every old window
        that then left, with the recorded test car's plateaus beside it, read as a level at the
        bound itself (a reviewing helper's streams: 30 kN over minutes 0-5, no settlement), and
        lowerings of 5-7 mm (34-47 kN on the sum) the chain then weighed at about 0.01 ended short
        of the truth without a word on 8 of its 160 streams near the bound, where the old noise
        model's width had held them; at twice the bound neither happened on its 511 streams.
        Past the young phase's windows (held on by ``_level_unsettled``) ``raises`` is False and only
        a lowering is read: a raise below twice the bound with a vehicle parked on it to the last
        window read as one raise of both (a reviewing helper's streams: 60 s windows, -14.6 mm,
        +6.5 mm, 25-40 kN from minute 27 on: covered before, -12.1 mm ± 2.7 for -18.0 and silent).
        Returns whether it moved them. It is read before the young jump rule (``_young_step``):
        the fall from a one-window load back onto a level that began windows before is a jump
        into ``w`` too, and opening the new state there left the level's first windows in the old
        segment (a reviewing helper's family C: 10 mm at minute 12 let go as data, 60 kN over
        minute 22: -2.6 mm ± 7.2 for -10, no event, nothing said).
        """
        found = level_beyond_vehicle_at_last(y, 2.0 * self.config.traffic_vehicle_max_n, raises)
        if found is None or not self.detector.takes_as_data(w.k, *self._judge_terms(w)):
            return False
        self._flush_rows()
        a, i = found
        old, moving, new = self.filter.segment, run[a:i], run[i:-1]
        self.sums.remove_last(self._window_rows(run[a:-1], old), self._window_rows(run[a - 1 : a], old))
        self._take_back(moving)  # a ramp's windows hold neither state
        prior = self.config.change_prior_probability
        self.filter.open_segment(new[0].k, self._drift_jump(new[0].k), kind="warmup", change_prior=prior)
        seg = self.filter.segment
        for x in new:
            x.seg = seg
        self.sums.add(self._window_rows(new, seg))
        self.detector.prev = None  # innovations after it refer to a new estimate
        self._refit()
        return True

    def _row(self, w: Window, seg: int) -> tuple[Any, ...]:
        """Return window ``w``'s row for the sums, taken as data of segment ``seg``."""
        return (w.k, w.samples, w.force - self.u0, w.temp, w.i0, w.bv, seg, _sun_var(w) ** 0.5)

    def _window_rows(self, windows: list[Window], seg: int) -> WindowRows:
        """Return the sums' rows of ``windows`` (at least one) taken as data of segment ``seg``."""
        return _rows_of([self._row(w, seg) for w in windows])

    def _note_young(self, w: Window) -> None:
        """Keep ``w`` among the young windows until the noise model rests on enough windows.

        Enough: ``RAMP_HOLD_FACTOR * warmup_windows`` accepted windows, and, up to twice as many,
        no level the young level rule has yet to read (``_level_unsettled``). Past the first count
        only that rule reads the young windows (``process``).
        """
        if self._young_done:
            return
        young = self._young_count
        if self._n_accepted >= young and not self._level_unsettled(w):
            self._young, self._young_done = [], True
            return
        self._young = [*self._young[1 - young :], w]

    def _level_unsettled(self, w: Window) -> bool:
        """Whether ``w`` lies beyond any vehicle below the young run's first windows (to twice the count).

        Only a lowering holds it on (``events.warmup.level_unsettled_at_last``), and only a lowering
        is read then: a vehicle parked on a smaller raise makes a raise. A support lowered over
        the minutes that end the young phase leaves its new level too few
        windows at rest for ``_young_level`` when the phase ends, and the noise model, fitted on the
        ramp's windows taken as data, no longer sees it (the reference record three times from
        the data's start, 10 mm lower over its minutes 20-30, no vehicle: -0.5 mm ± 8.1 for -10, no
        event). While the last window is that far below the first ones
        (``events.warmup.level_unsettled_at_last``) the young level rule reads on, up to as many
        accepted windows again.
        """
        if self._n_accepted >= 2 * self._young_count or self.detector.pending or not self.filter.starts:
            return False
        y, _ = self._compensated(self._young_with(w))
        return level_unsettled_at_last(y, self.config.traffic_vehicle_max_n)

    def _precompute_curve(
        self, windows: list[Window], temp: np.ndarray, i0: np.ndarray, bv: np.ndarray
    ) -> None:
        """Evaluate the current curve (and its variance) at every window of a batch, at once."""
        if self.fit is None:
            return
        comp = self.compensation
        one = (
            comp.curve_one(self.fit, temp[0].tolist(), i0[0].tolist(), bv[0].tolist())
            if len(windows) == 1
            else None
        )
        if one is not None:  # a live window: floats, the same values (``Compensation.curve_one``)
            g, gvar = [one[0]], [one[1]]
        else:
            g = comp.curve_rows(self.fit, temp, i0, bv).tolist()
            gvar = comp.curve_variance(self.fit, i0, bv).tolist()
        sun = self.fit.beta[:, -1] if comp.sun else np.zeros(2)
        s0, s1 = float(sun[0]), float(sun[1])
        t0, t1 = comp.slope_fe_floats
        for w, gw, vw in zip(windows, g, gvar, strict=True):
            w.g = (gw[0], gw[1])
            # the sun covariate's own uncertainty moves both channels' predictions together
            sv = _sun_var(w)
            # a stale air temperature (``stale_variance``) likewise, through the curve's FE slope
            tv = w.tvar if w.i0[0] >= 0 else 0.0
            w.gvar = (
                vw[0] + s0 * s0 * sv + t0 * t0 * tv,
                s0 * s1 * sv + t0 * t1 * tv,
                vw[1] + s1 * s1 * sv + t1 * t1 * tv,
            )
            w.g_fit = self._fit_id

    # -- gaps and provisional segments ---------------------------------------------------------
    def _drift_jump(self, k: int) -> np.ndarray | None:
        """``Q dt`` from the current segment's start to window ``k`` (None without process noise)."""
        if not self.drifting:
            return None
        return self._block_jump * ((k - self.filter.starts[-1]) / self._block_k)

    def _open_gap(self, w: Window) -> list[WindowOutput]:
        """Window ``w`` follows a gap: decide what is held, then start a provisional segment at ``w``.

        The supports may have moved while no data came: a run held before the gap is decided now
        (an event or an unconfirmed change, never outliers), the windows before ``w`` are applied
        to the state before the gap, and ``w`` opens a segment whose jump is uncertain
        (``change_prior_probability``; ``segments`` weighs both outcomes by the data).
        """
        outputs: list[WindowOutput] = []
        if self.warm:
            outputs.extend(self._release_fresh(at_gap=True))
            outputs.extend(self._close_run(self.detector.close_run(at_gap=True)))
            outputs.extend(self._drain())
        else:
            self._split_warm_segment()
        gap: dict[str, Any] = {
            "from_k": int(self._last_usable_k or w.k),
            "to_k": w.k,
            "segment": self.filter.segment + 1,
        }
        after = self._window_sun(w)
        if self._last_usable_sun is not None and after is not None:
            # the sun covariate on either side: what the deck's sun could have done across the gap
            # (``report.sun_ambiguity_lines``)
            gap["sun_covariate"] = [self._last_usable_sun, after]
        self.gaps.append(gap)
        self.filter.open_segment(
            w.k, self._drift_jump(w.k), kind="gap", change_prior=self.config.change_prior_probability
        )
        self.detector.prev = None  # innovations after the gap refer to a new estimate
        self._fresh_open = self.warm  # (during the warm-up its own search covers the segment)
        return outputs

    def _window_sun(self, w: Window) -> float | None:
        """Return the sun covariate window ``w`` entered the compensation with (None: no sun term, no air)."""
        if not self.compensation.sun or w.i0[0] < 0:
            return None
        sun = float(w.bv[0][-1])
        return sun if math.isfinite(sun) else None

    def _ramp_going_on(self) -> bool:
        """Whether the windows held after a gap end in a ramp still in progress (hold them on).

        ``events.warmup.ramp_in_progress``, up to ``RAMP_HOLD_FACTOR`` times ``warmup_windows``:
        a support lowered over minutes keeps moving past the tenth window, and the state after it
        needs windows among the held ones for ``_release_fresh`` to see where the ramp ends. That
        rule reads the ramp against still differences of the held windows before it; a lowering
        from the record's first minutes, or a record whose test car was cut, may have none or one.
        So the windows are held too while they move against the noise model known before the gap
        (``moving_on_known_noise``), and, once they have moved so, until their last differences are
        still (``moved_not_still``: the test car's moves among them), as the detector holds a run
        on (``ChangeDetector._long_run``). A hold decides nothing: the held windows are judged by
        the rules when it ends (``_release_fresh``; ``benchmarks/loadtest_days.py --only ramps``,
        ``test_ramp.py``).
        """
        if len(self._fresh) >= RAMP_HOLD_FACTOR * self.config.warmup_windows:
            return False
        y, k = self._compensated(self._fresh)
        cov = self._known_window_cov(self._fresh)
        probability = self.detector.false_trigger  # the trigger's false probability
        return self._moving(y, k, cov) or moved_not_still(y, k, cov, self.noise.phi, probability)

    def _moving(self, y: np.ndarray, k: np.ndarray, cov: np.ndarray) -> bool:
        """Whether windows held after a gap still move: a ramp in progress, or a move on the known ``cov``."""
        probability = self.detector.false_trigger  # the trigger's false probability
        return ramp_in_progress(y, k, probability) or moving_on_known_noise(
            y, k, cov, self.noise.phi, probability
        )

    def _step_reading(self, y: np.ndarray, ks: np.ndarray, steps: set[int], both: set[int]) -> None:
        """Add the step rules' reading of held windows: new states' first windows, windows a step was in."""
        probability = self.detector.false_trigger  # the trigger's false probability
        for start, mixed in step_windows(y, ks, probability, self.config.traffic_vehicle_max_n):
            if mixed is not None:  # each side keeps a window: its neighbours are its states'
                both.add(mixed)
                start = mixed + 1
            steps.add(start)

    def _known_window_cov(self, windows: list[Window]) -> np.ndarray:
        """Return the noise model's covariance (2, 2) N^2 of a window mean at the windows' mean count."""
        return self.noise.window_cov(np.mean([w.samples for w in windows], axis=0))

    def _compensated(self, windows: list[Window]) -> tuple[np.ndarray, np.ndarray]:
        """Return the windows' forces less the current curve (n, 2) N and their indices (n,)."""
        y = np.array([w.force - np.array(self._curve(w)) for w in windows]).reshape(-1, 2)
        return y, np.array([w.k for w in windows], np.int64)

    def _leave_out(self, w: Window, reason: str = "step_window") -> None:
        """Leave out a window that holds neither state (a step or a ramp went on in it), or ``reason``."""
        w.reason, w.action = reason, "invalid"
        self.counts[reason] += 1

    def _release_fresh(self, at_gap: bool = False) -> list[WindowOutput]:
        """Judge the windows held after a gap, in order; a step among them opens a provisional segment.

        Right after a gap the provisional segment's level rests on its first few windows, so the
        step detector, which judges a window against it, cannot see a step among them: a
        settlement minutes into the first record after hours (the test car cut leaves a window
        or two of the old state) was taken into that level, half of it lost, no event, and an
        interval that excluded the truth. The held windows are searched as the warm-up's are
        (``events.warmup.step_windows``: on their own scale, compensated by the current curve; one
        step, or two of a size, as when a support is lowered twice within a record); each step
        found opens a provisional segment (``kind: warmup``) at its first window, which the data
        after it decide like the gap's. The first window of either segment is taken as its data, not
        judged against it: a level beyond the jump prior's reach (50 mm here) made the detector
        hold the gap's first window and all after it, and the change ended an unconfirmed held run
        instead of the gap's event (an odd first window is the search's to find: it makes a step
        between the first and the second). The window a step happened in holds both states: taken
        as the first window of the new segment (the side it was nearer), it made that segment's
        level, the next window jumped from it by the rest of the step, and the detector reported a
        second event of about half the step (10 of 56 streams with two steps inside a record); it
        is left out as ``step_window`` (where ``step_windows`` names it: its neighbours next to it)
        and the new segment starts at the window after it. With ``at_gap`` (the data stop after
        these windows), a step whose new state is the last window alone, no heavier than any
        vehicle, is no state of its own (``detector.SHORT_STATE_WINDOWS``): that window is left
        out, and the gap's segment weighs any change by the windows after the gap
        (``ChangeDetector.close_run``). Not at the end of the data: the last difference of held
        windows may be the rest of a step whose window is left out before it, and a settlement
        in a record's last minutes was lost with it (5 to 19 mm, 13 of the 300 streams of
        ``--only inside``). Windows the hold kept past ``warmup_windows`` because they moved
        (``_ramp_going_on``) that no step rule reads are read where they moved and stopped first
        (``moved_then_still`` with the test car's moves among the moving windows, as the
        detector's ``_long_run`` reads a run it held on), then as a ramp: a lowering from the
        record's first minute, the car parked on it, began where the car's weight hid it, and
        ``ramp_windows`` dated it minutes late (the windows before, judged one by one, a state
        of their own). Two settlements minutes apart with the car parked on the state between
        are then one change of their sum, as a lowering in stages is. Windows held on that none
        of these read are read by the step rules as far as the hold went before it waited for
        stillness (``_moving`` stopped), the rest judged one by one: all thirteen windows of a
        record with a raise at minute 7 and a lowering at minute 10 read as nothing, and the
        lowering's two windows at the end of the data were taken as the raise's data, 2.8 mm off
        (``--only inside --stream-seed 71``, #8).
        """
        if not self._fresh_open:
            return []
        fresh, self._fresh, self._fresh_open = self._fresh, [], False
        steps: set[int] = set()
        both: set[int] = set()  # windows a step happened in, left out
        if len(fresh) > MIN_DIFFERENCES:
            y, ks = self._compensated(fresh)
            vehicle = self.config.traffic_vehicle_max_n
            self._step_reading(y, ks, steps, both)
            last = len(fresh) - 1
            if at_gap and last in steps and not beyond_any_vehicle(y[last] - y[last - 1], vehicle):
                steps.discard(last)  # one window before a gap: a vehicle's, or the gap's to weigh
                both.add(last)
                w0, w1 = fresh[last - 1], fresh[last]  # the difference's two windows
                cov = self.noise.window_cov(w0.samples) + self.noise.window_cov(w1.samples)
                self._note_excursion([fresh[last]], y[last] - y[last - 1], cov, "before_gap")
            if 1 in steps and 0 not in both and last > 1 and 0.0 <= float(np.sum(y[0] - y[1])) <= vehicle:
                # the gap's first window alone before a step down by no more than a vehicle: the
                # load of one that stood when the record began and left within its first minute
                # (the screen reads a load a minute long at least, ``MIN_SIDE_BINS``); no state of
                # its own, so left out, and the gap's segment begins at the step (a lowering in
                # that minute is then the gap's change, dated at the window after it, as it was)
                steps.discard(1)
                both.add(0)
                cov = self.noise.window_cov(fresh[0].samples) + self.noise.window_cov(fresh[1].samples)
                self._note_excursion([fresh[0]], y[0] - y[1], cov, "after_gap")
            young = None if 0 in steps else self._young_first(fresh, y, ks)
            if young is not None:  # the difference after the young jump's window is its own
                steps.discard(1)  # rest (mixed) or return (odd), no step of its own
            if young == "mixed":
                both.add(0)  # the young jump's window, the step inside it (``_young_first``)
            held_on = len(fresh) > self.config.warmup_windows  # held past the warm-up: they moved
            ramp = None if steps else self._gradual_change(fresh, y, ks, held_on)
            if ramp is None and not steps and held_on:
                # read as none of these: the step rules read the windows the hold released before
                # it waited for stillness, and the rest are judged
                quiet = self.config.warmup_windows
                while quiet < len(fresh) and self._moving(
                    y[:quiet], ks[:quiet], self._known_window_cov(fresh[:quiet])
                ):
                    quiet += 1
                if quiet < len(fresh):
                    self._step_reading(y[:quiet], ks[:quiet], steps, both)
            if ramp is not None:  # a gradual change: its moving windows hold neither state
                both.update(range(*ramp))
                steps.add(ramp[1])
        else:
            young = None
        outputs: list[WindowOutput] = []
        first = 0
        for j, w in enumerate(fresh):
            self.settle()
            if j == 0 and young == "odd":  # the young jump came back: an outlier, as the detector's
                w.action = "reject"
                outputs.extend(self._drain())
                if self.filter.current_windows == 0:  # (odd: a window after it, no step there)
                    self.filter.move_start(fresh[1].k)
                first += 1
                continue
            if j in both:  # it holds both states: the level of neither (see the docstring)
                self._leave_out(w)
                outputs.extend(self._drain())
                # the gap's segment begins with its data (a step there opens a segment of its own)
                data_next = j + 1 < len(fresh) and j + 1 not in steps
                if j == first and data_next and self.filter.current_windows == 0:
                    self.filter.move_start(fresh[j + 1].k)
                first += j == first
                continue
            if j in steps and young is not None and j == first and self.filter.current_windows == 0:
                # the young jump's segment has no window yet (those before were left out: the
                # jump went on over them): this step is the same change, its segment begins here
                # (opened again, it was an empty segment at probability one half and the change
                # split in two, neither warned: the 10 mm record raised 10 mm over two windows)
                self.filter.move_start(w.k)
            elif j in steps:
                outputs.extend(self._close_run(self.detector.close_run()))
                outputs.extend(self._drain())
                prior = self.config.change_prior_probability
                self.filter.open_segment(w.k, self._drift_jump(w.k), kind="warmup", change_prior=prior)
                self.detector.prev = None
            if j == first or j in steps:
                w.action = "accept"  # a provisional segment's first window is its data, not judged by it
            else:
                outputs.extend(self._judge(w))
            outputs.extend(self._drain())
        return outputs

    def _gradual_change(
        self, fresh: list[Window], y: np.ndarray, ks: np.ndarray, held_on: bool
    ) -> tuple[int, int] | None:
        """Return ``(first moving, first of the new state)`` of held windows no step rule reads, or None.

        Held on because they moved: where they moved and stopped, the test car's moves among them
        (``moved_then_still`` without one sign); then a ramp (``ramp_windows``); then, in stages or
        a ramp a vehicle broke, where they moved one way and stopped (``moved_then_still``).
        """
        probability = self.detector.false_trigger  # the trigger's false probability
        vehicle = self.config.traffic_vehicle_max_n
        cov = self._known_window_cov(fresh)
        if held_on:
            found = moved_then_still(y, ks, cov, self.noise.phi, probability, vehicle, one_sign=False)
            if found is not None:
                return found
        found = ramp_windows(y, ks, probability)
        if found is not None:
            return found
        return moved_then_still(y, ks, cov, self.noise.phi, probability, vehicle)

    def _note_excursion(
        self, windows: list[Window], step_n: np.ndarray, cov_n2: np.ndarray, kind: str
    ) -> None:
        """Report windows not in the estimate as a possible change of ``step_n`` (2,) N (``excursions``)."""
        self.excursions.append(
            {
                "window": windows[0].k,
                "until_window": windows[-1].k,
                "windows": len(windows),
                "step_n": np.asarray(step_n, float).tolist(),
                "step_cov_n2": np.asarray(cov_n2, float).tolist(),
                "kind": kind,
            }
        )

    def _settle_provisional(self, now_k: int, merge: bool = False) -> bool:
        """Note provisional segments the data have decided; merge the unchanged ones; True if merged.

        With at least ``event_confirm_windows`` windows (``SegmentChain.windows_changed``: its own
        and those after it that stayed with the change), a change probability of at least
        ``change_confirm_probability`` confirms the change (it is reported as an event from then
        on, with ``now_k`` as the window that confirmed it; the posterior stays the mixture, which
        by then is the new state's). With ``merge`` (at refits), one of at most
        ``1 - change_confirm_probability`` joins the segment before it, however few its windows:
        unchanged, its windows are that state's, one level and one measurement, as if there had
        been no gap. By the same likelihood-ratio bound, whatever the number of windows, a true
        change drawn from the jump prior is merged at most that often. (Merges once waited for
        ``event_confirm_windows`` too: a false step among a record's last few windows then stayed
        a segment and took them from the change before it, which was never confirmed.) Only a
        merge is final: a confirmation that later data (a noise model that has seen more) no
        longer support is reported as unconfirmed again.
        """
        f = self.filter
        cfg = self.config
        for s in range(len(f.starts) - 1, 0, -1):
            if not 0.0 < f.change_prior[s] < 1.0:
                continue
            if self._note_confirmed(s, now_k):
                continue
            if merge and f.segment_probability(s)[0] <= 1.0 - cfg.change_confirm_probability:
                self._merge_segment(s)
                return True  # the chain is stale now: refit before judging the next one
        return False

    def _confirm_previous(self, now_k: int) -> None:
        """Note the confirmation of the provisional segment before the current one by the windows after it.

        ``SegmentChain.windows_changed``: a change too short to confirm on its own windows is
        confirmed when the state after it stays away from the one before it (here, with no
        provisional segment open, only the segment before the current one can still be).
        """
        f = self.filter
        s = len(f.starts) - 2
        if s > 0 and 0.0 < f.change_prior[s] < 1.0 and f.starts[s] not in self.confirmed_at:
            self._note_confirmed(s, now_k)

    def _note_confirmed(self, s: int, now_k: int) -> bool:
        """If provisional segment ``s``'s change is confirmed (``SegmentChain.confirms``), note when."""
        cfg = self.config
        h = self.detector.h_event
        if not self.filter.confirms(s, cfg.change_confirm_probability, cfg.event_confirm_windows, h):
            return False
        self.confirmed_at.setdefault(self.filter.starts[s], int(now_k))
        return True

    def _merge_segment(self, s: int) -> None:
        """Segment ``s`` did not change: its windows join segment ``s - 1`` (indices after it shift)."""
        self._flush_rows()
        self.sums.merge_into_previous(s)
        self.filter.remove_segment(s)
        for e in self.events:
            if int(e.get("segment", -1)) > s:
                e["segment"] = int(e["segment"]) - 1
        for g in self.gaps:
            if g["segment"] == s:
                g["segment"] = -1  # merged: no change across this gap
            elif g["segment"] > s:
                g["segment"] -= 1
        for w in (*self._queue, *self._warm):
            if w.seg >= s:
                w.seg -= 1

    # -- judging and applying ---------------------------------------------------------------------
    def _curve(self, w: Window) -> tuple[float, float]:
        """Centred ``g(T)`` (N, per channel) of one window (0 without temperature or before a fit)."""
        if w.g_fit != self._fit_id and self.fit is not None:
            self._precompute_curve([w], w.temp[None, :], w.i0[None, :], w.bv[None, :])
        return w.g

    def _innovation(self, w: Window) -> tuple[float, float]:
        """``v = y - u0 - g(T) - A x`` (N) of one window against the current curve and estimate."""
        g0, g1 = self._curve(w)
        (x0, x1), _ = self.filter.predict_floats()
        a = self._af
        return (
            float(w.force[0]) - self._u0f[0] - g0 - (a[0] * x0 + a[1] * x1),
            float(w.force[1]) - self._u0f[1] - g1 - (a[2] * x0 + a[3] * x1),
        )

    def _judge(self, w: Window) -> list[WindowOutput]:
        """Innovation of one usable window against the current estimate, then the detector's verdict.

        ``v = y - u0 - g(T) - A x`` with the single-window covariance pieces ``R1 / m`` and
        ``A P A'`` (plain floats: this runs for every window). Returns the outputs of windows the
        verdict decided only when the detector gives a window back to be judged against the state
        it started (``Decision.rejudge``); otherwise they follow in ``_drain``.
        """
        self._last_judged = w.k
        v, r_window, apa = self._judge_terms(w)
        if not self.config.event_detection:
            infl = self.detector.inflation
            total = (r_window[0] * infl + apa[0], r_window[1] * infl + apa[1], r_window[2] * infl + apa[2])
            w.action = "reject" if quad_inv(total, v) > self.detector.h_outlier else "accept"
            return []
        decision = self.detector.step(w.k, v, r_window, apa, w)
        self._apply(decision)
        return self._rejudge(decision.rejudge) if decision.rejudge else []

    def _judge_terms(self, w: Window) -> tuple[Vec, Sym, Sym]:
        """Return window ``w``'s innovation ``v`` (N), ``R1 / m`` and ``A P A'`` (N^2, ``(a, b, d)``)."""
        v = self._innovation(w)
        apa = congruence(self._af, self.filter.predict_floats()[1])
        gv = w.gvar  # the curve's own uncertainty (large beyond the temperatures seen so far)
        apa = (apa[0] + gv[0], apa[1] + gv[1], apa[2] + gv[2])
        rl = self._relaxation(w.k)
        if rl is not None:  # the reactions may still relax after the change that began this state
            apa = (apa[0] + rl[0], apa[1] + rl[1], apa[2] + rl[2])
        return v, self.noise.window_floats(float(w.samples[0]), float(w.samples[1])), apa

    def _rejudge(self, windows: list[Window]) -> list[WindowOutput]:
        """Judge windows the detector gave back (``Decision.rejudge``) after the decided ones are applied."""
        outputs: list[WindowOutput] = []
        for again in windows:
            outputs.extend(self._drain())
            self.settle()
            outputs.extend(self._judge(again))
        return outputs

    def _close_run(self, decision: Decision) -> list[WindowOutput]:
        """Apply the detector's decision on a run it closed (a gap, the end of the data); return outputs.

        A run that held two states (``ChangeDetector._second_state``) gives the second one's
        windows back: they are judged against the first once it is applied, and what they leave
        held is closed again.
        """
        self._apply(decision)
        if not decision.rejudge:
            return []
        outputs = self._rejudge(decision.rejudge)
        outputs.extend(self._drain())
        return outputs + self._close_run(self.detector.close_run())

    def _relaxation(self, k: int) -> tuple[float, float, float] | None:
        """Variance (N^2) the reactions may have relaxed by at window ``k`` since the current state began.

        ``settlement.relaxation``: the change ``A dx`` that opened the current segment (noted at its
        first window, ``_note_change``) times the creep coefficient at ``k``, within
        ``relaxation_horizon_s`` of the segment's first window; None otherwise.
        """
        rl = self._relax
        if rl is None or rl[0] != self.filter.starts[-1]:
            return None
        t = (k - rl[0] + 0.5) * self.config.window_s
        if t > self.config.relaxation_horizon_s:
            return None
        return relaxation_variance((rl[1], rl[2]), t, self.config.relaxation_phi0)

    def _note_change(self) -> None:
        """At a changed segment's first window, keep its change ``A dx`` (N) for ``_relaxation``."""
        f = self.filter
        if self.config.relaxation_phi0 <= 0 or f.current_windows != 1 or f.kinds[-1] not in _CHANGES:
            return
        d0, d1 = f.level_change()
        a = self._af
        self._relax = (f.starts[-1], a[0] * d0 + a[1] * d1, a[2] * d0 + a[3] * d1)

    def _apply(self, decision: Decision) -> list[WindowOutput]:
        """Mark held windows with the detector's verdict (outputs follow in ``_drain``)."""
        for w in decision.reject:
            w.action = "reject"
        for w in decision.moving:  # a ramp's windows: neither state (``ChangeDetector._ramp_split``)
            self._leave_out(w)
        for w in decision.accept_before:
            w.action = "accept"
        if decision.event:
            first = decision.event[0]
            first.action = "event"
            for w in decision.event[1:]:
                w.action = "accept"
            decision.event[-1].event_end = True
            self.events.append(
                {
                    "window": first.k,
                    "detected_window": self._last_judged,
                    "glr": decision.glr,
                    "step_n": np.asarray(decision.step_n, float),
                    "segment": -1,  # set when the segment opens (``_drain``)
                    "kind": "step",
                }
            )
        if decision.change:
            decision.change[0].action = "change"
            for w in decision.change[1:]:
                w.action = "accept"
        if decision.unconfirmed:
            self._note_run(decision)
        if decision.excursion:
            kind = "excursion"
            if decision.before_gap:
                kind = "before_gap"
            elif decision.at_end:
                kind = "at_end"
            elif decision.between_steps:
                kind = "between_steps"
            self._note_excursion(decision.excursion, decision.excursion_n, decision.excursion_cov_n2, kind)
        for w in decision.accept:
            w.action = "accept"
        return []

    def _note_run(self, decision: Decision) -> None:
        """Report a run used as data without a step (its windows are data).

        At ``event_max_pending``, or a drift at the end of the data or a gap (``Decision.drift``).
        A run that starts where the last reported one ended continues the same excursion (a wander
        that went on for hours reaches the forced decision again and again): one report, its
        window count grown, its size the latest, a drift only if every part of it was one.
        """
        run = decision.unconfirmed or []
        record = {
            "detected_window": self._last_judged,
            "until_window": run[-1].k,
            "glr": float(decision.glr),
            "drift": bool(decision.drift),
            "step_n": np.asarray(decision.step_n, float).tolist(),
            "step_cov_n2": np.asarray(decision.step_cov_n2, float).tolist(),
        }
        last = self.unconfirmed_runs[-1] if self.unconfirmed_runs else None
        if last is not None and run[0].k - last["until_window"] <= self.detector.confirm:
            drift = bool(last.get("drift", False) and record["drift"])  # a drift only if all of it is
            last.update(
                record, windows=last["windows"] + len(run), glr=max(last["glr"], record["glr"]), drift=drift
            )
        else:
            self.unconfirmed_runs.append({"window": run[0].k, "windows": len(run), **record})

    def _note_rejected(self, k: int, reason: str) -> None:
        """Note window ``k`` as rejected for ``reason`` (``recent_rejected``, ``rejected_runs``)."""
        self.recent_rejected.append((k, reason))
        runs = self.rejected_runs
        if runs and runs[-1][2] == reason and runs[-1][1] + 1 == k:
            runs[-1][1] = k
        else:
            runs.append([k, k, reason])

    def _drain(self) -> list[WindowOutput]:
        """Apply the decided windows at the head of the queue in order; return their outputs."""
        outputs = []
        q = self._queue
        while q and q[0].action is not None:
            w = q.popleft()
            action = w.action
            if action == "invalid":
                self._note_rejected(w.k, w.reason)
                outputs.append(self._output(w, np.full(2, np.nan), False, w.reason))
            elif action == "reject":
                self.counts["outlier"] += 1
                self._note_rejected(w.k, "outlier")
                outputs.append(self._output(w, np.full(2, np.nan), False, "outlier"))
            elif action == "warm":
                outputs.append(self._accept(w, add_rows=False))
            else:
                if action == "event":
                    self.filter.open_segment(w.k, self._drift_jump(w.k))
                    for e in reversed(self.events):
                        if e["window"] == w.k:
                            e["segment"] = self.filter.segment
                            break
                elif action == "change":
                    self.filter.open_segment(
                        w.k,
                        self._drift_jump(w.k),
                        kind="held_run",
                        change_prior=self.config.change_prior_probability,
                    )
                outputs.append(self._accept(w, event=action == "event"))
        return outputs

    def _accept(self, w: Window, add_rows: bool = True, event: bool = False) -> WindowOutput:
        """Use one window: settlement update, its row for the sums, refit on schedule.

        A scheduled refit runs after the window's output is made, before anything reads the state
        again (``settle``): the output leaves without waiting for it, and a node publishes it
        first and refits in its idle time; the sequence of operations, hence every number, is the
        same at any pace.
        """
        self.settle()
        g0, g1 = self._curve(w)
        if self.drifting and add_rows and not event and w.k >= self.filter.starts[-1] + self._block_k:
            # a random walk, piecewise constant: a new block opens the covariance by Q dt
            self.filter.open_segment(w.k, self._drift_jump(w.k), kind="drift")
        z = (float(w.force[0]) - self._u0f[0] - g0, float(w.force[1]) - self._u0f[1] - g1)
        if w.seg < 0 or w.seg == self.filter.segment:  # a warm-up window of an earlier segment is in the sums
            self.filter.accept(w.samples, z)
            self._note_change()
            if self.filter.provisional:
                self._settle_provisional(w.k)  # a confirmation is noted at once (merges at refits)
            else:
                self._confirm_previous(w.k)
        self._last_ok = w
        self._latest.append(w)
        if add_rows:
            self._rows.append(self._row(w, self.filter.segment))
            self._n_accepted += 1
            t0, t1 = float(w.temp[0]), float(w.temp[1])
            lo, hi = self._range
            out_of_range = t0 < lo[0] or t0 > hi[0] or t1 < lo[1] or t1 > hi[1]
            if w.event_end:
                self._refit()
            elif self._n_accepted >= self._refit_at or out_of_range:
                self._pending_refit = self._n_accepted >= self._lambda_at
        return self._output(w, w.force - np.array((g0, g1)), True, "", event)

    def settle(self) -> None:
        """Run the refit the last accepted window scheduled, if any (idempotent; see ``_accept``)."""
        if self._pending_refit is not None:
            reselect, self._pending_refit = self._pending_refit, None
            self._refit(reselect=reselect)

    def _finish_warmup(self) -> None:
        """Fit on the warm-up windows, then apply them in order (outputs from the warm fit).

        When the warm-up ends a few windows after a gap (a record the test car cut down to a few
        windows, then the next one hours later), those windows are held on as the first windows
        after a gap (``_release_fresh``) if at least ``MIN_DIFFERENCES + 1`` windows before the
        gap remain for the fit: searched with the few the warm-up's count left them, a step among
        them could not be seen.
        """
        f = self.filter
        if f.kinds[-1] == "gap":
            tail = [w for w in self._warm if w.seg == f.segment]
            keep = len(self._warm) - len(tail)
            if tail and keep > MIN_DIFFERENCES:
                self._warm = self._warm[:keep]
                for w in tail:
                    w.seg = -1  # judged later, in the segment current then
                self._fresh, self._fresh_open = tail, True
        self._split_warm_segment()
        warm, self._warm = self._warm, []
        self.warm = True
        for w in warm:
            if w.action == "invalid":  # a window a step happened in (``_split_warm_segment``)
                continue
            self._rows.append(self._row(w, max(w.seg, 0)))
            self._n_accepted += 1
        self._refit(reselect=True, online=False)
        self._refit(reselect=True, online=False)  # the slope prior, weighed with the noise just learned
        for w in warm:
            if w.action is None:
                w.action = "warm"
            if w.action == "warm":
                self._latest.append(w)
        if not self._young_done:
            self._young = list(warm)

    def _warm_run(self) -> list[Window]:
        """Return the current segment's warm-up windows not left out, in order."""
        seg = self.filter.segment
        return [w for w in self._warm if w.seg == seg and w.action != "invalid"]

    def _warm_steps(self, run: list[Window]) -> list[tuple[int, int | None]]:
        """``events.warmup.step_windows`` of warm-up windows ``run`` (one segment's, in order)."""
        return step_windows(
            np.array([w.force for w in run]).reshape(-1, 2),
            np.array([w.k for w in run], np.int64),
            self.detector.false_trigger,
            self.config.traffic_vehicle_max_n,
        )

    def _leave_out_lone_warm(self) -> None:
        """Leave out, as outliers, the warm-up windows alone beyond any vehicle that came back.

        The warm-up's windows were all data: a load of one window (80 kN over minute 6, a glitch)
        went into the first noise model, which then took a 6 mm lowering at minute 4.5 of the same
        record for noise (-3.8 mm for -6 at the end, no event, nothing said), and the step search
        reads such a window as an odd one, not as an outlier. The detector rejects one window
        alone that came back, and so do the young rules (``_take_back_lone``); the warm-up now
        does too, with the same test (``events.warmup.lone_windows_beyond_vehicle``, per segment
        of its windows, not those after a gap), before its step search. The warm-up's last window
        has no next one yet (``_last_warm_alone``).
        """
        # the windows after a gap inside the warm-up are the gap's (``_finish_warmup`` may hold
        # them on for ``_release_fresh``, which decides each of them itself)
        gap = self.filter.segment if self.filter.kinds[-1] == "gap" else None
        runs: dict[int, list[Window]] = {}
        for w in self._warm:
            if w.action != "invalid" and w.seg != gap:
                runs.setdefault(w.seg, []).append(w)
        vehicle = self.config.traffic_vehicle_max_n
        for run in runs.values():
            y = np.array([w.force for w in run]).reshape(-1, 2)
            for i in lone_windows_beyond_vehicle(y, vehicle):
                self._leave_out(run[i], "outlier")

    def _last_warm_alone(self) -> bool:
        """Take the warm-up's last window out of it when a step's new state would be that window alone.

        The warm-up's step search (``_split_warm_segment``) reads its windows at once; a load of
        one window at its end (80 kN for a minute, the tenth window of the data) was a step there,
        its window the first of a provisional state, and the next window's return an event of its
        own: a raise of 11 mm reported unconfirmed and a settlement event of -11 mm, on a record
        without any (60 kN: warm data, the estimate 0.7 mm off). One window alone is no state
        (``events.detector.SHORT_STATE_WINDOWS``): the window is judged after the warm-up instead,
        as a young state's window (the detector, ``_take_back_lone``), and the windows after it
        decide: an outlier that came back, or the first window of a new state.
        True if it was taken out (the caller judges it).
        """
        run = self._warm_run()
        if len(run) <= MIN_DIFFERENCES + 1:
            return False
        if not any(i == len(run) - 1 and mixed is None for i, mixed in self._warm_steps(run)):
            return False
        last = self._warm.pop()
        last.seg = -1  # judged after the warm-up, in the segment current then
        return True

    def _split_warm_segment(self) -> None:
        """Open a provisional segment where a step shows among the current segment's warm-up windows.

        ``events.warmup``: the windows are held before any noise model exists, and would be
        fitted as one state; a step among them (its scale from their own differences) starts a
        segment whose change the data after it decide, as after a gap. A window a step happened
        in holds both states and is left out, as after a gap (``_release_fresh``): fitted as the
        new state's first window, its part of the old level went into the noise model (the 10 mm
        record whole, then again 20 minutes on, raised 9.5 mm at its minute 1 and lowered at 5:
        the lowering went unseen and the stream ended 7.8 mm off). Also where a gap inside the
        warm-up closes the segment (``_open_gap``).
        """
        run = self._warm_run()
        for i, mixed in self._warm_steps(run):
            if mixed is not None:  # each side keeps a window: its neighbours are its states'
                self._leave_out(run[mixed])
                i = mixed + 1
            k = run[i].k
            self.filter.open_segment(
                k, self._drift_jump(k), kind="warmup", change_prior=self.config.change_prior_probability
            )
            for w in run[i:]:
                w.seg = self.filter.segment

    def _flush_rows(self) -> None:
        """Move the accepted windows' rows into the sums."""
        if not self._rows:
            return
        rows, self._rows = self._rows, []
        self.sums.add(_rows_of(rows))

    def _refit(self, reselect: bool = False, online: bool = True) -> None:
        """Refit the curve (``lambda`` too if ``reselect``), the noise model and the settlement.

        Provisional segments the data have decided are then confirmed (an event) or merged into the
        segment before them (no change), and the fit is repeated after a merge.
        """
        self._flush_rows()
        cfg = self.config
        detected = self._last_judged if self._last_judged >= 0 else (self._last_usable_k or 0)
        passes = 0
        while True:
            lam = None if reselect or not np.all(np.isfinite(self.lam)) else self.lam
            per_sample = np.diag(self.noise.r1)
            kappa = self.compensation.slope_weight(per_sample)
            long_run = np.diag(self.noise.long_run_cov()) / np.maximum(per_sample, 1e-300)
            fit = self.compensation.fit(self.sums, lam, kappa, long_run)
            self.fit = fit
            self._fit_id += 1
            self._set_range(fit)
            if lam is None:
                self.lam = fit.lam
                self._lambda_at = max(
                    int(self.sums.n * cfg.lambda_reselect_growth), self.sums.n + cfg.refit_windows
                )
            moments = residual_moments(self.sums, fit.beta, fit.level)
            self.noise.update(moments, fit.edf, self.sums.ns)
            passes += 1
            moved = np.diag(self.noise.r1) / np.maximum(per_sample, 1e-300)
            if passes < _NOISE_PASSES and np.any(
                (moved > _NOISE_CONSISTENT) | (moved < 1 / _NOISE_CONSISTENT)
            ):
                continue  # the priors were weighed on another noise: fit again with this one
            self.filter.refresh(self.sums, fit, self.noise)
            if not self._settle_provisional(detected, merge=True):
                break  # else one level fewer: fit again (the noise settling again with it)
            passes = 0
        if not online:
            self.filter.restart_current()
        self.detector.set_noise(self.noise.phi, float(np.min(self.noise.dof)))
        last = self._last_ok
        if last is not None:  # the jump test's reference window, against the new curve and estimate
            self.detector.rebase(last.k, self._innovation(last))
        # on a schedule that thins out as the record grows: a refit every refit_windows windows,
        # or every 5 % of the windows already fitted (the curve and the noise settle)
        self._refit_at = self.sums.n + max(cfg.refit_windows, self.sums.n // 20)

    def _set_range(self, fit: CompensationFit) -> None:
        """Set the temperatures beyond which a window brings a refit (the fitted range plus a margin)."""
        self._range = (
            (float(fit.t_lo[0]) - _RANGE_MARGIN_K, float(fit.t_lo[1]) - _RANGE_MARGIN_K),
            (float(fit.t_hi[0]) + _RANGE_MARGIN_K, float(fit.t_hi[1]) + _RANGE_MARGIN_K),
        )

    def _output(
        self, w: Window, compensated: np.ndarray, updated: bool, reason: str, event: bool = False
    ) -> WindowOutput:
        x, P = self.filter.posterior()
        last = self._last_usable_k
        if last is not None and self.filter.starts and w.k - last - 1 >= self._gap_k:
            # a window after a gap, out before the gap's segment opened (the test car's, rejected,
            # at a record's start): the supports may have moved, as ``posterior`` says while the
            # record is held; it carried the state before the gap with its own narrow interval,
            # a stale value in the burst a record's end publishes
            P = self._gap_open(P)
        return WindowOutput(
            w.k,
            (w.k + 1) * self._w_ns,
            w.samples,
            w.temp,
            w.force,
            compensated,
            x,
            self._published_cov(x, P),
            updated,
            reason,
            event,
        )

    # -- reporting ----------------------------------------------------------------------------
    @property
    def posterior(self) -> tuple[np.ndarray, np.ndarray]:
        """Posterior mean (2,) m and published covariance (2, 2) m^2 (+ systematic + model terms).

        While the record after a gap is held for the traffic screen (``pending_gap_ns``) the
        supports may have moved in the gap and no window has said yet: the covariance is the gap's
        two outcomes before data, ``P + pi J`` (``segments.mixture_update`` without a
        measurement). Until the record ended the old state was published with its own narrow
        interval, which excluded the new state for the whole record (-9.4 ± 4.0 mm through the
        -20 mm record of a load-test day, found by a helper session reading every output).
        """
        self.settle()
        x, P = self.filter.posterior()
        if self.pending_gap_ns() is not None:
            P = self._gap_open(P)
        return x, self._published_cov(x, P)

    def _gap_open(self, P: np.ndarray) -> np.ndarray:
        """``P + pi J``: the covariance after a gap no window has measured (both outcomes, before data)."""
        return P + self.config.change_prior_probability * self.filter.jump_cov

    def pending_gap_ns(self) -> int | None:
        """First stamp of a record held for the traffic screen that began after a gap (None: none).

        Its windows are judged when it ends; a gap before it (``gap_s`` without a usable window)
        is when the supports may have moved.
        """
        held = self.buffer.held_since_ns
        last = self._last_usable_k
        if held is None or last is None or not self.filter.starts:
            return None
        return held if held // self._w_ns - last - 1 >= self._gap_k else None

    def _published_cov(self, x: np.ndarray, P: np.ndarray) -> np.ndarray:
        """Filter covariance + ``A^-1 diag(systematic^2) A^-T`` + the surrogate's model covariance at x."""
        cov = P + self._systematic
        if self._model_cov is not None:
            c00, c01, c11 = self._model_cov(float(x[0]), float(x[1]))
            cov = cov + np.array([[c00, c01], [c01, c11]])
        return cov

    @property
    def rejected(self) -> dict[str, int]:
        """Rejections by reason (every reason listed, zeros included)."""
        return {r: int(self.counts.get(r, 0)) for r in REASONS}

    def event_records(self) -> list[EventRecord]:
        """Return the detected events with their size and covariance as the data now say."""
        self.settle()
        return report.event_records(self)

    def unconfirmed_changes(self) -> list[ChangeRecord]:
        """Return the possible changes not confirmed (gaps, held runs) with their probability and size."""
        self.settle()
        return report.unconfirmed_changes(self)

    def warnings(self) -> list[str]:
        """Return what a user must hear about (one line each): silent failures made loud."""
        self.settle()
        return report.warnings(self)

    def spline_info(self) -> dict[str, dict[str, float]]:
        """Return, per channel, the curve's edf, lambda, level, windows and temperature range."""
        self.settle()
        return report.spline_info(self)

    def noise_info(self) -> dict[str, Any]:
        """Return the noise model: mode, phi per channel, per-sample sigma (N), windows behind it."""
        self.settle()
        return report.noise_info(self)

    def prior_info(self) -> dict[str, Any]:
        """Return the prior in use: sigma per support (m), its source, and an event's opening (m)."""
        return report.prior_info(self)

    def diagnostics(self, now_ns: int | None = None) -> dict[str, Any]:
        """Return health and key values (SI): level OK/WARN/ERROR, message, posterior, counts, events."""
        self.settle()
        return report.diagnostics(self, now_ns)

    # -- state ----------------------------------------------------------------------------
    def state_dict(self) -> dict[str, Any]:
        """Return the whole online state as nested plain data (arrays, numbers, strings)."""
        self.settle()
        return shadow_state(self)

    @classmethod
    def from_state_dict(
        cls, state: dict[str, Any], config: ShadowConfig | None = None, surrogate: Surrogate | None = None
    ) -> Shadow:
        """Rebuild a shadow from ``state_dict`` (config and surrogate default to the saved ones)."""
        return restore_shadow(cls, state, config, surrogate)

    def checkpoint_state(self, held_air: TemperatureSeries | None = None) -> dict[str, Any]:
        """Return ``state_dict()`` with ``held_air`` as the air it holds unfed (None or empty: none).

        What a chain's checkpoint holds after a bag's last force (``replay.air_tail``), taken before
        the held air is fed for the bag's own result and written once the run is complete.
        """
        before, self.held_air = self.held_air, held_air if held_air is not None and len(held_air) else None
        try:
            return self.state_dict()
        finally:
            self.held_air = before

    def save_checkpoint(
        self,
        path: str | Path | None = None,
        state: dict[str, Any] | None = None,
        held_air: TemperatureSeries | None = None,
    ) -> Path | None:
        """Write the state atomically to ``path`` (default ``checkpoint_path``); None if disabled.

        ``state``: a ``state_dict`` taken earlier (the state before an end-of-data close), else now.
        ``held_air``: air messages not fed, written as the checkpoint's ``held_air`` (the air past a
        bag's last force, ``replay.air_tail``; empty: none).
        """
        target = path if path is not None else self.config.checkpoint_path
        if not target:
            return None
        if held_air is not None and state is None:
            state = self.checkpoint_state(held_air)
        self._ckpt_ns = self.clock_ns
        written = save_state(self.state_dict() if state is None else state, target)
        self.checkpoint_failure = None
        return written

    @classmethod
    def resume(
        cls, path: str | Path, config: ShadowConfig | None = None, surrogate: Surrogate | None = None
    ) -> Shadow:
        """Rebuild a shadow from a checkpoint file written by ``save_checkpoint``."""
        return restore(path, config, surrogate, cls.from_state_dict)  # refuses unusable/incompatible files

    def _maybe_checkpoint(self) -> None:
        if not self.config.checkpoint_path or self.clock_ns is None or self.checkpoints_paused:
            return
        if self._ckpt_ns is None:
            self._ckpt_ns = self.clock_ns
        elif self.clock_ns - self._ckpt_ns >= self.config.checkpoint_period_s * _NS:
            # a write that fails (a full disk, a mount gone read-only) must not stop the monitoring:
            # the windows go on, the failure is a warning (JSON, /diagnostics, the node's log) and
            # the write is tried again a period later (save_checkpoint moved the clock of the last try)
            try:
                self.save_checkpoint()
            except CheckpointError as err:
                self.checkpoint_failure = (int(self.clock_ns), str(err))

    # -- offline ----------------------------------------------------------------------------
    def result(self, outputs: list[WindowOutput], messages: int, seconds: float) -> ReplayResult:
        """Return the replay result of what this shadow has seen."""
        self.settle()
        return report.replay_result(self, outputs, messages, seconds)

    def run(
        self,
        data: MonitoringData,
        chunk: int = 200_000,
        progress: Callable[[float], None] | None = None,
        flush: bool = True,
    ) -> ReplayResult:
        """Feed ``data`` in arrival (log time) order, ``chunk`` messages per call; return the result.

        As ``replay.replay_bag``: air a resumed checkpoint holds (``held_air``) is merged in by log
        time, and with ``checkpoint_path`` the checkpoint is written before the air past the data's
        last force and holds it (``replay.air_tail``).
        """
        t0 = time.perf_counter()
        held = self.held_air
        if held is not None:  # merged by log time, the held air first at equal times
            air = TemperatureSeries.concat([held, data.temperature])
            data = MonitoringData(data.forces, air.take(np.argsort(air.log_ns, kind="stable")))
        series = [data.forces[ch] for ch in CHANNELS]
        temp = data.temperature
        logs = [s.log_ns for s in series] + [temp.log_ns]
        sizes = [len(x) for x in logs]
        total = sum(sizes)
        topic = np.concatenate([np.full(n, i, dtype=np.int8) for i, n in enumerate(sizes)])
        pos = np.concatenate([np.arange(n) for n in sizes])
        all_logs = np.concatenate(logs)
        order = np.argsort(all_logs, kind="stable")
        topic, pos = topic[order], pos[order]
        outputs: list[WindowOutput] = []
        chunk = max(int(chunk), 1)
        # arrival positions [0, head) go first; [head, total) is the air past the last force (all
        # of it without forces, as ``AirTail``), held in the checkpoint
        holding = flush and bool(self.config.checkpoint_path)
        head = total
        if holding:
            forces_at = np.flatnonzero(topic < 2)
            head = int(forces_at[-1]) + 1 if len(forces_at) else 0
        for start in [*range(0, head, chunk), *range(head, total, chunk)]:
            stop = min(start + chunk, head if start < head else total)
            if start == head:
                self.save_checkpoint(held_air=temp.take(pos[head:total]))
                self.checkpoints_paused = True  # this result goes on to the air's end
            t_chunk, p_chunk = topic[start:stop], pos[start:stop]
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
            if held is not None and start < head:
                # a periodic checkpoint written in this poll keeps the held air still to come (one
                # at this chunk's last log time may be fed: it comes again as a duplicate)
                rest = held.take(held.log_ns >= all_logs[order[stop - 1]])  # type: ignore[operator]
                self.held_air = rest if len(rest) else None
            outputs.extend(self.poll())
            if progress is not None:
                progress(stop / max(total, 1))
        self.held_air = None
        if flush:
            # the state before the end-of-data close: a run resumed from it goes on with the
            # records still open, as one run over both would (``replay.bag.replay_bag``)
            if holding and head == total:
                self.save_checkpoint()
            self.checkpoints_paused = False
            outputs.extend(self.flush())
        return self.result(outputs, total, time.perf_counter() - t0)
