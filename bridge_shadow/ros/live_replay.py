"""Live replay: play a bag to ``bridge_shadow_node`` through a real (loopback) DDS graph.

``run_live`` starts the node as a subprocess (``NodeProcess``), publishes the bag's raw CDR bytes in
log order from this process (``Player``), calls the node's flush service once every message is
acknowledged, and returns the posterior the node published, with the replay JSON keys of the
direct mode (``posterior.mean_m``, ``posterior.covariance_m2``, ``messages``, ``rejected``,
``messages_per_s``, ``spline``, ...).

Why a subprocess rather than the node on an executor thread of this process: it is the graph of a
real deployment (two processes, DDS between them, the same ``bridge_shadow_node`` entry point),
and on a 2-core machine the node and the player do not share one interpreter lock, so the measured
rate is the node's.

Nothing is lost and the topics stay in step: the graph is RELIABLE, and the player keeps fewer
messages in flight than the node's history depth (``qos_depth``), asking the node's status service
how many it has taken. (Letting DDS push back instead is not enough: a full reliable reader drops
samples for the writer to resend at its next heartbeat, seconds later, and the three topics drift
hours of stamp time apart.) Once the node has taken every message (status service again; reliable
acknowledgements come only at the writer's heartbeat) the player calls flush; the node reports how
many messages it received and run_live checks that against what it published.
"""

from __future__ import annotations

import json
import os
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Temperature
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from bridge_shadow.contract import (
    CHANNELS,
    COMPENSATED_TOPICS,
    COVARIANCE_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE_TOPICS,
    INPUT_TOPICS,
    MEAN_TOPIC,
    NODE_NAME,
    OUTPUT_TOPICS,
    SUPPORTS,
    TEMPERATURE_TOPIC,
)
from bridge_shadow.estimate.parameters.config import ShadowConfig
from bridge_shadow.estimate.parameters.specs import YEAR_S
from bridge_shadow.estimate.result import split_rejected
from bridge_shadow.estimate.state.checkpoint import load_state
from bridge_shadow.replay.air_tail import mark_air_held_whole
from bridge_shadow.ros.convert import array_from_msg
from bridge_shadow.ros.launcher import NodeError, NodeProcess, wait_until
from bridge_shadow.ros.live_chain import (
    RawAirTail,
    decode_air,
    merge_held,
    merge_log_order,
    prepare,
    raw_piece,
)
from bridge_shadow.ros.node import (
    CHECKPOINT_SERVICE,
    FLUSH_SERVICE,
    HISTORY_SERVICE,
    STATUS_SERVICE,
    input_qos,
    outputs_from_history,
)

__all__ = ["INPUT_ORDER", "MAX_IN_FLIGHT", "Player", "merge_log_order", "run_live", "write_params_file"]

#: Messages in flight at most: below the history depth, and below Fast DDS's shared-memory port
#: queue (512 messages per participant by default), whose overflow also costs a heartbeat stall.
MAX_IN_FLIGHT = 400
#: A query of the node's state (status, history) unanswered this long is asked again (the first
#: answer to any request is taken), up to the call's timeout: a service's answer can be lost while
#: DDS still matches the node's response writer to this client's reader, although the service
#: already shows as ready (ros2/rclpy#1181, ros2/rclcpp#625), and the lost one never comes. A
#: flush is never asked twice.
RESEND_S = 5.0
#: Input topics in the node's index order (frc_01, frc_02, air temperature).
INPUT_ORDER: tuple[str, str, str] = (*(FORCE_TOPICS[ch] for ch in CHANNELS), TEMPERATURE_TOPIC)
_OUTPUT_TYPES = {
    MEAN_TOPIC: Float64MultiArray,
    COVARIANCE_TOPIC: Float64MultiArray,
    **{COMPENSATED_TOPICS[ch]: WrenchStamped for ch in CHANNELS},
    DIAGNOSTICS_TOPIC: DiagnosticArray,
}


def posterior_reader_qos(latched_depth: int) -> QoSProfile:
    """Return the QoS of a player's posterior readers: every sample, those before they matched too.

    ``latched_depth``: the node's posterior writers keep their last ``latched_depth`` samples for
    late readers (``node.posterior_qos``, ``qos_depth`` > 0); the reader asks for them
    (TRANSIENT_LOCAL) and keeps all it gets. 0: the node's writers are VOLATILE (``qos_depth`` <=
    0, or not a node of ours), and so is the reader (a TRANSIENT_LOCAL reader would not match them).
    """
    if latched_depth <= 0:
        return input_qos(0)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


