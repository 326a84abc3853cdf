"""``bridge_shadow_node``: the live shadow, a thin rclpy shell over ``bridge_shadow.estimate.Shadow``.

Wiring (types from ``bridge_shadow.contract``; topic names are the ``topic_*`` parameters, whose
defaults are the contract's)::

    /bridge/frc_01/force, /bridge/frc_02/force   WrenchStamped  --raw CDR-->  buffer per topic
    /bridge/air_temperature                      Temperature    --raw CDR-->  buffer per topic
    buffers --(vectorized decode)--> Shadow.ingest_* --> Shadow.poll() --> per closed window:
        /bridge_shadow/settlement/mean        Float64MultiArray [south, north] m, dim ``support``
        /bridge_shadow/settlement/covariance  Float64MultiArray 2x2 m^2, dims ``row``, ``col``
        /bridge_shadow/compensated/frc_0{1,2} WrenchStamped, stamp = window end, N
    (mean and covariance RELIABLE and TRANSIENT_LOCAL: a late subscriber asking for it gets the last)
    timer (diagnostics_period_s) --> /diagnostics  DiagnosticArray (settlement, inputs, compensation)
    service /bridge_shadow/flush (std_srvs/Trigger): end of a replay, close every window holding
        data, publish it and answer with the diagnostics as JSON (what the offline replay's
        ``flush`` does; ``bridge-shadow replay --live`` calls it after the last message).
    service /bridge_shadow/status (std_srvs/Trigger): raw messages taken per input topic and the
        posteriors published so far, as JSON (the live replay's flow control, and what its VOLATILE
        readers missed).
    service /bridge_shadow/history (std_srvs/Trigger): the last ``HISTORY_WINDOWS`` window outputs
        as JSON (SI units): what a late-joining viewer, or ``replay --live --plots``, draws.
    service /bridge_shadow/checkpoint (std_srvs/Trigger): ingest what was taken, close the windows
        that are due and write the checkpoint now, no window held closed early (a save before
        maintenance; ``replay --live --checkpoint`` calls it after a bag's last force).

Subscriptions take raw CDR (no Python message object per sample) and the buffers are decoded in
blocks: when one holds ``BATCH`` messages, when a message brings the last topic past the end of
the open window (so a window's outputs leave within a millisecond of the message that closes it),
and every ``DRAIN_PERIOD_S``. The shadow's result does not depend on that chunking, but its missing-topic
timeout reads the data clock (the newest stamp of any topic), so topics must be ingested in step:
DDS keeps the order within a topic, not across topics, and in a fast replay a few milliseconds of
transport skew are hours of stamp time. A decoded message therefore waits until every other topic
has delivered a stamp at least as new (or that topic has been quiet, or the message has waited,
for ``REORDER_HOLD_S``). Live, the window-closing message never waits: the others are past it.

Quiet inputs (wall clock): windows close on stamp time, so when every input stops the window holding
the last data would wait for the next message. Once no input has arrived for
``max(topic_timeout_s, window_s)`` of wall time (what /diagnostics reports as an ERROR), the node closes
the windows holding data as the replay's end does (``Shadow.flush``) and publishes them. That close
is provisional: the node keeps the shadow's state from before it, and when the inputs come back
with stamps less than ``gap_s`` after the last ones (a logger that paused inside a record:
the offline replay goes on with the same record there), it goes back to that state, says so in
the log, publishes the posterior it holds and goes on as the offline replay of the whole stream
does; the outputs of the undone close leave the history. Data from ``gap_s`` on is a new record
and the close stands. A checkpoint written on exit before any data has decided holds the state
from before the close (a resumed node whose inputs stay quiet closes the held windows again).
A message for a closed window that arrives later still is counted ``late``.

Checkpoint: with ``checkpoint_path`` set, the node resumes from that file when it exists, the shadow
saves it every ``checkpoint_period_s`` of stamp time, and the node saves it on SIGINT/SIGTERM
after ingesting what it has buffered. A file that cannot be read, or was saved under parameters
that shape the state differently (``estimate.state.checkpoint``), stops the node with one line naming
it (``checkpoint_unusable: fresh`` sets it aside and starts from the prior); it is never
overwritten. At start the node logs the surrogate, the parameter files, the topics and the
checkpoint it uses.

Parameter declarations: ``ros.parameters``; the command line (``bridge_shadow_node``): ``ros.main``.
"""

