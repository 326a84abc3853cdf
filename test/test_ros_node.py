"""The live node in a real DDS graph (loopback): live replay equals direct replay, SIGTERM + resume.

Each test starts ``bridge_shadow_node`` as a subprocess in this run's domain (conftest confines DDS
to loopback). The bundled bag has 3 force samples per 60 s window, so the tests lower
``window_min_samples`` to 2 (the default 10 would skip every window and compare zeros).
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rclpy")

from input_messages import raw_inputs
from rclpy.serialization import deserialize_message

from bridge_shadow.bagio import read_monitoring, read_raw_topics
from bridge_shadow.contract import (
    DIAGNOSTICS_TOPIC,
    FLOAT_ARRAY_TYPE,
    INPUT_TOPICS,
    MEAN_TOPIC,
)
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.ros.convert import array_from_msg
from bridge_shadow.ros.launcher import NodeProcess, wait_until
from bridge_shadow.ros.live_replay import (
    INPUT_ORDER,
    Player,
    merge_log_order,
    run_live,
    write_params_file,
)

pytestmark = pytest.mark.ros

OVERRIDES = {"window_min_samples": 2}
TIMEOUT_S = 30.0


@pytest.fixture(scope="module")
def bag(root: Path) -> Path:
    return root / "bags" / "baseline_1d"


@pytest.fixture(scope="module")
def direct(bag: Path):
    """The offline replay of the same bag with the same parameters (the reference)."""
    return Shadow(load_config(None, OVERRIDES)).run(read_monitoring(bag))


#: Log time kept by ``short_bag``: 8 h, 480 windows (the whole day runs once, in the first test).
SHORT_NS = 8 * 3600 * 10**9


def _head_of(bag: Path, out: Path, topics: dict[str, str], span_ns: int) -> Path:
    """Write the first ``span_ns`` of log time of ``topics`` (name -> type) of ``bag`` to ``out``."""
    from bridge_shadow.bagio import BagOutputWriter

    with BagOutputWriter(out) as writer:
        for topic, (log_ns, raws) in read_raw_topics(bag, INPUT_TOPICS).items():
            if topic in topics:
                keep = log_ns < log_ns[0] + span_ns
                kept = [r for r, k in zip(raws, keep, strict=True) if k]
                writer.write_many_raw(topic, INPUT_TOPICS[topic], log_ns[keep], kept)
    return out


@pytest.fixture(scope="module")
def short_bag(bag: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The bag's first eight hours, every input topic (for the tests that need a node run, not a day)."""
    return _head_of(bag, tmp_path_factory.mktemp("short") / "bag", INPUT_TOPICS, SHORT_NS)


@pytest.fixture(scope="module")
def short_direct(short_bag: Path):
    """The offline replay of ``short_bag`` (the reference of the tests that use it)."""
    return Shadow(load_config(None, OVERRIDES)).run(read_monitoring(short_bag))


def test_a_live_replay_writes_its_temporary_checkpoint_at_the_flush_only(tmp_path: Path) -> None:
    """The node's checkpoint is a temporary file of the replay's, read after its writes, never periodic.

    Its periodic writes (every ``checkpoint_period_s`` of stamp time: 144 on the bundled day, a
    quarter of the node's CPU as fast as it takes them) served nothing: the period is the longest
    the parameter takes. A checkpoint named (``--checkpoint``) is copied there and written back
    at the end (``live_chain``, ``test_live_chain.py``); the parameter file's own checkpoint path (a
    running node's) is never the one used.
    """
    from bridge_shadow.estimate.parameters.specs import YEAR_S
    from bridge_shadow.ros.live_replay import _node_config

    given = load_config(None, {"checkpoint_path": str(tmp_path / "node.npz"), "checkpoint_period_s": 60.0})
    temporary = _node_config(given, tmp_path / "tmp")
    assert temporary.checkpoint_path == str(tmp_path / "tmp" / "checkpoint.npz")
    assert temporary.checkpoint_period_s == YEAR_S  # exact: the constant passed through


def test_live_replay_equals_direct_replay(bag: Path, direct, tmp_path: Path) -> None:
    shown: list[float] = []
    live = run_live(
        bag,
        overrides=OVERRIDES,
        out=tmp_path / "out",
        plots=tmp_path / "plots",
        timeout_s=TIMEOUT_S,
        progress=shown.append,
    )
    ref = direct.to_json()
    assert ref["windows"]["updates"] > 1000  # a real comparison, not two priors
    assert live["messages"] == ref["messages"]
    assert live["rejected"] == ref["rejected"]
    # The pipeline is chunk-independent, so DDS delivery must not change a bit: batch equality.
    np.testing.assert_allclose(live["posterior"]["mean_m"], ref["posterior"]["mean_m"], rtol=1e-12, atol=0)
    np.testing.assert_allclose(
        live["posterior"]["covariance_m2"], ref["posterior"]["covariance_m2"], rtol=1e-12, atol=0
    )
    assert live["windows"] == ref["windows"]
    assert live["rejected_windows"] == ref["rejected_windows"]  # every one, as the offline JSON
    assert live["live"]["windows_published"] == len(direct.outputs)
    # --out records every published posterior; the last one is the returned posterior
    raw = read_raw_topics(tmp_path / "out", {MEAN_TOPIC: FLOAT_ARRAY_TYPE})[MEAN_TOPIC][1]
    assert len(raw) == len(direct.outputs)
    from std_msgs.msg import Float64MultiArray

    last, labels = array_from_msg(deserialize_message(raw[-1], Float64MultiArray))
    assert labels == ("support",)
    np.testing.assert_array_equal(
        last, live["posterior"]["mean_m"]
    )  # the node's floats, copied through the bag
    # --plots: the same four PNGs as the direct replay, drawn from the node's own state
    assert sorted(Path(p).name for p in live["plots"]) == [
        "compensation_curve.png",
        "credible_ellipse.png",
        "posterior.png",
        "raw_vs_compensated.png",
    ]
    assert all(Path(p).stat().st_size > 10_000 for p in live["plots"])
    # the same pictures as the direct replay's (drawn from the node's state after its flush: the
    # compensation curve was drawn from the state before the flush's refit)
    from bridge_shadow.estimate.plots import write_plots

    shadow = Shadow(load_config(None, OVERRIDES))
    drawn = write_plots(tmp_path / "direct_plots", shadow.run(read_monitoring(bag)), shadow)
    import matplotlib.image as mpimg

    for mine, theirs in zip(sorted(drawn), sorted(map(Path, live["plots"])), strict=True):
        a, b = mpimg.imread(mine), mpimg.imread(theirs)
        assert a.shape == b.shape, mine.name
        # drawn from floats two runs compute: an ulp may move an edge pixel, not a curve (the curve
        # from the state before the refit differed in 5,221 pixels of the 559,020, 2026-12-02)
        differ = int(np.count_nonzero(np.any(np.abs(a - b) > 2 / 255, axis=-1)))
        assert differ <= 50, (mine.name, differ)
    # the progress callback saw the publishing advance to the end
    assert shown and shown[-1] == 1.0 and shown == sorted(shown)  # exact: the last is n / n (or clipped at 1)