class Player:
    """The far end of the node's graph, in its own rclpy context and executor thread.

    Publishes raw input messages (RELIABLE, KEEP_ALL), records every output message raw with its
    receive time (wall ns), and calls the node's flush service. ``inputs`` (frc_01, frc_02, air
    temperature) and ``outputs`` (contract output topic -> name in the graph) follow the node's
    ``topic_*`` parameters; the defaults are the contract's names. ``latched_depth``: how many
    posteriors the node keeps for late readers (``posterior_reader_qos``; 0: none).

    Attributes:
        records: contract output topic (and each ``extra`` topic) -> list of
            ``(receive_ns, raw_cdr)``, in arrival order; ``receive_ns`` is ``time.time_ns()``.

    """

    def __init__(
        self,
        name: str = "bridge_shadow_player",
        *,
        record_diagnostics: bool = True,
        extra: dict[str, Any] | None = None,
        inputs: Sequence[str] = INPUT_ORDER,
        outputs: dict[str, str] | None = None,
        latched_depth: int = 0,
    ) -> None:
        self.context = rclpy.Context()
        # no rclpy signal handlers: Ctrl-C stays a KeyboardInterrupt, and callers' finally blocks
        # stop the node subprocess and this executor thread
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)
        qos = input_qos(0)
        types = (WrenchStamped, WrenchStamped, Temperature)
        self.publishers = [
            self.node.create_publisher(t, topic, qos) for t, topic in zip(types, inputs, strict=True)
        ]
        names = {t: t for t in _OUTPUT_TYPES} | dict(outputs or {})
        self.records: dict[str, list[tuple[int, bytes]]] = {topic: [] for topic in _OUTPUT_TYPES}
        topics = [t for t in _OUTPUT_TYPES if record_diagnostics or t != DIAGNOSTICS_TOPIC]
        # the posterior the node publishes before this reader matched (a node resumed holding a
        # record after a gap says its widened interval at start) is had from its TRANSIENT_LOCAL
        # history; a VOLATILE reader lost it, and the replay waited for a posterior it never got
        durable = posterior_reader_qos(latched_depth)
        special = {DIAGNOSTICS_TOPIC: 10, MEAN_TOPIC: durable, COVARIANCE_TOPIC: durable}
        self._subs = [
            self.node.create_subscription(
                _OUTPUT_TYPES[t], names[t], self._recorder(t), special.get(t, qos), raw=True
            )
            for t in topics
        ]
        self._extra = []
        for topic, msg_type in (extra or {}).items():
            self.records[topic] = []
            sub = self.node.create_subscription(msg_type, topic, self._recorder(topic), qos, raw=True)
            self._extra.append(sub)
        self.flush_client = self.node.create_client(Trigger, FLUSH_SERVICE)
        self.status_client = self.node.create_client(Trigger, STATUS_SERVICE)
        self.history_client = self.node.create_client(Trigger, HISTORY_SERVICE)
        self.checkpoint_client = self.node.create_client(Trigger, CHECKPOINT_SERVICE)
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="player-executor", daemon=True)
        self._thread.start()

    def _recorder(self, topic: str) -> Any:
        log = self.records[topic]
        now = time.time_ns

        def record(raw: bytes) -> None:
            log.append((now(), raw))

        return record

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def graph_ready(self, outputs: bool = True) -> bool:
        """Return True once the node's input subscriptions, services and (optionally) outputs match."""
        subs_ok = all(p.get_subscription_count() > 0 for p in self.publishers)
        pubs_ok = not outputs or all(
            s.get_publisher_count() > 0 for s in self._subs if s.topic_name != DIAGNOSTICS_TOPIC
        )
        clients = (self.flush_client, self.status_client, self.history_client)
        services_ok = all(c.service_is_ready() for c in clients)
        extra_ok = all(s.get_publisher_count() > 0 for s in self._extra)
        return subs_ok and pubs_ok and services_ok and extra_ok

    def wait_for_node(self, node: NodeProcess | None, timeout_s: float = 20.0, outputs: bool = True) -> float:
        """Wait for discovery (no fixed sleep); return the seconds it took."""
        alive = node.check_alive if node is not None else None
        ready = lambda: self.graph_ready(outputs)  # noqa: E731
        return wait_until(ready, timeout_s, "the bridge_shadow node to appear", alive)

    def publish(
        self,
        topic: np.ndarray,
        pos: np.ndarray,
        raws: Sequence[Sequence[bytes]],
        log_ns: np.ndarray | None = None,
        rate: float | None = None,
        in_flight: int | None = None,
        node: NodeProcess | None = None,
        progress: Callable[[float], None] | None = None,
    ) -> tuple[float, float]:
        """Publish ``raws[topic[j]][pos[j]]`` for j in order; return (first, last) perf_counter times.

        One piece of ``publish_pieces`` (see there); ``rate`` needs ``log_ns``.
        """
        n = len(topic)
        logs = np.zeros(n, np.int64) if log_ns is None else np.asarray(log_ns, np.int64)
        shown = None if progress is None else (lambda sent, _log: progress(sent / max(n, 1)))
        t_first, t_last, _ = self.publish_pieces(
            [(topic, pos, raws, logs)], rate if log_ns is not None else None, in_flight, node, shown
        )
        return t_first, t_last

    def publish_pieces(
        self,
        pieces: Iterable[tuple[np.ndarray, np.ndarray, Sequence[Sequence[bytes]], np.ndarray]],
        rate: float | None = None,
        in_flight: int | None = None,
        node: NodeProcess | None = None,
        progress: Callable[[int, int], None] | None = None,
    ) -> tuple[float, float, int]:
        """Publish pieces ``(topic, pos, raws, log_ns)`` in order, as they come (a streamed bag).

        Each piece publishes ``raws[topic[j]][pos[j]]`` for j in order, with log times ``log_ns``.
        With ``rate`` (a speed factor of log time, 1.0 = real time) the player sleeps to keep pace
        with the first message's log time. With ``in_flight`` it keeps at most that many messages
        published but not yet taken by the node (asked through its status service after each chunk
        of ``in_flight / 2``; the answers are awaited one chunk late, so publishing and the node's
        work overlap), so the node's reliable readers never overflow: an overflowing reader drops
        samples for the writer to resend at its next heartbeat, which stalls the stream for
        seconds and lets topics drift. ``progress`` is called with the messages sent so far and the
        last log time, at most every 0.2 s and at the end.

        Returns:
            perf_counter times of the first and the last publication, and the messages sent.

        """
        pubs = [p.publish for p in self.publishers]
        asked: deque[Any] = deque()  # status requests in flight, one sent after each chunk
        sent = 0
        # the node's count is its own since it started: what it took before this call (an earlier
        # call's, another player's) is no room (compared with this call's count alone, a second
        # bag to the same node overflowed its readers, "cannot publish data")
        base = taken = self.taken(node) if in_flight else 0
        last_log = 0
        origin: int | None = None
        t_first = t_shown = time.perf_counter()
        for topic, pos, raws, log_ns in pieces:
            n = len(topic)
            if not n:
                continue
            step = n if not in_flight else max(int(in_flight) // 2, 1)
            due = None
            if rate is not None:
                origin = int(log_ns[0]) if origin is None else origin
                due = ((np.asarray(log_ns, np.int64) - origin) / (1e9 * float(rate))).tolist()
            topics, positions = topic.tolist(), pos.tolist()
            for start in range(0, n, step):
                stop = min(start + step, n)
                # the answer to the request sent after chunk k-2 is usually there by now: pipelined
                while in_flight and sent + stop - start - (taken - base) > in_flight:
                    if not asked:
                        asked.append(self.status_client.call_async(Trigger.Request()))
                    answer = self._answer(asked.popleft(), node, client=self.status_client)
                    taken = max(taken, answer["taken_total"])
                if due is None:
                    for i, j in zip(topics[start:stop], positions[start:stop], strict=True):
                        pubs[i](raws[i][j])
                else:
                    for k in range(start, stop):
                        lag = t_first + due[k] - time.perf_counter()
                        if lag > 0:
                            time.sleep(lag)
                        pubs[topics[k]](raws[topics[k]][positions[k]])
                sent += stop - start
                last_log = int(log_ns[stop - 1])
                if in_flight:
                    asked.append(self.status_client.call_async(Trigger.Request()))
                if progress is not None and time.perf_counter() - t_shown >= 0.2:
                    t_shown = time.perf_counter()
                    progress(sent, last_log)
        if progress is not None:
            progress(sent, last_log)
        return t_first, time.perf_counter(), sent

    def _answer(
        self, future: Any, node: NodeProcess | None, timeout_s: float = 30.0, client: Any = None
    ) -> dict[str, Any]:
        """Wait for a Trigger answer and parse its JSON (``taken_total`` added when ``taken`` is there).

        ``client``: the request was a query (status, history) of that client, asked again every
        ``RESEND_S`` without an answer, the first answer to any of them taken; None (a flush):
        waited for once.
        """
        alive = node.check_alive if node is not None else None
        deadline = time.monotonic() + timeout_s
        answered = threading.Event()  # set from the spinning thread: no polling at a fine period
        asked = [future]
        future.add_done_callback(lambda _future: answered.set())
        while True:
            again = deadline if client is None else min(deadline, time.monotonic() + RESEND_S)

            def due(t: float = again) -> bool:
                return any(f.done() for f in asked) or time.monotonic() >= t

            wait_until(due, timeout_s, "an answer from the node", alive, period_s=0.05, wake=answered)
            done = [f for f in asked if f.done()]
            if done:
                future = done[0]
                break
            if client is None or time.monotonic() >= deadline:
                raise NodeError(f"timed out after {timeout_s:g} s waiting for an answer from the node")
            # asked again, the earlier requests kept: a slow answer (a node busy, a long history)
            # still counts, and whichever comes first is taken
            asked.append(client.call_async(Trigger.Request()))
            asked[-1].add_done_callback(lambda _future: answered.set())
        for f in asked:
            if f is not future and not f.done():
                client.remove_pending_request(f)  # a late answer to it is dropped (rclpy's executor)
        response = future.result()
        if response is None or not response.success:
            raise NodeError(f"the node's service failed: {getattr(response, 'message', 'no answer')}")
        answer = json.loads(response.message)
        if "taken" in answer:
            answer["taken_total"] = int(sum(answer["taken"]))
        return answer

    def _call(self, client: Any, node: NodeProcess | None, timeout_s: float, query: bool = True) -> Any:
        """Ask ``client``'s service; a ``query`` (idempotent) is asked again when its answer is lost."""
        return self._answer(client.call_async(Trigger.Request()), node, timeout_s, client if query else None)

    def history(self, node: NodeProcess | None = None, timeout_s: float = 30.0) -> list[Any]:
        """Return the node's kept window outputs (``WindowOutput``, oldest first), via its history service."""
        return outputs_from_history(self._call(self.history_client, node, timeout_s)["windows"])

    def status(self, node: NodeProcess | None = None, timeout_s: float = 30.0) -> dict[str, Any]:
        """Ask the node's status service (``taken`` per topic, ``posteriors`` published so far)."""
        return self._call(self.status_client, node, timeout_s)

    def taken(self, node: NodeProcess | None = None, timeout_s: float = 30.0) -> int:
        """Ask the node how many input messages it has taken in total."""
        return int(sum(self.status(node, timeout_s)["taken"]))

    def wait_acked(self, timeout_s: float = 30.0) -> None:
        """Block until every published message is acknowledged by the node's reliable readers."""
        for p in self.publishers:
            if not p.wait_for_all_acked(Duration(seconds=timeout_s)):
                raise NodeError(f"{p.topic_name}: not acknowledged within {timeout_s:g} s")

    def checkpoint(self, node: NodeProcess | None = None, timeout_s: float = 30.0) -> dict[str, Any]:
        """Call the node's checkpoint service (write its state now, no window closed early)."""
        alive = node.check_alive if node is not None else None
        client = self.checkpoint_client  # not in ``graph_ready``: a bare echo node has no such service
        wait_until(client.service_is_ready, timeout_s, "the node's checkpoint service", alive)
        return self._call(client, node, timeout_s)

    def flush(self, node: NodeProcess | None = None, timeout_s: float = 30.0) -> dict[str, Any]:
        """Call the node's flush service; return its report (``Shadow.diagnostics()`` + ``node``)."""
        return self._call(self.flush_client, node, timeout_s, query=False)

    def received(self, topic: str) -> int:
        """Return the number of output messages recorded on ``topic``."""
        return len(self.records[topic])

    def last(self, topic: str) -> Any:
        """Return the last recorded message of ``topic``, deserialized."""
        return deserialize_message(self.records[topic][-1][1], _OUTPUT_TYPES[topic])

    def close(self) -> None:
        """Stop the executor thread and shut the context down."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> Player:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_params_file(params: dict[str, Any], directory: Path) -> Path:
    """Write a complete ``bridge_shadow: ros__parameters:`` file (the node then uses exactly these)."""
    path = directory / "params.yaml"
    path.write_text(yaml.safe_dump({NODE_NAME: {"ros__parameters": params}}, sort_keys=False))
    return path


def _write_outputs(
    path: str | Path,
    records: dict[str, list[tuple[int, bytes]]],
    names: dict[str, str],
    overwrite: bool = False,
    storage: str = "sqlite3",
) -> Path:
    """Record the node's outputs under their graph ``names``, log time = receive time (as a recorder)."""
    from bridge_shadow.bagio import BagOutputWriter

    with BagOutputWriter(path, storage, overwrite=overwrite) as writer:
        for topic, items in records.items():
            if items:
                stamps, raws = zip(*items, strict=True)
                writer.write_many_raw(names.get(topic, topic), OUTPUT_TOPICS[topic], stamps, raws)
    return Path(path)


def _node_config(config: ShadowConfig, tmp: Path) -> ShadowConfig:
    """Return the node's parameters of a live replay: a checkpoint of its own in ``tmp``, written rarely.

    The replay must not resume an earlier run nor overwrite a running node's state (the params
    file's ``checkpoint_path`` is the node's). A checkpoint named (``--checkpoint``) is copied
    there first (``live_chain.prepare``) and written back once the run is complete
    (``LiveChain.finish``). The node's file is read after the checkpoint service's write (a
    chain's state) and after the flush (the plots' curve), and is removed with ``tmp``: nothing
    resumes from a periodic write of it, which in a replay as fast as the node takes it came every
    ``checkpoint_period_s`` of stamp time (a 1440-window day: 144 writes, a quarter of the node's
    CPU). It is written when asked, at the flush and at exit only (a period of a year of stamp
    time, the longest the parameter takes).
    """
    return config.replace(checkpoint_path=str(tmp / "checkpoint.npz"), checkpoint_period_s=YEAR_S)


def run_live(
    bag: str | Path | Sequence[str | Path],
    params_path: str | Path | None = None,
    *,
    out: str | Path | None = None,
    overwrite: bool = False,
    storage: str = "sqlite3",
    plots: str | Path | None = None,
    rate: float | None = None,
    overrides: dict[str, Any] | None = None,
    timeout_s: float = 60.0,
    progress: Callable[[float], None] | None = None,
    checkpoint: str | Path | None = None,
    watch: bool = False,
    taken: Sequence[dict[str, Any]] = (),
) -> dict[str, Any]:
    """Replay ``bag`` through ``bridge_shadow_node`` over loopback DDS; return the replay JSON.

    Args:
        bag: rosbag2 directory with the contract input topics, or several read as one stream merged
            by log time (``bagio.merged.MergedStream``: bags that overlap in time, as the direct
            replay reads them; published serialized again from what was decoded).
        params_path: shadow parameter file (default ``config/shadow.yaml``).
        out: record the node's output topics into this bag (log time = receive time).
        overwrite: replace an existing bag at ``out`` (``--force``), once the new one is complete.
        storage: ``out``'s storage, ``sqlite3`` or ``mcap``.
        plots: write the replay PNGs into this directory, from the node's own state: its window
            outputs (history service) and its final spline fit (the checkpoint it writes at flush).
        rate: speed factor of log time (1.0 = real time); None = as fast as the node takes it.
        overrides: parameter overrides applied after the file (as ``-p name:=value``).
        timeout_s: limit for discovery, acknowledgement, flush and outputs, each.
        progress: called with the fraction of the bag published (a progress bar).
        checkpoint: resume from this file if it exists, and write it once the run is complete: the
            state after the bag's last force, with the air past that force held unfed for the next
            bag (``live_chain``: a chain of live replays gives what one replay of the bags merged
            gives); an interrupted run leaves it as it was. Default: none (the node's checkpoint is
            a temporary one, so the replay never touches a running node's state; the
            ``checkpoint_path`` of the parameter file is not used).
        watch: print the node's latest outputs once a second on stderr (``watch.TopicWatch``).
        taken: the signatures of the bags (``replay.taken.bag_signature``), recorded as taken in
            ``checkpoint`` when it is written.

    Network: unless the environment sets ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (an explicit choice is
    respected), this process and the node are confined to loopback discovery in one domain id of
    their own (``netenv.confine_to_loopback``), so the replay never reaches another machine or a
    running node. When the node is not discovered in ``timeout_s`` the error says which range
    and domain were searched.

    Returns:
        The direct replay's JSON keys (``posterior``, ``messages``, ``rejected``, ``messages_per_s``,
        ``seconds``, ``windows``, ``spline``, ``noise``) plus ``live`` (graph timings, node counters).

    """
    from bridge_shadow.bagio.merged import open_monitoring
    from bridge_shadow.estimate import load_config
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.ros.netenv import check_domain_id, confine_to_loopback

    bags = [Path(bag)] if isinstance(bag, str | Path) else [Path(b) for b in bag]
    check_domain_id()  # a domain DDS cannot use ends the node's process with no line of ours
    if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in os.environ:  # before rclpy starts (Player, node)
        confine_to_loopback()
    config = load_config(params_path, overrides)
    surrogate = load_surrogate(config.surrogate_path or None)
    inputs = config.input_topics()
    # streamed: what is held is one piece of the bag, whatever its length (as in the direct mode,
    # the air temperature may be absent: the node then runs uncompensated and says so)
    with (
        open_monitoring(bags, topics=inputs, required=list(INPUT_TOPICS)[:2]) as stream,
        tempfile.TemporaryDirectory(prefix="bridge_shadow_live_") as tmp,
    ):
        node_config = _node_config(config, Path(tmp))
        # a chain: the node resumes from a copy, the held air is played merged with the bag
        copy = Path(node_config.checkpoint_path)
        chain = None if checkpoint is None else prepare(config, surrogate, checkpoint, copy)
        params_file = write_params_file(node_config.to_params(), Path(tmp))
        node = NodeProcess(["--ros-args", "--params-file", str(params_file)])
        player = None
        kept = False  # the named checkpoint left as it was (``LiveChain.finish``)
        forces_played = 0  # the bag's load-cell messages the node received
        try:
            first, last = stream.first_ns, stream.last_ns
            span = max((last or 0) - (first or 0), 1)
            fraction = None
            if progress is not None:
                fraction = lambda _sent, log: progress(min(max(log - (first or 0), 0) / span, 1.0))  # noqa: E731
            t0 = time.perf_counter()
            node.start()
            latched = max(config.qos_depth, 100) if config.qos_depth > 0 else 0  # the node's ``out_depth``
            player = Player(inputs=inputs, outputs=config.output_topics(), latched_depth=latched)
            discovery_s = _discover(player, node, timeout_s)
            # VOLATILE posterior readers (qos_depth <= 0: the node keeps none for late readers) never
            # get what the node published before they matched: a resumed node's widened interval at
            # start (the replay waited for it until its timeout, one run in two); not waited for.
            # Those published by the status answer less those received by then (not below 0: one
            # published after the answer may be in already)
            missed = 0
            if not latched:
                published = int(player.status(node, timeout_s).get("posteriors", 0))
                missed = max(published - player.received(MEAN_TOPIC), 0)
            in_flight = min(config.qos_depth if config.qos_depth > 0 else MAX_IN_FLIGHT, MAX_IN_FLIGHT)
            if watch:
                from bridge_shadow.ros.watch import TopicWatch

                watcher = TopicWatch(player.records)
                fraction = lambda _sent, log: watcher(min(max(log - (first or 0), 0) / span, 1.0))  # noqa: E731
            pieces: Iterable[Any] = _merged_pieces(stream) if len(bags) == 1 else _encoded_pieces(stream)
            hold = None
            if chain is not None:  # the air past the bag's last force is held (``live_chain``)
                pieces = hold = RawAirTail(merge_held(pieces, chain.held))
            t_first, t_last, total = player.publish_pieces(pieces, rate, in_flight, node, fraction)
            captured: dict[str, Any] = {}
            if chain is not None and hold is not None:
                # the state after the last force, before the tail: the offline chain's checkpoint
                sent = f"the node to take {total} messages"
                wait_until(lambda: player.taken(node) >= total, timeout_s, sent)
                player.checkpoint(node, timeout_s)
                captured = load_state(chain.private)
                if hold.tail:  # then the tail, for this bag's own result
                    _, t_last, more = player.publish_pieces(hold.tail, rate, in_flight, node, fraction)
                    total += more
            wait_until(lambda: player.taken(node) >= total, timeout_s, f"the node to take {total} messages")
            report = player.flush(node, timeout_s)
            t_done = time.perf_counter()
            counters = report["node"]
            got = sum(counters["received"].values())
            if got != total:
                raise NodeError(f"the node received {got} of {total} messages")
            n_out = int(counters["windows_published"])
            # the windows', and the flush's refit, less those a VOLATILE reader missed
            n_post = int(counters["posteriors_published"]) - missed
            wait_until(
                lambda: player.received(MEAN_TOPIC) >= n_post and player.received(COVARIANCE_TOPIC) >= n_post,
                timeout_s,
                f"{n_post} posterior messages",
                node.check_alive,
            )
            if n_post > 0 and not missed:
                mean, _ = array_from_msg(player.last(MEAN_TOPIC))
                cov, _ = array_from_msg(player.last(COVARIANCE_TOPIC))
            else:  # none, or some missed: the count may be one off (one in flight when it was taken)
                # and the last received one not the last published; the flush's report holds that
                mean, cov = np.asarray(report["mean_m"]), np.asarray(report["covariance_m2"])
            history = player.history(node, timeout_s)  # the node keeps a week of windows
            plot_paths = (
                _plot_live(plots, history, report, node_config, surrogate) if plots is not None else []
            )
            code = node.stop()
            if node.killed_after_s is not None:
                # the flush has answered and written the checkpoint, the outputs and history are in:
                # nothing of the replay is lost, but a node that does not stop is said
                report["warnings"] = [
                    *report["warnings"],
                    f"bridge_shadow_node did not exit within {node.killed_after_s:g} s of SIGINT after the "
                    "replay's flush and was killed (its flush had answered and written the checkpoint: "
                    "nothing of this replay is lost)",
                ]
            elif code != 0:
                raise NodeError(f"bridge_shadow_node exited with code {code}: {node.output().strip()[-300:]}")
            records = player.records
            if chain is not None and hold is not None:
                tail, malformed_tail = decode_air(hold.tail)
                forces_played = sum(int(counters["received"].get(ch, 0)) for ch in CHANNELS)
                kept = chain.finish(captured, tail, taken, forces_played) is None
        except NodeError as err:
            if chain is None:
                raise
            # the node's own last lines may say "checkpoint written to" its private copy, removed now
            left = f"{chain.checkpoint} is left as it was: the node wrote only a copy"
            raise NodeError(f"{err} ({left})") from None
        finally:
            if player is not None:
                player.close()
            node.close()
    seconds = t_done - t_first
    used = report["used"]
    js: dict[str, Any] = {
        "posterior": {
            "mean_m": mean.tolist(),
            "covariance_m2": cov.tolist(),
            "sigma_m": np.sqrt(np.diag(cov)).tolist(),
            "supports": list(SUPPORTS),
            "state": report["state"],
        },
        "messages": {
            "total": total,
            "used": int(sum(used.values())),
            "used_by_topic": used,
            "rejected": total - int(sum(used.values())) - int(counters["malformed"]),
            "rejected_by_reason": split_rejected(report["rejected"])[0],
        },
        "rejected": report["rejected"],
        "messages_per_s": total / seconds if seconds > 0 else float("inf"),
        "seconds": seconds,
        "windows": {
            "closed": report["windows"]["closed"],
            "updates": report["windows"]["updates"],
            "uncompensated": report["windows"]["uncompensated"],
            "stale_temperature": report["windows"].get("stale_temperature", 0),
            "rejected_by_reason": split_rejected(report["rejected"])[1],
        },
        "events": report["events"],
        "unconfirmed_changes": report["unconfirmed_changes"],
        "gaps": report["gaps"],
        "traffic": report["traffic"],
        "rejected_windows": report["rejected_windows"],  # the node's whole list (ShadowNode.report)
        "warnings": [*report["warnings"], *_malformed_line(int(counters["malformed"]))],
        "prior": report["prior"],
        "spline": report["spline"],
        "noise": report["noise"],
        "bag": str(bags[0]),
        **({"bags": [str(b) for b in bags]} if len(bags) > 1 else {}),  # read merged by log time
        "surrogate": surrogate.summary(),
        "live": {
            "domain_id": int(node.env["ROS_DOMAIN_ID"]),
            "discovery_s": discovery_s,
            "startup_s": t_first - t0,
            "publish_s": t_last - t_first,
            "windows_published": n_out,
            "malformed": counters["malformed"],
            "received": counters["received"],
        },
    }
    if chain is not None and kept:
        js["checkpoint_kept"] = True  # none of the bag's load-cell messages used: not written
    elif chain is not None:
        # a bag of the air alone, held whole for the next bag: no failure
        mark_air_held_whole(js, forces_played, len(tail) if tail is not None else 0)
        # as the offline chain's: the windows the next bag's run closes again, the air it holds
        js["windows"]["at_end"] = {
            "closed": js["windows"]["closed"] - int(captured["scalars"]["n_windows"]),
            "updates": js["windows"]["updates"] - int(captured["filter"]["n_updates"]),
            "held_air": len(tail) if tail is not None else 0,
        }
        js["warnings"] = [*chain.notes, *js["warnings"]]
        if malformed_tail:
            js["warnings"].append(
                f"{malformed_tail} air message(s) past the bag's last force could not be decoded: not "
                "held in the checkpoint (the node dropped them as malformed)"
            )
    if out is not None:
        js["out"] = str(_write_outputs(out, records, config.output_topics(), overwrite, storage))
    if plots is not None:
        js["plots"] = [str(p) for p in plot_paths]
    return js


def _malformed_line(n: int) -> list[str]:
    """Say that the node dropped messages it could not decode (the direct replay refuses such a bag)."""
    if not n:
        return []
    return [
        f"{n} message(s) of the bag could not be decoded (malformed): the node dropped them, as it "
        "drops such live data (the direct replay refuses the bag: 'replay BAG' names the first one)"
    ]


def _discover(player: Player, node: NodeProcess, timeout_s: float) -> float:
    """Wait for the node in the graph; on a timeout say where discovery looked (one line)."""
    try:
        return player.wait_for_node(node, timeout_s)
    except NodeError as err:
        if not str(err).startswith("timed out"):
            raise  # the node died: its own last line says why
        where = (
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '(unset)')}, "
            f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '(unset: 0)')}"
        )
        hint = (
            "unset ROS_AUTOMATIC_DISCOVERY_RANGE to let replay --live keep DDS on loopback in a "
            "domain of its own, or make sure that range and domain reach this machine's loopback"
        )
        raise NodeError(f"{err}: DDS discovery found no node ({where}); {hint}") from None