from __future__ import annotations

import dataclasses
import json
import re
import struct
import time
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Temperature
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from bridge_shadow.contract import (
    CHANNELS,
    COMPENSATED_TOPICS,
    COVARIANCE_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE_FRAMES,
    MEAN_TOPIC,
    NODE_NAME,
)
from bridge_shadow.errors import BridgeShadowError
from bridge_shadow.estimate import Shadow, ShadowConfig, WindowOutput
from bridge_shadow.estimate.parameters.specs import SPECS
from bridge_shadow.estimate.report import rejected_list
from bridge_shadow.estimate.startup import open_shadow
from bridge_shadow.estimate.state.checkpoint import CheckpointError
from bridge_shadow.jsonvalues import jsonable
from bridge_shadow.model.surrogate_file import describe_surrogate, load_surrogate
from bridge_shadow.paths import config_file
from bridge_shadow.ros import convert
from bridge_shadow.ros.diagnostics import diagnostic_array, event_text, statuses
from bridge_shadow.ros.parameters import declare_parameters, is_ros_own, plain_value

__all__ = [
    "BATCH",
    "CHECKPOINT_SERVICE",
    "DRAIN_PERIOD_S",
    "FLUSH_SERVICE",
    "HISTORY_SERVICE",
    "HISTORY_WINDOWS",
    "MIN_DRAIN_GAP_S",
    "REORDER_HOLD_S",
    "STATUS_SERVICE",
    "ShadowNode",
    "input_qos",
    "outputs_from_history",
    "startup_lines",
    "window_history",
]

# The services' names are relative: ``/bridge_shadow/flush`` for a node in the root namespace (and
# for a client there), ``/NS/bridge_shadow/flush`` for a node started in namespace NS (a fleet:
# ``bridge_shadow.ros.fleet``), so the nodes of a fleet do not answer for each other.
#: Service that closes every window holding data (end of a replay).
FLUSH_SERVICE = f"{NODE_NAME}/flush"
#: Service answering with the raw messages taken per input topic (flow control of a replay).
STATUS_SERVICE = f"{NODE_NAME}/status"
#: Service answering with the recent window outputs (``window_history``) as JSON.
HISTORY_SERVICE = f"{NODE_NAME}/history"
#: Service that writes the checkpoint now, closing only the windows that are due.
CHECKPOINT_SERVICE = f"{NODE_NAME}/checkpoint"
#: Window outputs the node keeps for the history service: one week of 60 s windows (about 1 MB).
HISTORY_WINDOWS = 10_080
#: Buffered messages per topic that trigger a decode-and-ingest.
BATCH = 1024
#: Period of the timer that ingests whatever is buffered [s].
DRAIN_PERIOD_S = 0.05
#: A message that brings the last topic past the open window's end triggers a drain; while that
#: window stays open (held by the traffic screen), later such messages drain at most this often [s]
#: (live, windows end minutes apart; in a fast replay the batch and timer take over).
MIN_DRAIN_GAP_S = 0.002
#: Longest wall time a message waits for the other topics to catch up with its stamp [s].
REORDER_HOLD_S = 5.0
_NS = 1_000_000_000


def input_qos(depth: int) -> QoSProfile:
    """RELIABLE QoS of the given history depth; ``depth <= 0`` means KEEP_ALL (lossless)."""
    reliable = ReliabilityPolicy.RELIABLE
    if depth <= 0:
        return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=reliable)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliable)


