"""The same posterior at any pace: direct replay, live replay as fast as taken, and paced live replays.

The node ingests what DDS delivers, a window or less at a time; the direct replay feeds a bag in
chunks of many windows. Both must judge every window against the estimate of the windows before
it, so that the chunking (and with it the live ``--rate``) cannot change a decision: on the first
sunny morning of a demo-like bag the step detector fires, and whether it fires used to depend on
whether the window after the warm-up came in the same chunk as the warm-up (the direct replay
judged it against the prior, the node against the warm-up's estimate).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import placeholder_surrogate

#: The demo bag's effects (bags/README.md), on its first 9 hours: the first sunny morning trips the
#: detector, so the comparison covers events and held windows, not only a quiet estimate.
DEMO_EFFECTS = {
    "settlement_offset": 7e-4,
    "vertical_gradient": 4.0,
    "transverse_gradient": 3.0,
    "traffic": 2.5e4,
}


def _innovations(monkeypatch: pytest.MonkeyPatch, data: Any, chunk: int) -> list[tuple[int, tuple]]:
    """The innovation ``y - u0 - g(T) - A x`` of every judged window, in order, at one chunking."""
    seen: list[tuple[int, tuple]] = []
    innovation = Shadow._innovation

    def spy(self: Shadow, w: Any) -> tuple[float, float]:
        v = innovation(self, w)
        seen.append((w.k, v))
        return v

    monkeypatch.setattr(Shadow, "_innovation", spy)
    from test_estimate_pipeline import small_config

    Shadow(small_config(), placeholder_surrogate()).run(data, chunk=chunk)
    monkeypatch.undo()
    return seen


def test_every_window_is_judged_against_the_windows_before_it_at_any_chunking(monkeypatch) -> None:
    from test_estimate_pipeline import synthetic

    # a 2 mm settlement: against the prior the first window after the warm-up would be kilonewtons off
    data = synthetic(minutes=16, rate=2, x_m=(2e-3, -2e-3))
    whole = _innovations(monkeypatch, data, chunk=10**7)  # the whole record in one chunk
    parts = _innovations(monkeypatch, data, chunk=60)  # a third of a window at a time, as the node
    assert [k for k, _ in parts] == [k for k, _ in whole] and len(whole) >= 5
    np.testing.assert_allclose([v for _, v in parts], [v for _, v in whole], rtol=1e-9, atol=1e-9)
    assert max(abs(np.array(whole[0][1]))) < 1e3  # judged against the warm-up's estimate of x


@pytest.mark.ros
def test_live_replay_at_several_rates_ends_at_the_direct_posterior(synth_bag) -> None:
    pytest.importorskip("rclpy")
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.ros.live_replay import run_live

    # the sun of the demo and a 2 mm step at 06:00 (an event the live run must find at its window)
    step = [(0.25, -0.002, -0.002)]
    bag: Path = synth_bag(days=0.375, rate_hz=0.1, seed=1, effects=DEMO_EFFECTS, surrogate="file", steps=step)
    data = read_monitoring(bag)
    direct = Shadow(load_config()).run(data).to_json()
    assert direct["events"], "a comparison of events needs some"
    logs = np.concatenate([*(s.log_ns for s in data.forces.values()), data.temperature.log_ns])
    span_s = (int(logs.max()) - int(logs.min())) / 1e9
    for rate in (20_000.0, 80_000.0):  # 1.6 s and 0.4 s of pacing (as fast as taken: test_ros_node)
        live = run_live(bag, rate=rate, timeout_s=30.0)
        assert live["live"]["publish_s"] >= 0.95 * span_s / rate  # it kept the pace asked for
        np.testing.assert_allclose(live["posterior"]["mean_m"], direct["posterior"]["mean_m"], rtol=1e-12)
        np.testing.assert_allclose(
            live["posterior"]["covariance_m2"], direct["posterior"]["covariance_m2"], rtol=1e-12
        )
        assert live["windows"] == direct["windows"], rate
        assert [e["window"] for e in live["events"]] == [e["window"] for e in direct["events"]], rate
        np.testing.assert_allclose(
            [e["size_m"] for e in live["events"]], [e["size_m"] for e in direct["events"]], rtol=1e-9
        )


@pytest.mark.ros
def test_live_replay_keeps_dds_on_loopback_itself(monkeypatch, tmp_path: Path) -> None:
    """Outside make (no ROS_* set), --live keeps DDS on loopback in a domain of its own.

    Before rclpy starts it confines this process and the node alike; an explicit range is kept.
    """
    pytest.importorskip("rclpy")
    from bridge_shadow.bagio import BagError
    from bridge_shadow.ros.live_replay import run_live

    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE")
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    with pytest.raises(BagError):  # the bag is opened after the confinement, before any rclpy work
        run_live(tmp_path / "missing")
    import os

    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert 20 <= int(os.environ["ROS_DOMAIN_ID"]) < 220
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")  # a monitoring network's choice
    with pytest.raises(BagError):
        run_live(tmp_path / "missing")
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"


@pytest.mark.ros
def test_a_discovery_timeout_says_where_it_looked(monkeypatch) -> None:
    pytest.importorskip("rclpy")
    from bridge_shadow.ros.launcher import NodeError
    from bridge_shadow.ros.live_replay import _discover

    class Deaf:
        def wait_for_node(self, node: object, timeout_s: float) -> float:
            raise NodeError(f"timed out after {timeout_s:g} s waiting for the bridge_shadow node to appear")

    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")
    monkeypatch.setenv("ROS_DOMAIN_ID", "7")
    with pytest.raises(NodeError) as err:
        _discover(Deaf(), None, 60.0)  # type: ignore[arg-type]
    text = str(err.value)
    assert "\n" not in text and text.startswith("timed out after 60 s")
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET, ROS_DOMAIN_ID=7" in text
    assert "unset ROS_AUTOMATIC_DISCOVERY_RANGE" in text


@pytest.mark.ros
def test_a_lost_answer_to_a_query_is_asked_again_and_a_flush_is_waited_for_once(monkeypatch) -> None:
    """A status or history answer lost in DDS is asked for again; a flush is never sent twice.

    Fast DDS can drop a service's answer while the node's response writer is not yet matched to
    the caller's reader (ros2/rclpy#1181): the future never completes. A query is asked again
    every ``RESEND_S`` until the call's timeout, the first answer to any request taken (a slow one
    too) and the others withdrawn; the flush (not idempotent) times out.
    """
    pytest.importorskip("rclpy")
    import threading

    from rclpy.task import Future
    from std_srvs.srv import Trigger

    from bridge_shadow.ros import live_replay
    from bridge_shadow.ros.launcher import NodeError

    monkeypatch.setattr(live_replay, "RESEND_S", 0.05)

    class Client:
        """A service client whose first answer is lost; later requests are answered at once."""

        def __init__(self) -> None:
            self.sent: list[Future] = []
            self.withdrawn: list[Future] = []

        def call_async(self, request: object) -> Future:
            future = Future()
            self.sent.append(future)
            if len(self.sent) >= 2:
                future.set_result(Trigger.Response(success=True, message='{"taken": [4, 5, 1]}'))
            return future

        def remove_pending_request(self, future: Future) -> None:
            self.withdrawn.append(future)

    client = Client()
    lost = client.call_async(Trigger.Request())
    answer = live_replay.Player._answer(None, lost, None, 10.0, client=client)  # type: ignore[arg-type]
    assert answer["taken_total"] == 10
    assert client.withdrawn == [lost] and len(client.sent) == 2  # the unanswered one, once answered
    slow = Client()  # an answer that comes after RESEND_S is still taken
    first = slow.call_async(Trigger.Request())
    threading.Timer(
        0.12, lambda: first.set_result(Trigger.Response(success=True, message='{"taken": [1]}'))
    ).start()
    slow.call_async = lambda request: slow.sent.append(Future()) or slow.sent[-1]  # never answered
    assert live_replay.Player._answer(None, first, None, 10.0, client=slow)["taken_total"] == 1  # type: ignore[arg-type]
    assert len(slow.sent) >= 2 and first not in slow.withdrawn and set(slow.withdrawn) == set(slow.sent[1:])
    flush = Client()
    with pytest.raises(NodeError, match=r"timed out after 0\.3 s"):
        live_replay.Player._answer(None, flush.call_async(Trigger.Request()), None, 0.3)  # type: ignore[arg-type]
    assert len(flush.sent) == 1 and not flush.withdrawn


def test_the_players_flow_control_counts_from_what_the_node_had_taken_before() -> None:
    """A second bag played to the same node keeps at most ``in_flight`` messages untaken.

    The node's count of taken messages is its own since it started; compared with one call's
    count alone, a second call never waited and overflowed the node's readers ("cannot publish
    data" after 40,200 messages of a second bag, a helper session feeding one node a day in bags).
    A fake node here takes messages only as it is asked, half the limit each time.
    """
    pytest.importorskip("rclpy")
    from bridge_shadow.ros.live_replay import Player

    class FakeNodePlayer(Player):
        def __init__(self, in_flight: int) -> None:  # no rclpy graph: the accounting alone
            self.published = self.node_taken = self.worst = 0
            self.step = in_flight // 2
            self.publishers = [self] * 3
            self.status_client = self

        def publish(self, raw: bytes) -> None:
            self.published += 1
            self.worst = max(self.worst, self.published - self.node_taken)

        def call_async(self, request: Any) -> None:
            return None

        def _answer(self, future: Any, node: Any, timeout_s: float = 30.0, client: Any = None) -> dict:
            self.node_taken = min(self.published, self.node_taken + self.step)
            return {"taken": [self.node_taken, 0, 0], "taken_total": self.node_taken}

        def taken(self, node: Any = None, timeout_s: float = 30.0) -> int:
            return self.node_taken

    limit = 40
    player = FakeNodePlayer(limit)
    n = 1000
    piece = (np.zeros(n, np.int64), np.zeros(n, np.int64), [[b"x"]] * 3, np.arange(n, dtype=np.int64))
    for _ in range(2):  # the same node, two bags
        player.publish_pieces([piece], in_flight=limit)
        assert player.published % n == 0 and player.worst <= limit
        player.node_taken = player.published  # the node catches up between the bags