def _encoded_pieces(stream: Any) -> Iterator[tuple[np.ndarray, np.ndarray, list[list[bytes]], np.ndarray]]:
    """Yield the pieces of several bags read as one stream (``MergedStream``) serialized again.

    Bags that overlap in time are read merged by log time, as the direct replay reads them; the
    messages go out as ``publish_pieces`` takes them, serialized from what was decoded
    (``live_chain.raw_piece``): the same stamps, frame ids, forces and air temperatures with their
    variance (a wrench's other components, which the shadow does not read, go out as zero).
    """
    for piece in stream:
        yield raw_piece(piece)


def _merged_pieces(
    stream: Any,
) -> Iterator[tuple[np.ndarray, np.ndarray, list[list[bytes]], np.ndarray]]:
    """Yield the bag's pieces as ``publish_pieces`` takes them: arrival order, raw bytes per topic."""
    empty = np.empty(0, np.int64)
    for blocks in stream.raw_pieces():
        topic, pos, merged = merge_log_order([empty if b is None else b.log_ns for b in blocks])
        yield topic, pos, [[] if b is None else b.raws() for b in blocks], merged


def _plot_live(
    directory: str | Path, outputs: list[Any], report: dict[str, Any], config: Any, surrogate: Any
) -> list[Path]:
    """Draw the direct replay's PNGs from what the node kept: its outputs and final checkpoint.

    The node keeps its last ``HISTORY_WINDOWS`` outputs, so on longer bags the time plots show that
    last stretch; the compensation curve and the ellipse are the final state either way.
    """
    from bridge_shadow.estimate import ReplayResult, Shadow
    from bridge_shadow.estimate.plots import write_plots

    ckpt = Path(config.checkpoint_path)
    if not ckpt.is_file():
        raise NodeError(f"the node wrote no checkpoint at flush ({ckpt}): cannot draw its compensation curve")
    shadow = Shadow.resume(ckpt, config, surrogate)
    # the checkpoint holds the state before the flush's provisional close (a next bag goes on from
    # it); the close the node made is made again here, its refit the curve the direct replay draws
    # (drawn from the state before, the live compensation curve was not the direct one's)
    shadow.flush()
    result = ReplayResult(
        mean_m=np.asarray(report["mean_m"], float),
        covariance_m2=np.asarray(report["covariance_m2"], float),
        messages=int(sum(report["node"]["received"].values())),
        used=report["used"],
        rejected=report["rejected"],
        windows=int(report["windows"]["closed"]),
        updates=int(report["windows"]["updates"]),
        spline=report["spline"],
        noise=report["noise"],
        outputs=outputs,
    )
    return write_plots(directory, result, shadow)