def posterior_qos(depth: int) -> QoSProfile:
    """QoS of the posterior's topics: RELIABLE, and TRANSIENT_LOCAL with a bounded history.

    A subscriber that asks for TRANSIENT_LOCAL durability (a dashboard started after the node, or
    after a quiet-input close on a load-test day, when the next posterior may be hours away) is
    sent the last ``depth`` posteriors at once, as a latched ``/map`` or ``/tf_static`` is; a
    VOLATILE subscriber matches as before and gets only the new ones (Fast DDS was seen to hand
    the history to a best-effort VOLATILE reader in a process that also holds a TRANSIENT_LOCAL
    reader of the topic; a reliable VOLATILE one never). ``depth <= 0`` (KEEP_ALL)
    stays VOLATILE: a durable KEEP_ALL writer would keep every posterior for ever.
    """
    if depth <= 0:
        return input_qos(depth)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


class ShadowNode(Node):
    """Wires the contract topics, a diagnostics timer and the flush service to one ``Shadow``.

    Attributes:
        config: the parameters in force (``ShadowConfig``).
        shadow: the pipeline (fresh, or resumed from ``checkpoint_path``).
        received: raw messages taken per input topic key.
        malformed: raw messages that could not be decoded (dropped).
        windows_published: window outputs published so far.
        posteriors_published: posterior (mean, covariance) pairs published so far: one per window,
            and one more at a flush whose final refit moved the posterior after the last window.

    """

    def __init__(self, params_files: Sequence[str] = (), **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.config = self._read_parameters()
        self._next_config: ShadowConfig | None = None
        cfg = self.config
        surrogate = load_surrogate(cfg.surrogate_path or None)
        self._surrogate = surrogate
        self.shadow, notes = open_shadow(cfg, surrogate)
        held = self.shadow.held_air
        if held is not None:
            # a replay's checkpoint holds the air past its bag's last force unfed (``replay.air_tail``):
            # live data come after it, so it goes in first
            self.shadow.held_air = None
            self.shadow.ingest_temperature(held.stamp_ns, held.temp_c, held.frame_id)
            notes.append(
                f"resumed with the {len(held)} air readings the checkpoint held unfed: ingested first"
            )
        log = self.get_logger()
        for line in startup_lines(cfg, surrogate, params_files):
            log.info(line)
        for line in notes:
            log.info(line) if line.startswith(("resumed", "checkpoint")) else log.warning(line)
        self.received = [0, 0, 0]
        self.malformed = 0
        self.windows_published = 0
        self.posteriors_published = 0
        self._last_posterior: tuple[np.ndarray, np.ndarray] | None = None
        self.quiet_flushes = 0
        self.quiet_flushes_undone = 0
        self._pending_gap_said: int | None = None  # the held record after a gap last published for
        # before the last quiet-input close: the state, its data clock, the outputs published so far
        self._before_quiet: tuple[dict[str, Any], int, int] | None = None
        self._warned: set[str] = set()
        self.history: deque[Any] = deque(maxlen=HISTORY_WINDOWS)
        self._raw: list[list[bytes]] = [[], [], []]
        self._arrival: list[float | None] = [None, None, None]
        self._latest: list[int | None] = [None, None, None]
        self._last_drain = 0.0
        self._tried_end = -(2**62)  # the window end a closing message last drained for
        self._started: float | None = None  # wall time of the first message (monotonic)
        self._born = time.monotonic()  # the quiet limit's reference before any message
        self._peek = [-(2**62)] * 3  # stamp of the last raw message per topic (undecoded)
        self._pending: list[tuple[np.ndarray, ...] | None] = [None, None, None]
        self._next_end_ns = self._window_end()
        self._timeout_s = max(cfg.topic_timeout_s, cfg.window_s)
        in_qos = input_qos(cfg.qos_depth)
        out_depth = cfg.qos_depth if cfg.qos_depth <= 0 else max(cfg.qos_depth, 100)
        out_qos = input_qos(out_depth)
        latched = posterior_qos(out_depth)
        types = (WrenchStamped, WrenchStamped, Temperature)
        self._subs = [
            self.create_subscription(t, topic, self._callback(i), in_qos, raw=True)
            for i, (t, topic) in enumerate(zip(types, cfg.input_topics(), strict=True))
        ]
        outs = cfg.output_topics()
        self._pub_mean = self.create_publisher(Float64MultiArray, outs[MEAN_TOPIC], latched)
        self._pub_cov = self.create_publisher(Float64MultiArray, outs[COVARIANCE_TOPIC], latched)
        self._pub_comp = [
            self.create_publisher(WrenchStamped, outs[COMPENSATED_TOPICS[ch]], out_qos) for ch in CHANNELS
        ]
        self._pub_diag = self.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 10)
        self._drain_timer = self.create_timer(DRAIN_PERIOD_S, self._on_drain_timer)
        self._diag_timer = self.create_timer(cfg.diagnostics_period_s, self.publish_diagnostics)
        self._flush_srv = self.create_service(Trigger, FLUSH_SERVICE, self._on_flush)
        self._status_srv = self.create_service(Trigger, STATUS_SERVICE, self._on_status)
        self._history_srv = self.create_service(Trigger, HISTORY_SERVICE, self._on_history)
        self._checkpoint_srv = self.create_service(Trigger, CHECKPOINT_SERVICE, self._on_checkpoint)

    # -- parameters ------------------------------------------------------------------------
    def _read_parameters(self) -> ShadowConfig:
        """Declare the parameters (``ros.parameters.declare_parameters``) and watch their changes."""
        config = declare_parameters(self)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        return config

    def _on_set_parameters(self, params: list[Any]) -> SetParametersResult:
        """Refuse a new value that breaks its spec, with the reason (read-only ones rclpy refuses)."""
        # use_sim_time and the like are rclpy's own
        changes = {p.name: plain_value(p.value) for p in params if not is_ros_own(p.name)}
        if not changes:
            return SetParametersResult(successful=True)
        frozen = [n for n in changes if n not in SPECS or not SPECS[n].live]
        if frozen:
            return SetParametersResult(
                successful=False,
                reason=f"{', '.join(frozen)}: read-only while the node runs (restart it with the new value)",
            )
        try:
            self._next_config = self.config.replace(**changes)
        except (BridgeShadowError, TypeError) as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, params: list[Any]) -> None:
        """Apply the accepted values (only ``diagnostics_period_s`` changes at run time)."""
        new = getattr(self, "_next_config", None)
        if new is None:
            return
        self._next_config = None
        if new.diagnostics_period_s != self.config.diagnostics_period_s:
            self.destroy_timer(self._diag_timer)
            self._diag_timer = self.create_timer(new.diagnostics_period_s, self.publish_diagnostics)
        self.config = new

    # -- input -----------------------------------------------------------------------------
    def _callback(self, i: int) -> Any:
        """Subscription callback of topic ``i``: buffer raw bytes, ingest on batch or window end."""
        buf = self._raw[i]
        append = buf.append
        unpack = struct.Struct("<iI").unpack_from
        clock = time.monotonic

        peek = self._peek

        def callback(raw: bytes) -> None:
            append(raw)
            if len(buf) >= BATCH:
                self.drain()
            elif len(raw) >= 12:
                sec, nsec = unpack(raw, 4)
                stamp = peek[i] = sec * _NS + nsec
                # every topic past the open window's end: this message may close it
                end = self._next_end_ns
                if stamp >= end and min(peek) >= end:
                    # the first message that may close this window drains at once (whatever ran
                    # just before: a timer's drain had not seen it); later ones for the same end
                    # (a window the screen holds) at most every MIN_DRAIN_GAP_S
                    if end != self._tried_end or clock() - self._last_drain >= MIN_DRAIN_GAP_S:
                        self._tried_end = end
                        self.drain()

        return callback

    def _window_end(self) -> int:
        k = self.shadow.next_k
        return -(2**62) if k is None else (k + 1) * round(self.config.window_s * _NS)

    def _decode_buffers(self, now: float) -> None:
        """Move raw buffers into the decoded pending arrays (arrival order per topic)."""
        for i, buf in enumerate(self._raw):
            if not buf:
                continue
            raws = buf[:]
            buf.clear()
            self.received[i] += len(raws)
            self._arrival[i] = now
            if self._started is None:
                self._started = now
            decode = convert.decode_forces if i < 2 else convert.decode_temperatures
            stamp, value, frame, bad = decode(raws)
            self.malformed += bad
            if not len(stamp):
                continue
            top = int(stamp.max())
            self._latest[i] = top if self._latest[i] is None else max(self._latest[i], top)
            old = self._pending[i]
            new = (stamp, value, frame, np.full(len(stamp), now))
            self._pending[i] = (
                new if old is None else tuple(np.concatenate(x) for x in zip(old, new, strict=True))
            )

    def _releasable(self, i: int, now: float) -> int:
        """Messages at the head of topic ``i``'s pending arrays that may be ingested now.

        A message waits while its stamp is ahead of the newest stamp some other topic has
        delivered (that topic may still be in flight: DDS keeps order within a topic, not across
        topics), or while some topic has delivered nothing yet, unless that topic is quiet (or
        absent) for ``REORDER_HOLD_S`` or the message has waited that long. A stamp more than
        ``clock_jump_s`` ahead does not wait (a clock glitch, for the gate).
        """
        stamp, _, _, t_dec = self._pending[i]
        horizon = None
        for j in range(3):
            if j == i:
                continue
            if self._latest[j] is None:
                if now - self._started < REORDER_HOLD_S:  # topic j may be about to deliver its first
                    return int(np.searchsorted(t_dec, now - REORDER_HOLD_S, side="right"))
                continue
            if now - self._arrival[j] < REORDER_HOLD_S:
                horizon = self._latest[j] if horizon is None else min(horizon, self._latest[j])
        # every message in step (the usual drain): all of them, whatever has waited how long
        if horizon is None or int(stamp.max()) <= horizon:
            return len(stamp)
        # a stamp more than clock_jump_s ahead of the others is no transport skew but a clock
        # glitch (or a new time base): it goes on to the gate, which rejects it (or confirms the
        # new base) as the direct replay's does; held, it held its topic back for REORDER_HOLD_S
        # while the others closed its windows, and the messages after it came late
        wild = stamp > horizon + round(self.config.clock_jump_s * _NS)
        ahead = np.flatnonzero((stamp > horizon) & ~wild)
        if not len(ahead):
            return len(stamp)
        n_aged = int(np.searchsorted(t_dec, now - REORDER_HOLD_S, side="right"))
        return max(int(ahead[0]), n_aged)

    def ingest_pending(self, everything: bool = False) -> None:
        """Decode the buffers and ingest what is in step across topics (all with ``everything``).

        No window is closed here (``drain`` polls).
        """
        now = time.monotonic()
        self._decode_buffers(now)
        if self._before_quiet is not None and any(p is not None and len(p[0]) for p in self._pending):
            self._resume_or_confirm_quiet_close()
        for i in range(3):
            if self._pending[i] is None:
                continue
            n = len(self._pending[i][0]) if everything else self._releasable(i, now)
            if n == 0:
                continue
            stamp, value, frame, t_dec = self._pending[i]
            if i < 2:
                self.shadow.ingest_forces(i, stamp[:n], value[:n], frame[:n])
            else:
                self.shadow.ingest_temperature(stamp[:n], value[:n], frame[:n])
            rest = (stamp[n:], value[n:], frame[n:], t_dec[n:])
            self._pending[i] = rest if len(rest[0]) else None

    def drain(self, everything: bool = False) -> None:
        """Ingest the buffers, close due windows and publish their outputs."""
        self._last_drain = time.monotonic()
        self.ingest_pending(everything)
        self._publish(self.shadow.poll())
        pending = self.shadow.pending_gap_ns()
        if pending is not None and pending != self._pending_gap_said:
            # a record after a gap is held for the traffic screen: the state may have moved in the
            # gap, so the posterior's interval widens now, not when the record ends
            self._pending_gap_said = pending
            self._publish_posterior(*self.shadow.posterior)
        self.shadow.settle()  # a scheduled refit, after the posterior is out (Shadow._accept)
        self._next_end_ns = self._window_end()

    def _on_drain_timer(self) -> None:
        """Ingest what is buffered; close the open windows when every input has been quiet too long."""
        self.drain()
        arrivals = [t for t in self._arrival if t is not None]
        # no message yet: a shadow resumed holding a record's windows closes them as quiet too
        if time.monotonic() - max(arrivals, default=self._born) <= self._timeout_s:
            return
        if any(p is not None for p in self._pending) or self.shadow.holds_data:
            n = self.close_open_windows(provisional=True)
            self.quiet_flushes += 1
            self.get_logger().warning(
                f"no input for {self._timeout_s:g} s: decided the {n} window(s) still held (the open "
                "one and any the record's screen or a warm-up held, hours back on a load-test day) "
                f"(undone if the inputs come back within gap_s = {self.config.gap_s:g} s of the data)"
            )

    def _resume_or_confirm_quiet_close(self) -> None:
        """Undo the last quiet-input close if the new data go on with its record, else keep it."""
        assert self._before_quiet is not None
        state, last_ns, published = self._before_quiet
        self._before_quiet = None
        first = min(int(p[0].min()) for p in self._pending if p is not None and len(p[0]))
        if first - last_ns >= round(self.config.gap_s * _NS):
            return  # a new record: the close stands
        self.shadow = Shadow.from_state_dict(state, self.config, self._surrogate)
        undone = self.windows_published - published
        for _ in range(min(undone, len(self.history))):
            self.history.pop()
        self.quiet_flushes_undone += 1
        self._publish_posterior(*self.shadow.posterior)
        self._next_end_ns = self._window_end()
        self.get_logger().info(
            f"inputs back {(first - last_ns) / _NS:.0f} s of data after the last, within gap_s: the "
            f"quiet-input close is undone ({undone} window output(s) provisional), the record goes on"
        )

    def close_open_windows(self, provisional: bool = False) -> int:
        """Ingest everything buffered, close every window holding data, publish; return how many.

        ``provisional`` (the quiet-input close): keep the state from before the close, to go back
        to when the data goes on within ``gap_s`` (``_resume_or_confirm_quiet_close``).
        """
        self.drain(everything=True)
        clock = self.shadow.clock_ns
        if not provisional or clock is None:
            self._before_quiet = None
        elif self._before_quiet is None:  # an earlier provisional close no data has decided stays
            self._before_quiet = (self.shadow.state_dict(), clock, self.windows_published)
        outputs = self.shadow.flush()
        self._publish(outputs)
        # the flush's refit (lambda reselected) lands on its last output; when every window had
        # closed before, no output carries it, so the final posterior goes out on its own
        final = self.shadow.posterior
        if self._last_posterior is not None and not all(
            np.array_equal(a, b) for a, b in zip(final, self._last_posterior, strict=True)
        ):
            self._publish_posterior(*final)
        self._next_end_ns = self._window_end()
        return len(outputs)

    # -- output ----------------------------------------------------------------------------
    def _publish(self, outputs: list[Any]) -> None:
        for out in outputs:
            self._publish_posterior(out.mean_m, out.covariance_m2)
            if np.all(np.isfinite(out.compensated_n)):
                for c, ch in enumerate(CHANNELS):
                    self._pub_comp[c].publish(
                        convert.wrench_raw(out.end_ns, FORCE_FRAMES[ch], out.compensated_n[c])
                    )
            self.windows_published += 1
            self.history.append(out)

    def _publish_posterior(self, mean_m: np.ndarray, covariance_m2: np.ndarray) -> None:
        self._pub_mean.publish(convert.mean_raw(mean_m))
        self._pub_cov.publish(convert.covariance_raw(covariance_m2))
        self._last_posterior = (np.array(mean_m, float), np.array(covariance_m2, float))
        self.posteriors_published += 1

    def report(self) -> dict[str, Any]:
        """``Shadow.diagnostics()`` plus the node's counters (SI units, plain data)."""
        diag = self.shadow.diagnostics()
        keys = list(diag["used"])
        diag["node"] = {
            "received": dict(zip(keys, self.received, strict=True)),
            "malformed": self.malformed,
            "windows_published": self.windows_published,
            "posteriors_published": self.posteriors_published,
            "quiet_flushes": self.quiet_flushes,
            "quiet_flushes_undone": self.quiet_flushes_undone,
            "arrival_age_s": self._ages(),
        }
        # every rejected window since the state began (the checkpoint's too), as the offline JSON
        # lists them; the live replay listed only the windows this process published
        diag["rejected_windows"] = rejected_list(self.shadow)
        return diag

    def _ages(self) -> dict[str, float | None]:
        now = time.monotonic()
        keys = list(self.shadow.used)
        return {k: (None if t is None else now - t) for k, t in zip(keys, self._arrival, strict=True)}

    def publish_diagnostics(self) -> None:
        """Publish /diagnostics: settlement, inputs, compensation, events; log new warnings once."""
        self.drain()
        diag = self.shadow.diagnostics()
        for line in diag["warnings"]:  # what must not pass silently also reaches the log (stderr)
            # the same warning with other counts is not new; an unconfirmed change is one per time
            key = line.split(" (")[0] if line.startswith("unconfirmed") else warning_key(line)
            if key not in self._warned:
                self._warned.add(key)
                self.get_logger().warn(line)
        for e in diag["events"]:  # a settlement found is news for whoever reads the log, once
            key = f"event at window {e['window']}"
            if key not in self._warned:
                self._warned.add(key)
                self.get_logger().warn(f"settlement event: {event_text(e)}")
        running = time.monotonic() - self._born
        items = statuses(diag, self._ages(), self.malformed, self._timeout_s, running)
        if self.get_namespace() != "/":  # a fleet's nodes share /diagnostics: say which bridge
            ns = self.get_namespace().strip("/")
            items = [dataclasses.replace(s, name=f"{ns}/{s.name}") for s in items]
        self._pub_diag.publish(diagnostic_array(items, self.get_clock().now().nanoseconds))

    def _on_status(self, request: Any, response: Any) -> Any:
        """Answer ``{"taken": [n_frc_01, n_frc_02, n_air_temperature], "posteriors": n}``.

        ``taken``: raw messages taken so far; ``posteriors``: posteriors published so far (a
        VOLATILE reader that matched after some never gets those, ``live_replay.run_live``).
        """
        taken = [n + len(buf) for n, buf in zip(self.received, self._raw, strict=True)]
        response.success = True
        response.message = json.dumps({"taken": taken, "posteriors": self.posteriors_published})
        return response

    def _on_history(self, request: Any, response: Any) -> Any:
        """Answer ``{"windows": [...], "published": n}``: the kept window outputs, oldest first."""
        response.success = True
        response.message = json.dumps(
            {"windows": window_history(self.history), "published": self.windows_published}
        )
        return response

    def _on_flush(self, request: Any, response: Any) -> Any:
        """Close every window holding data, publish, checkpoint; answer with the report as JSON.

        The close is provisional, as the quiet-input one: the checkpoint (and the one written at
        exit) holds the state before it, as ``replay``'s, so a node or a replay resumed from it
        with the next bag goes on with the last record still open, and data that go on within
        ``gap_s`` resume it here too (written after the close, a bag split inside a record lost
        the next bag's first seconds as ``late``).
        """
        self.close_open_windows(provisional=True)
        if self.config.checkpoint_path:
            try:
                self._write_checkpoint()
            except CheckpointError as err:  # the report's warnings say so; the node goes on
                self.shadow.checkpoint_failure = (int(self.shadow.clock_ns or 0), str(err))
        response.success = True
        response.message = json.dumps(jsonable(self.report()))
        return response

    def _on_checkpoint(self, request: Any, response: Any) -> Any:
        """Ingest every message taken, close the windows due, write the checkpoint; answer ``{"path": ...}``.

        No window is closed early (a flush would decide the open ones): the state written is the
        one a replay's checkpoint holds after its bag's last force (``replay_bag``), which is what
        ``replay --live --checkpoint`` asks for before it plays the air past that force
        (``live_chain``). After a quiet-input close no data has decided, the state from before it is
        written, as at exit. Fails (success false, the reason) without ``checkpoint_path`` or when
        the write fails; the node goes on either way.
        """
        if not self.config.checkpoint_path:
            response.success = False
            response.message = "checkpoint_path is empty: the node writes no checkpoint"
            return response
        self.drain(everything=True)
        try:
            path = self._write_checkpoint()
        except CheckpointError as err:
            response.success = False
            response.message = str(err)
            return response
        response.success = True
        response.message = json.dumps({"path": str(path)})
        return response

    def save_on_exit(self) -> Path | None:
        """Ingest what is buffered and write the checkpoint (if configured); return its path.

        After a quiet-input close that no data has decided yet, the state from before it is
        written: the stream as the offline replay has it (the node resumed from it closes the held
        windows again once its inputs stay quiet, and goes on with the record if they come back
        within ``gap_s``).
        """
        self.ingest_pending(everything=True)
        return self._write_checkpoint()

    def _write_checkpoint(self) -> Path | None:
        """Write the checkpoint and return its path (None without ``checkpoint_path``).

        The state now, or from before a quiet-input close (or a flush's) no data has decided yet.
        """
        before = self._before_quiet[0] if self._before_quiet is not None else None
        return self.shadow.save_checkpoint(state=before)