def test_history_service_returns_the_window_outputs(short_bag: Path, short_direct) -> None:
    """The node's history service gives every window output the offline replay produced, exactly."""
    direct = short_direct
    params = load_config(None, OVERRIDES)
    data = read_raw_topics(short_bag, INPUT_TOPICS)
    raws = [data[t][1] for t in INPUT_ORDER]
    topic, pos, _ = merge_log_order([data[t][0] for t in INPUT_ORDER])
    with tempfile.TemporaryDirectory() as tmp:
        args = ["--ros-args", "--params-file", str(write_params_file(params.to_params(), Path(tmp)))]
        with Player() as player, NodeProcess(args) as node:
            player.wait_for_node(node, TIMEOUT_S)
            player.publish(topic, pos, raws, in_flight=200, node=node)
            wait_until(lambda: player.taken(node) >= len(topic), TIMEOUT_S, "every message", node.check_alive)
            player.flush(node, TIMEOUT_S)
            history = player.history(node, TIMEOUT_S)
    assert len(history) == len(direct.outputs) > 400
    got, ref = direct.history(), _history_arrays(history)
    for key, value in ref.items():
        np.testing.assert_allclose(got[key], value, rtol=1e-12, atol=0, err_msg=key)  # NaN = NaN
    assert [o.reason for o in history] == [o.reason for o in direct.outputs]


def _history_arrays(outputs: list) -> dict[str, np.ndarray]:
    from bridge_shadow.estimate import ReplayResult

    empty = {"used": {}, "rejected": {}, "spline": {}, "noise": {}}
    return ReplayResult(np.zeros(2), np.eye(2), 0, windows=0, updates=0, outputs=outputs, **empty).history()


def _diagnostic_values(raw: bytes) -> dict[str, tuple[int, dict[str, str]]]:
    from diagnostic_msgs.msg import DiagnosticArray

    msg = deserialize_message(raw, DiagnosticArray)
    return {s.name: (s.level[0], {kv.key: kv.value for kv in s.values}) for s in msg.status}


def test_ctrl_c_while_the_node_starts_is_exit_130_without_a_traceback() -> None:
    """rclpy, numpy and scipy take seconds to import on a busy machine; Ctrl-C then printed a trace.

    The signal is sent once rcl's library is in the process (the imports under way) and before
    the node could have installed its own handler (it has not said anything yet).
    """
    node = NodeProcess()  # the console script's way: SIGINT's default handler, python -m
    node.start()
    try:
        maps = Path(f"/proc/{node.proc.pid}/maps")

        def importing() -> bool:
            return node.proc.poll() is not None or "librcl" in maps.read_text()

        wait_until(importing, 60.0, "the node's imports")
        assert not node.output(), node.output()  # still before its first line
        code = node.stop(signal.SIGINT, timeout_s=30.0)
        assert code == 130 and "Traceback" not in node.output(), (code, node.output())
    finally:
        node.close()