#: an ISO time, then a count or measure: what changes in a warning that is still the same one
_WARNING_TIME = re.compile(r"\d{4}-\d\d-\d\dT[\d:.]+Z?")
_WARNING_NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d+)?")


def warning_key(line: str) -> str:
    """Return what makes a warning line new: its text with times and numbers blanked.

    The digits of a name stay (``frc_01`` and ``frc_02`` are two warnings, one per load cell).
    """
    return _WARNING_NUMBER.sub("#", _WARNING_TIME.sub("#", line))


def startup_lines(config: ShadowConfig, surrogate: Any, params_files: Sequence[str] = ()) -> list[str]:
    """Return what the node says at start: surrogate, parameter files, topics, checkpoint."""
    files = ", ".join(params_files) if params_files else "none (defaults only)"
    outs = config.output_topics()
    return [
        f"surrogate: {describe_surrogate(surrogate, config.surrogate_path or None)}",
        f"parameters: defaults {config_file('shadow.yaml')}; parameter files: {files}",
        f"inputs: {', '.join(config.input_topics())}",
        f"outputs: {', '.join(outs.values())} (every {config.diagnostics_period_s:g} s)",
        f"checkpoint: {config.checkpoint_path or 'off (checkpoint_path is empty)'}",
    ]


def window_history(outputs: Any) -> list[dict[str, Any]]:
    """``WindowOutput``s as plain JSON data (SI units; NaN, e.g. an uncompensated window, as null)."""
    fields = [f.name for f in dataclasses.fields(WindowOutput)]
    return [jsonable({name: getattr(out, name) for name in fields}) for out in outputs]


def outputs_from_history(windows: list[dict[str, Any]]) -> list[WindowOutput]:
    """Rebuild ``WindowOutput``s from ``window_history`` data (null back to NaN)."""
    return [
        WindowOutput(
            index=int(w["index"]),
            end_ns=int(w["end_ns"]),
            samples=np.array(w["samples"], dtype=np.int64),
            temp_c=np.array(w["temp_c"], dtype=float),  # null -> nan
            force_n=np.array(w["force_n"], dtype=float),
            compensated_n=np.array(w["compensated_n"], dtype=float),
            mean_m=np.array(w["mean_m"], dtype=float),
            covariance_m2=np.array(w["covariance_m2"], dtype=float),
            updated=bool(w["updated"]),
            reason=str(w["reason"]),
        )
        for w in windows
    ]