def test_sigterm_writes_checkpoint_and_restart_resumes(short_bag: Path, short_direct, tmp_path: Path) -> None:
    direct = short_direct
    ckpt = tmp_path / "shadow.npz"
    params = load_config(None, OVERRIDES).replace(checkpoint_path=str(ckpt), diagnostics_period_s=0.2)
    args = ["--ros-args", "--params-file", str(write_params_file(params.to_params(), tmp_path))]
    data = read_raw_topics(short_bag, INPUT_TOPICS)
    raws = [data[t][1] for t in INPUT_ORDER]
    topic, pos, _ = merge_log_order([data[t][0] for t in INPUT_ORDER])
    half = len(topic) // 2
    with Player() as player:
        with NodeProcess(args) as first:
            player.wait_for_node(first, TIMEOUT_S)
            player.publish(topic[:half], pos[:half], raws, in_flight=200, node=first)
            wait_until(lambda: player.taken(first) >= half, TIMEOUT_S, "the first half", first.check_alive)
            # on SIGTERM the node ingests what it has buffered before the checkpoint: on a busy
            # machine (the other test process replaying twin days) that took longer than the
            # launcher's default 10 s, and the node was killed while writing
            assert first.stop(signal.SIGTERM, timeout_s=TIMEOUT_S) == 0, first.output()
            assert "checkpoint written" in first.output()
        assert ckpt.is_file()
        wait_until(lambda: player.publishers[0].get_subscription_count() == 0, TIMEOUT_S, "the node to leave")
        with NodeProcess(args) as second:
            player.wait_for_node(second, TIMEOUT_S)
            assert "resumed from" in second.output()
            player.publish(topic[half:], pos[half:], raws, in_flight=200, node=second)
            rest = len(topic) - half
            wait_until(lambda: player.taken(second) >= rest, TIMEOUT_S, "the second half", second.check_alive)
            report = player.flush(second, TIMEOUT_S)
            n_diag = player.received(DIAGNOSTICS_TOPIC)
            wait_until(lambda: player.received(DIAGNOSTICS_TOPIC) > n_diag + 1, TIMEOUT_S, "diagnostics")
            diag = _diagnostic_values(player.records[DIAGNOSTICS_TOPIC][-1][1])
    # interrupted + resumed equals one uninterrupted offline run
    assert report["used"] == direct.used
    assert report["rejected"] == direct.rejected
    np.testing.assert_allclose(report["mean_m"], direct.mean_m, rtol=1e-12, atol=0)
    np.testing.assert_allclose(report["covariance_m2"], direct.covariance_m2, rtol=1e-12, atol=0)
    # the /diagnostics the node published after the flush carry that posterior, in mm
    assert set(diag) == {
        "bridge_shadow: settlement",
        "bridge_shadow: inputs",
        "bridge_shadow: compensation",
        "bridge_shadow: events",
    }
    level, values = diag["bridge_shadow: settlement"]
    assert level in (0, 1)
    sigma = np.sqrt(np.diag(direct.covariance_m2))
    for i, side in enumerate(("south", "north")):
        assert values[f"{side} settlement [mm]"] == f"{1e3 * direct.mean_m[i]:+.4f}"
        assert values[f"{side} sigma [mm]"] == f"{1e3 * sigma[i]:.4f}"
    _, inputs = diag["bridge_shadow: inputs"]
    assert inputs["rejected nonfinite"] == str(direct.rejected["nonfinite"])
    assert inputs["frc_01 used"] == str(direct.used["frc_01"])
    _, comp = diag["bridge_shadow: compensation"]
    assert comp["frc_01 edf"] == f"{direct.spline['frc_01']['edf']:.2f}"


def test_a_child_that_ignores_sigint_is_killed_and_the_kill_recorded(tmp_path: Path) -> None:
    """``NodeProcess.stop``: SIGINT, the grace, then SIGKILL, and ``killed_after_s`` says so."""
    (tmp_path / "stubborn.py").write_text(
        "import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\nprint('ready', flush=True)\n"
        "time.sleep(60)\n"
    )
    (tmp_path / "polite.py").write_text("import time\nprint('ready', flush=True)\ntime.sleep(60)\n")
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    with NodeProcess(module="stubborn", env=env) as stubborn, NodeProcess(module="polite", env=env) as polite:
        for child in (stubborn, polite):
            wait_until(lambda c=child: "ready" in c.output(), TIMEOUT_S, "the child to start")
        assert stubborn.stop(timeout_s=0.5) == -signal.SIGKILL and stubborn.killed_after_s == 0.5
        assert polite.stop(timeout_s=10.0) != -signal.SIGKILL and polite.killed_after_s is None


def test_a_child_hears_sigint_where_its_launcher_was_started_with_it_ignored(tmp_path: Path) -> None:
    """A shell's background job starts with SIGINT ignored, and an ignored signal survives ``exec``.

    The child gets Python's own SIGINT handler back, so ``stop`` ends it by SIGINT, not by SIGKILL
    after the grace (rclpy installs its own handler in the node; a plain child relies on Python's).
    It runs as under ``python -m``.
    """
    (tmp_path / "polite.py").write_text(
        "import sys, time\nprint('ready', __name__, sys.argv[1:], flush=True)\ntime.sleep(60)\n"
    )
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    node = NodeProcess(["--ros-args", "-p", "x:=1"], module="polite", env=env)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # as in a background job: inherited
    try:
        node.start()
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        # the whole line: the child writes unbuffered (PYTHONUNBUFFERED), print's parts one by one
        wait_until(lambda: "\n" in node.output(), TIMEOUT_S, "the child's first line")
        assert "ready __main__ ['--ros-args', '-p', 'x:=1']" in node.output()
        assert node.stop(timeout_s=10.0) == -signal.SIGINT and node.killed_after_s is None
    finally:
        node.close()


def test_a_node_killed_after_the_flush_leaves_the_replay_whole_with_a_warning(
    short_bag: Path, short_direct, monkeypatch
) -> None:
    """Once the flush has answered the replay is complete: a node that will not exit is said, not fatal."""
    stop = NodeProcess.stop

    def hung(self, sig=signal.SIGINT, timeout_s=10.0):  # the node stops, as if it had to be killed
        stop(self, sig, timeout_s)
        self.killed_after_s = timeout_s
        return -signal.SIGKILL

    monkeypatch.setattr(NodeProcess, "stop", hung)
    live = run_live(short_bag, overrides=OVERRIDES, timeout_s=TIMEOUT_S)
    np.testing.assert_allclose(live["posterior"]["mean_m"], short_direct.mean_m, rtol=1e-12, atol=0)
    assert live["warnings"][:-1] == short_direct.to_json()["warnings"]
    assert "did not exit within 10 s of SIGINT" in live["warnings"][-1] and "nothing" in live["warnings"][-1]


def test_bad_parameter_exits_2_with_one_line() -> None:
    with NodeProcess(["--ros-args", "-p", "window_s:=-1.0"]) as node:
        assert node.proc is not None
        assert node.proc.wait(TIMEOUT_S) == 2
        out = node.output()
    assert "window_s must be a finite number in (0, 86400], not -1.0" in out
    assert "Traceback" not in out


def test_an_argument_outside_ros_args_stops_the_node_before_it_starts(capsys) -> None:
    """``bridge_shadow_node --params-file F`` (without ``--ros-args``): ROS would run on the defaults.

    The node takes no arguments of its own, so one outside ``--ros-args`` (before it, or after a
    ``--`` that ends it) is a mistake: exit 2 with one line that says where parameters go.
    """
    from bridge_shadow.ros.main import main, user_args

    assert user_args(["--ros-args", "-p", "window_s:=60.0", "--params-file", "f.yaml"]) == []
    assert user_args(["--params-file", "f.yaml"]) == ["--params-file", "f.yaml"]
    assert user_args(["--ros-args", "-p", "a:=1", "--", "x"]) == ["x"]
    assert main(["--params-file", "shadow.yaml"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unrecognized arguments: --params-file shadow.yaml" in err[0]
    assert "go after --ros-args" in err[0]


def test_parameters_default_to_shadow_yaml_and_override() -> None:
    import rclpy
    from rclpy.parameter import Parameter

    from bridge_shadow.ros.node import ShadowNode

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        overrides = [Parameter("window_s", value=30), Parameter("prior_sigma_m", value=[4.0e-4, 5.0e-4])]
        node = ShadowNode(context=context, parameter_overrides=overrides)
        try:
            expected = load_config().replace(window_s=30.0, prior_sigma_m=[4.0e-4, 5.0e-4])
            assert node.config == expected  # an int for a float parameter is accepted (dynamic typing)
            assert node.get_name() == "bridge_shadow"
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def _steady_100hz(n: int, seed: int) -> tuple[list[list[bytes]], list[Any]]:
    """Return ``n`` raw messages per input topic at 100 Hz and the node's overrides.

    Steady forces and a constant air; 0.1 s windows that publish a posterior each after a short
    warm-up (an in-process node, its callbacks called directly).
    """
    from rclpy.parameter import Parameter

    from bridge_shadow.bagio import encode_stamped_floats
    from bridge_shadow.contract import CHANNELS, FORCE_FRAMES, TEMPERATURE_FRAME

    stamp = 1_646_667_300 * 10**9 + np.arange(n, dtype=np.int64) * 10_000_000
    rng = np.random.default_rng(seed)
    wrench = np.zeros((n, 6))
    raws = []
    for ch in CHANNELS:
        wrench[:, 2] = 2.4e5 + rng.normal(0.0, 60.0, n)
        raws.append(encode_stamped_floats(stamp, FORCE_FRAMES[ch], wrench))
    raws.append(encode_stamped_floats(stamp, TEMPERATURE_FRAME, np.c_[np.full(n, 8.0), np.zeros(n)]))
    overrides = [
        Parameter("window_s", value=0.1),
        Parameter("window_min_samples", value=5),
        # every topic in each window, so the windows close as the topics pass their ends; the
        # node's quiet-input close (after max(this, window_s) of wall time without a message)
        # stays out of a run whose callbacks a busy machine stalls for a moment
        Parameter("topic_timeout_s", value=2.0),
        Parameter("warmup_windows", value=5),
        Parameter("traffic_hold_s", value=0.0),
    ]
    return raws, overrides


def _feed_ticks(node: Any, raws: list[list[bytes]], n: int) -> None:
    """Call the node's callbacks tick by tick (air, frc_01, frc_02), its drain timer every fifth tick."""
    callbacks = [node._callback(i) for i in range(3)]
    for j in range(n):
        if j % 5 == 0:
            node._on_drain_timer()
        for i in (2, 0, 1):
            callbacks[i](raws[i][j])


def test_the_message_that_closes_a_window_publishes_it_even_right_after_a_timers_drain() -> None:
    """The closing message drains at once, also when the drain timer ran a moment before.

    In-process (the subscription callbacks called directly, no DDS): 100 Hz forces and air, 0.1 s
    windows. Before each window's closing messages the drain timer has just run; the window's
    posterior must leave with its closing message, not with the next message
    10 ms later (the closing drain used to be skipped within ``MIN_DRAIN_GAP_S`` of any drain: a
    timer in that phase delayed every window of a live run by a sample period).
    """
    import rclpy

    from bridge_shadow.ros.node import ShadowNode

    n = 400
    raws, overrides = _steady_100hz(n, 4)
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ShadowNode(context=context, parameter_overrides=overrides)
        try:
            temp_cb, f1_cb, f2_cb = node._callback(2), node._callback(0), node._callback(1)
            late = 0
            for j in range(n):
                closing = j % 10 == 0 and j >= 100  # after the warm-up: a posterior per window
                if j % 5 == 0:
                    node._on_drain_timer()  # every 50 ms, and just before each closing message
                before = node.posteriors_published
                temp_cb(raws[2][j])
                f1_cb(raws[0][j])
                f2_cb(raws[1][j])
                if closing:
                    late += node.posteriors_published == before
            assert late == 0
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_a_subscriber_that_joins_late_is_sent_the_last_posterior() -> None:
    """The posterior's topics are TRANSIENT_LOCAL: a dashboard started after the node gets the last one.

    On a load-test day the node publishes a record's posterior at its quiet-input close and then
    nothing for hours; a viewer started in between saw nothing (the topics kept no history). A
    subscriber created after the node has published, asking for TRANSIENT_LOCAL durability, must
    receive the mean and covariance the node published last (in-process node, DDS on loopback).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64MultiArray

    from bridge_shadow.contract import COVARIANCE_TOPIC
    from bridge_shadow.ros.node import ShadowNode

    n = 300
    raws, overrides = _steady_100hz(n, 5)
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ShadowNode(context=context, parameter_overrides=overrides)
        viewer = rclpy.create_node("late_viewer", context=context)
        executor = SingleThreadedExecutor(context=context)
        try:
            _feed_ticks(node, raws, n)
            assert node.posteriors_published > 3
            # the last messages are ingested now, and the drain timer is stopped: on a busy CI machine
            # it fired before the viewer's first message, ingested them and published once more, so
            # the latched posterior was a later one than the one taken here
            node._on_drain_timer()
            node._drain_timer.cancel()
            sent_mean, sent_cov = node._last_posterior
            got: dict[str, Any] = {}
            latched = QoSProfile(
                depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
            )
            for topic in (MEAN_TOPIC, COVARIANCE_TOPIC):
                viewer.create_subscription(
                    Float64MultiArray, topic, lambda m, t=topic: got.__setitem__(t, m), latched
                )
            executor.add_node(node)
            executor.add_node(viewer)
            wait_until(lambda: executor.spin_once(timeout_sec=0.05) or len(got) == 2, TIMEOUT_S, "latched")
            mean, _ = array_from_msg(got[MEAN_TOPIC])
            cov, _ = array_from_msg(got[COVARIANCE_TOPIC])
            # the published message's values, decoded: the same floats (a copy through CDR)
            np.testing.assert_allclose(mean, sent_mean, rtol=1e-15, atol=0)
            np.testing.assert_allclose(cov.reshape(2, 2), sent_cov, rtol=1e-15, atol=0)
        finally:
            executor.shutdown()
            viewer.destroy_node()
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_quiet_inputs_close_the_open_window_on_the_wall_clock() -> None:
    """When every input stops, the windows holding the last data are closed and published anyway.

    Short windows so that the quiet limit, max(topic_timeout_s, window_s), is half a second of wall
    time. The posterior the node publishes without any flush call equals the offline replay of the
    same data (which closes the last window at its end).
    """
    from bridge_shadow.series import MonitoringData

    t0 = 1_646_667_300 * 10**9
    stamp = t0 + np.arange(1025, dtype=np.int64) * 10_000_000  # 100 Hz, ends 0.24 s into a window
    t_stamp = stamp[::10]
    rng = np.random.default_rng(3)
    temp = 8.0 + 0.2 * np.sin(np.arange(len(t_stamp)) / 10.0)
    force = np.c_[2.6e5 + 300 * np.interp(stamp, t_stamp, temp), 2.2e5 + 0 * stamp] + rng.normal(
        0, 60, (1025, 2)
    )
    data = MonitoringData.from_arrays(stamp, force, t_stamp, temp)
    overrides = {
        "window_s": 0.5,
        "topic_timeout_s": 0.2,
        "temperature_stale_s": 0.5,
        "window_min_samples": 10,
        "warmup_windows": 5,
    }
    config = load_config(None, overrides)
    ref = Shadow(config).run(data)
    assert len(ref.outputs) == 21 and ref.updates > 10
    raws = raw_inputs(data)
    topic, pos, _ = merge_log_order([stamp, stamp, t_stamp])
    with tempfile.TemporaryDirectory() as tmp:
        args = ["--ros-args", "--params-file", str(write_params_file(config.to_params(), Path(tmp)))]
        with Player() as player, NodeProcess(args) as node:
            player.wait_for_node(node, TIMEOUT_S)
            player.publish(topic, pos, raws, in_flight=200, node=node)
            n = len(ref.outputs)
            wait_until(
                lambda: player.received(MEAN_TOPIC) >= n, TIMEOUT_S, f"{n} posteriors", node.check_alive
            )
            mean, _ = array_from_msg(player.last(MEAN_TOPIC))
            # the 10 s record is shorter than traffic_hold_s: held whole for the traffic screen,
            # then screened, closed and published at the quiet-input close (as replay's flush)
            logged = lambda: f"decided the {ref.windows} window(s) still held" in node.output()  # noqa: E731
            wait_until(logged, TIMEOUT_S, "the node to log the quiet-input close", node.check_alive)
    np.testing.assert_allclose(mean, ref.mean_m, rtol=1e-12, atol=0)


def _paused_record_stream() -> dict:
    """Return a stream with a logger pause inside a record, its raw messages and its offline replay.

    1 Hz forces and air: a reference record, 3 h on a 20-min record whose logger paused over
    minutes 5-8 while a test car stood (minutes 3-10), the level 20 kN lower after the pause, and
    an hour on a 5-min record of its own.
    """
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.series import MonitoringData

    ns = 10**9
    u0 = load_surrogate().u0
    rng = np.random.default_rng(5)
    t0 = 1_650_000_000 * ns + 8 * 3600 * ns
    ref = t0 + np.arange(12 * 60) * ns
    later = t0 + 3 * 3600 * ns + np.arange(20 * 60) * ns
    f_ref = u0[:, None] + rng.normal(0.0, 20.0, (2, len(ref)))
    f_later = u0[:, None] + rng.normal(0.0, 20.0, (2, len(later)))
    f_later[:, 180:600] += 6000.0
    f_later[:, 480:] -= 20000.0
    keep = (later < later[0] + 300 * ns) | (later >= later[0] + 480 * ns)
    last = later[-1] + 3600 * ns + np.arange(5 * 60) * ns
    stamp = np.r_[ref, later[keep], last]
    force = np.c_[f_ref, f_later[:, keep], u0[:, None] - 20000.0 + rng.normal(0.0, 20.0, (2, len(last)))].T
    t_stamp = stamp[::10]
    temp = np.full(len(t_stamp), 12.0)
    data = MonitoringData.from_arrays(stamp, force, t_stamp, temp)
    return {
        "stamp": stamp,
        "force": force,
        "t_stamp": t_stamp,
        "temp": temp,
        "raws": raw_inputs(data),
        "pauses": [int(np.searchsorted(stamp, later[0] + 300 * ns)), int(np.searchsorted(stamp, last[0]))],
        "whole": Shadow(load_config()).run(data),
    }


def _feed(node, stream: dict, start: int, stop: int, quiet_at: tuple[int, ...] = ()) -> None:
    """Call the node's callbacks with messages ``start:stop`` of ``stream`` in stamp order.

    Before message ``j`` in ``quiet_at`` the inputs fall quiet for longer than the quiet limit (the
    arrival times aged, the drain timer run).
    """
    import time

    callbacks = [node._callback(i) for i in range(3)]
    stamp, t_stamp, raws = stream["stamp"], stream["t_stamp"], stream["raws"]
    j_t = int(np.searchsorted(t_stamp, stamp[start], side="left")) if start else 0
    for j in range(start, stop):
        if j in quiet_at:
            node.drain()
            node._arrival = [time.monotonic() - 1000.0] * 3
            node._on_drain_timer()
        while j_t < len(t_stamp) and t_stamp[j_t] <= stamp[j]:
            callbacks[2](raws[2][j_t])
            j_t += 1
        callbacks[0](raws[0][j])
        callbacks[1](raws[1][j])


def test_a_quiet_input_close_inside_a_record_is_undone_when_the_record_goes_on() -> None:
    """A logger pause inside a record, longer than the quiet limit: live ends as the offline replay.

    In-process (the callbacks called directly, the quiet limit passed by ageing the arrival times;
    ``_paused_record_stream``). The node's quiet-input close at the pause ended the record there
    (flushed as a replay's end), and the car's half before it stayed data: the live posterior
    ended 0.11 mm off the offline replay of the same stream. Now the close is undone when the
    data goes on within ``gap_s`` (the state from before it restored), and the node ends where
    the offline replay does; the close before the record an hour on stands.
    """
    import rclpy

    from bridge_shadow.ros.node import ShadowNode

    stream = _paused_record_stream()
    stamp, force, t_stamp, temp, pauses, whole = (
        stream[k] for k in ("stamp", "force", "t_stamp", "temp", "pauses", "whole")
    )
    # the premise: ended at the pause (what the node did), the stream reads otherwise
    split = Shadow(load_config())
    for a, b in zip([0, pauses[0]], [pauses[0], len(stamp)], strict=True):
        for c in range(2):
            split.ingest_forces(c, stamp[a:b], force[a:b, c])
        inside = (t_stamp >= stamp[a]) & (t_stamp <= stamp[b - 1])
        split.ingest_temperature(t_stamp[inside], temp[inside])
        split.poll()
        split.flush()
    assert np.max(np.abs(split.posterior[0] - whole.mean_m)) > 1e-4

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ShadowNode(context=context)
        try:
            _feed(node, stream, 0, len(stamp), quiet_at=tuple(pauses))
            node.close_open_windows()
            # the same code on the same windows, in another order of calls: rounding only
            np.testing.assert_allclose(node._last_posterior[0], whole.mean_m, rtol=1e-9, atol=0)
            np.testing.assert_allclose(node._last_posterior[1], whole.covariance_m2, rtol=1e-9, atol=0)
            assert (node.quiet_flushes, node.quiet_flushes_undone) == (2, 1)
            shown = [out.index for out in node.history]
            assert len(shown) == len(set(shown)), "the undone close's outputs left the history"
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_a_node_stopped_after_a_quiet_close_resumes_the_record_as_the_offline_replay(tmp_path: Path) -> None:
    """Stopped during the logger pause (after its quiet-input close), restarted, the data goes on.

    The checkpoint written on exit holds the state from before the close; the resumed node, its
    inputs still quiet, closes the held record again (the same outputs as before the stop), and
    when the data comes back within ``gap_s`` goes on with the record: it ends where the offline
    replay does. Written after the close, the checkpoint had the record ended at the pause.
    """
    import time

    import rclpy
    from rclpy.parameter import Parameter

    from bridge_shadow.ros.node import ShadowNode

    stream = _paused_record_stream()
    pause = stream["pauses"][0]
    ckpt = tmp_path / "shadow.ckpt"
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        params = [Parameter("checkpoint_path", value=str(ckpt))]
        node = ShadowNode(context=context, parameter_overrides=params)
        try:
            _feed(node, stream, 0, pause)
            node.drain()
            node._arrival = [time.monotonic() - 1000.0] * 3  # quiet: the close, then SIGTERM
            node._on_drain_timer()
            assert node.quiet_flushes == 1
            before = [(out.index, out.mean_m.copy()) for out in node.history]
            assert node.save_on_exit() == ckpt
        finally:
            node.destroy_node()
        node = ShadowNode(context=context, parameter_overrides=params)
        try:
            assert node.shadow.holds_data  # the record's windows, held as before the close
            node._born = time.monotonic() - 1000.0  # quiet since the start
            node._on_drain_timer()
            assert node.quiet_flushes == 1
            again = [(out.index, out.mean_m) for out in node.history]
            assert [k for k, _ in again] == [k for k, _ in before[-len(again) :]]
            for (_, a), (_, b) in zip(again, before[-len(again) :], strict=True):
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)
            _feed(node, stream, pause, len(stream["stamp"]), quiet_at=(stream["pauses"][1],))
            node.close_open_windows()
            whole = stream["whole"]
            np.testing.assert_allclose(node._last_posterior[0], whole.mean_m, rtol=1e-9, atol=0)  # rounding
            assert node.quiet_flushes_undone == 1
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_the_flush_services_checkpoint_lets_the_next_bag_go_on_with_the_record(tmp_path: Path) -> None:
    """A recording split into bags inside a record, played live one after the other with a checkpoint.

    At each bag's end ``replay --live`` calls the node's flush service, then stops it. Its
    checkpoint (at the flush, and again at exit) held the state after the end-of-bag close: the
    next bag's first seconds of the window cut there came late (7022 messages of the real
    records split 0.1 h into the first record). The close is provisional now, as the quiet-input
    one: both writes hold the state before it, and the next node ends where the offline replay of
    the whole stream does.
    """
    import json
    from types import SimpleNamespace

    stream = _paused_record_stream()
    cut = stream["pauses"][0] - 90  # inside the later record, before its logger paused
    ckpt = tmp_path / "shadow.ckpt"
    with _in_process_node(checkpoint_path=str(ckpt)) as node:
        _feed(node, stream, 0, cut)
        answer = node._on_flush(None, SimpleNamespace(success=False, message=""))
        assert answer.success and json.loads(answer.message)["windows"]["closed"] > 0
        assert node.save_on_exit() == ckpt  # the stop after the flush: the same state again
    with _in_process_node(checkpoint_path=str(ckpt)) as node:
        assert node.shadow.holds_data  # the record's open window, held as before the close
        _feed(node, stream, cut, len(stream["stamp"]), quiet_at=tuple(stream["pauses"]))
        node.close_open_windows()
        assert node.shadow.rejected.get("late", 0) == 0
        np.testing.assert_allclose(node._last_posterior[0], stream["whole"].mean_m, rtol=1e-9, atol=0)
        # the report lists every rejected window, the first node's too (what `replay --live` prints)
        assert node.report()["rejected_windows"] == stream["whole"].rejected_windows() != []


@contextlib.contextmanager
def _in_process_node(**parameters: object) -> Iterator[Any]:
    """A ``ShadowNode`` in a context of its own, its callbacks called directly (no DDS traffic)."""
    import rclpy
    from rclpy.parameter import Parameter

    from bridge_shadow.ros.node import ShadowNode

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        params = [Parameter(k, value=v) for k, v in parameters.items()]
        node = ShadowNode(context=context, parameter_overrides=params)
        try:
            yield node
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_a_settlement_event_reaches_the_nodes_log_once(tmp_path: Path) -> None:
    """The node's log said nothing of a 20 mm settlement it found (only /diagnostics did).

    Whoever reads the log (journald, the fleet's relayed output) now reads a WARN line per event,
    with its kind, time and size (95 %), once however often /diagnostics goes out.
    """
    from types import SimpleNamespace

    stream = _paused_record_stream()
    with _in_process_node() as node:
        lines: list[str] = []
        log = SimpleNamespace(warn=lines.append, warning=lines.append, info=lines.append, error=lines.append)
        node.get_logger = lambda: log  # type: ignore[method-assign]
        _feed(node, stream, 0, len(stream["stamp"]), quiet_at=tuple(stream["pauses"]))
        node.close_open_windows()
        node.publish_diagnostics()
        node.publish_diagnostics()
        events = node.shadow.diagnostics()["events"]
        said = [line for line in lines if line.startswith("settlement event: ")]
        assert events and len(said) == len(events)
        for e, line in zip(events, said, strict=True):
            assert e["time"] in line and f"{1e3 * e['size_m'][0]:+.3f}" in line and "(95 %" in line


def test_topic_parameters_rename_the_node_graph(short_bag: Path, short_direct, tmp_path: Path) -> None:
    """The node subscribes and publishes under the topic_* parameters; the posterior is unchanged."""
    from renamed_topics import RENAMED, renamed_bag

    from bridge_shadow.contract import FLOAT_ARRAY_TYPE

    direct = short_direct
    renamed = renamed_bag(short_bag, tmp_path / "renamed")
    live = run_live(renamed, overrides={**OVERRIDES, **RENAMED}, out=tmp_path / "out", timeout_s=TIMEOUT_S)
    np.testing.assert_allclose(live["posterior"]["mean_m"], direct.mean_m, rtol=1e-12, atol=0)
    assert live["messages"]["used_by_topic"] == direct.used
    wanted = {RENAMED["topic_mean"]: FLOAT_ARRAY_TYPE, MEAN_TOPIC: FLOAT_ARRAY_TYPE}
    out = read_raw_topics(tmp_path / "out", wanted)
    assert MEAN_TOPIC not in out and len(out[RENAMED["topic_mean"]][1]) == len(direct.outputs)


def test_live_replay_of_a_bag_without_temperature_runs_uncompensated(
    bag: Path, tmp_path: Path, capfd
) -> None:
    """As the direct mode: no temperature topic is not an error, it is a loud uncompensated run."""
    from bridge_shadow.contract import FORCE_TOPICS

    forces = {t: INPUT_TOPICS[t] for t in FORCE_TOPICS.values()}
    forces_only = _head_of(bag, tmp_path / "forces_only", forces, 3 * 3600 * 10**9)  # three hours say it
    import json

    from bridge_shadow.cli import main
    from bridge_shadow.commands.replay import _summary

    params = tmp_path / "params.yaml"  # the OVERRIDES, as a parameter file for the command line
    params.write_text(
        f"bridge_shadow:\n  ros__parameters:\n    window_min_samples: {OVERRIDES['window_min_samples']}\n"
    )
    ref = Shadow(load_config(params)).run(read_monitoring(forces_only, required=list(INPUT_TOPICS)[:2]))
    capfd.readouterr()
    assert main(["replay", str(forces_only), "--live", "--params", str(params), "--json"]) == 0
    out, err = capfd.readouterr()
    live = json.loads(out)
    js = ref.to_json()
    assert js["windows"]["updates"] > 100 and live["windows"] == js["windows"]
    assert live["windows"]["uncompensated"] == live["windows"]["updates"]
    assert any("temperature" in w for w in live["warnings"]) and live["warnings"] == js["warnings"]
    np.testing.assert_allclose(live["posterior"]["mean_m"], ref.mean_m, rtol=1e-12, atol=0)
    # and the command line says so, in its summary and on stderr, as the direct replay does
    assert "lambda inf" in _summary(live) and "WARN: no air temperature" in err


@pytest.mark.realdata
def test_live_replay_of_the_real_lowering_ends_at_the_direct_posterior(
    munich_data: Path, tmp_path: Path
) -> None:
    """The final posterior reaches the topics, with the last windows or on its own.

    The lowered record's windows are held after the 44-min gap until the end
    (``Shadow._release_fresh``); the flush's refit then lands on the last of them.
    """
    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.importers import import_csv

    folder = munich_data / "Settlements"
    data, _ = import_csv(
        [
            folder / "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
            folder / "UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
            folder / "TemperatureData2022-04-11.zip",
        ]
    )
    # every 10th sample (10 Hz): the live path is the same at any rate, and a tenth of the messages
    # keeps the test short (test_replay_rates plays a record at several rates)
    data = data.select(lambda stamps: np.arange(len(stamps)) % 10 == 0)
    bag = write_monitoring(tmp_path / "real", data)
    direct = Shadow(load_config()).run(read_monitoring(bag))
    live = run_live(bag, out=tmp_path / "out", timeout_s=TIMEOUT_S)
    assert len(direct.events) == 1 and live["events"][0]["window"] == direct.events[0].window
    # the traffic screen's report (the test car's windows cut), as the direct replay's JSON has it:
    # counts, stamps and the hold (a parameter) exactly; the loads of parked vehicles to rounding
    traffic = direct.to_json()["traffic"]
    assert traffic["windows_cut"] > 0
    assert {k: v for k, v in live["traffic"].items() if k != "parked"} == {
        k: v for k, v in traffic.items() if k != "parked"
    }
    assert len(live["traffic"]["parked"]) == len(traffic["parked"])
    for got, want in zip(live["traffic"]["parked"], traffic["parked"], strict=True):
        assert got["since_ns"] == want["since_ns"] and got["until_ns"] == want["until_ns"]
        if want["load_n"] is not None:
            np.testing.assert_allclose(got["load_n"], want["load_n"], rtol=1e-12)
    np.testing.assert_allclose(live["posterior"]["mean_m"], direct.mean_m, rtol=1e-12, atol=0)
    np.testing.assert_allclose(live["posterior"]["covariance_m2"], direct.covariance_m2, rtol=1e-12, atol=0)
    # what a subscriber saw last is that final posterior (one message per window, one when the
    # 10 mm record, after the gap, was held for the traffic screen (its interval widened at once),
    # and one more when the flush's refit came after the last window)
    raw = read_raw_topics(tmp_path / "out", {MEAN_TOPIC: FLOAT_ARRAY_TYPE})[MEAN_TOPIC][1]
    assert live["live"]["windows_published"] + 1 <= len(raw) <= live["live"]["windows_published"] + 2
    from std_msgs.msg import Float64MultiArray

    last, _ = array_from_msg(deserialize_message(raw[-1], Float64MultiArray))
    np.testing.assert_allclose(last, direct.mean_m, rtol=1e-12, atol=0)


def test_one_wild_stamp_does_not_hold_its_topic_back_until_the_others_closed_its_windows() -> None:
    """A force message stamped a day ahead (a logger's clock glitch) among 100 Hz messages, in-process.

    The node holds a message whose stamp is ahead of what the other topics delivered (they may
    still be in flight), and the messages after it in its topic, for ``REORDER_HOLD_S`` of wall time.
    A stamp a day ahead is no transport skew: the topic stalled while the others closed its windows,
    and its messages came ``late`` (about 8,000 of a fast live replay's; the direct replay: one
    ``clock_jump``, none late). A stamp more than ``clock_jump_s`` ahead of the others now goes on
    at once, to the gate that rejects it, and the node ends where the direct replay does.
    """
    import rclpy

    from bridge_shadow.bagio import decode_stamped_floats, encode_stamped_floats
    from bridge_shadow.contract import FORCE_FRAMES
    from bridge_shadow.ros.node import ShadowNode
    from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

    n, wild = 600, 300
    raws, overrides = _steady_100hz(n, 6)
    stamp, _, values = decode_stamped_floats(raws[0], 6)
    stamp = stamp.copy()
    stamp[wild] += 86_400 * 10**9
    raws[0] = encode_stamped_floats(stamp, FORCE_FRAMES["frc_01"], values)
    f2, air = decode_stamped_floats(raws[1], 6), decode_stamped_floats(raws[2], 2)
    log = f2[0]  # the arrival order: every topic's message j at tick j
    forces = {
        "frc_01": ForceSeries(stamp, values[:, 2], FORCE_FRAMES["frc_01"], log),
        "frc_02": ForceSeries(f2[0], f2[2][:, 2], FORCE_FRAMES["frc_02"], log),
    }
    data = MonitoringData(forces, TemperatureSeries(air[0], air[2][:, 0], log_ns=log))
    config = {p.name: p.value for p in overrides}
    direct = Shadow(load_config(None, config)).run(data)
    assert direct.rejected["clock_jump"] == 1 and direct.rejected["late"] == 0
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ShadowNode(context=context, parameter_overrides=overrides)
        try:
            _feed_ticks(node, raws, n)
            node.close_open_windows()
            assert node.shadow.rejected["late"] == 0 and node.shadow.rejected["clock_jump"] == 1
            np.testing.assert_allclose(node.shadow.posterior[0], direct.mean_m, rtol=1e-9, atol=1e-12)
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_a_malformed_message_played_live_is_dropped_and_said(bag: Path, tmp_path: Path) -> None:
    """One truncated force message in an hour of the bundled day, played live: dropped, counted and said.

    The node drops what it cannot decode, as it must with live data; the replay's JSON counted it
    (``live.malformed``) with no warning, where the direct replay refuses the bag.
    """
    from bridge_shadow.bagio import BagOutputWriter

    out = tmp_path / "one_malformed"
    with BagOutputWriter(out) as writer:
        for topic, (log_ns, raws) in read_raw_topics(bag, INPUT_TOPICS).items():
            keep = log_ns < log_ns[0] + 3600 * 10**9
            kept = [r for r, k in zip(raws, keep, strict=True) if k]
            if topic == "/bridge/frc_01/force":
                kept[len(kept) // 2] = kept[len(kept) // 2][:20]  # cut short inside its header
            writer.write_many_raw(topic, INPUT_TOPICS[topic], log_ns[keep], kept)
    live = run_live(out, overrides=OVERRIDES, timeout_s=TIMEOUT_S)
    assert live["live"]["malformed"] == 1
    (line,) = [w for w in live["warnings"] if "malformed" in w]
    assert line.startswith("1 message(s) of the bag could not be decoded")
