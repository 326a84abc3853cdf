"""A live replay's checkpoint chain holds the air past a bag's last force, as the offline chain does.

``replay --live --checkpoint`` of a bag holding the day's air (``import-csv`` of a record with the
day's temperature file) played that air to the node, whose data clock then ran hours past the
record, and the next bag's forces were all ``late`` (the real records: 144,000 forces of a record
230 min on, exit 1, the chain ending at the earlier state). ``ros.live_chain`` gives the player the
offline chain's rule (``replay.air_tail``): the checkpoint's held air published merged with the
bag, the air past the bag's last force held, the checkpoint written before it. Here the pieces,
the checkpoint's copy and write, and a chain crossing between the offline and the live replay;
the real records' case is in ``test_later_records_cli.py``.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from test_air_tail import _pieces, _record

from bridge_shadow.bagio import encode_stamped_floats, write_monitoring
from bridge_shadow.bagio.cdr import decode_stamped_floats
from bridge_shadow.bagio.merged import MergedStream
from bridge_shadow.bagio.reader import read_monitoring
from bridge_shadow.bagio.stream import MonitoringStream
from bridge_shadow.cli import main
from bridge_shadow.contract import CHANNELS
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.state.checkpoint import load_state
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.replay.air_tail import AirTail, air_piece
from bridge_shadow.ros.live_chain import AIR, RawAirTail, decode_air, merge_held, prepare, raw_piece
from bridge_shadow.ros.live_replay import _merged_pieces
from bridge_shadow.series import MonitoringData, TemperatureSeries

_FLOATS = (6, 6, 2)  # WrenchStamped, WrenchStamped, Temperature after the header


def _raw_pieces(pieces: list[MonitoringData]) -> list[tuple]:
    """The player's raw pieces of decoded ``pieces``: each topic's messages serialized, in log order."""
    return [raw_piece(p) for p in pieces]


def _published(pieces: list[tuple]) -> list[tuple[int, int, int, float]]:
    """Every message of raw ``pieces`` as (log_ns, topic, stamp_ns, value) in publishing order.

    Compared exactly: stamps are integers, the values copies through serialization.
    """
    out = []
    for topic, pos, raws, logs in pieces:
        for i, j, lg in zip(topic.tolist(), pos.tolist(), logs.tolist(), strict=True):
            stamp, _, values = decode_stamped_floats([raws[i][j]], _FLOATS[i])
            out.append((int(lg), i, int(stamp[0]), float(values[0, 2 if i < AIR else 0])))
    return out


def _per_topic(messages: list[tuple[int, int, int, float]]) -> list[list[tuple[int, int, float]]]:
    return [[(lg, s, v) for lg, t, s, v in messages if t == k] for k in range(3)]


def _decoded(pieces: list[MonitoringData]) -> list[tuple[int, int, int, float]]:
    """The messages of decoded ``pieces`` as ``_published`` gives them (order within a topic kept)."""
    out = []
    for p in pieces:
        for k, ch in enumerate(CHANNELS):
            f = p.forces[ch]
            rows = zip(f.log_ns, f.stamp_ns, f.force_n, strict=True)
            out += [(int(a), k, int(b), float(c)) for a, b, c in rows]
        t = p.temperature
        rows = zip(t.log_ns, t.stamp_ns, t.temp_c, strict=True)
        out += [(int(a), AIR, int(b), float(c)) for a, b, c in rows]
    return out


@pytest.mark.parametrize("limit", [None, 30])
def test_the_player_holds_the_air_the_offline_chain_holds(limit: int | None) -> None:
    """``RawAirTail`` on raw pieces passes and holds what ``AirTail`` does on the decoded ones."""
    pieces = _pieces(np.random.default_rng(5))
    kw = {} if limit is None else {"limit": limit}
    offline, live = AirTail(pieces, **kw), RawAirTail(_raw_pieces(pieces), **kw)
    passed_offline, passed_live = list(offline), list(live)
    assert live.released == offline.released and (limit is None) == (live.released == 0)
    assert _per_topic(_published(passed_live)) == _per_topic(_decoded(passed_offline))
    tail, bad = decode_air(live.tail)
    assert bad == 0 and tail is not None and offline.tail is not None and live.n_tail == len(tail)
    for key in ("log_ns", "stamp_ns", "temp_c", "variance"):
        np.testing.assert_array_equal(getattr(tail, key), getattr(offline.tail, key))  # copies
    # what went on is in log order, the tail after it
    logs = [m[0] for m in _published(passed_live)]
    assert logs == sorted(logs) and logs[-1] <= int(tail.log_ns[0])


def test_the_held_air_is_published_as_the_merged_stream_reads_it(tmp_path: Path) -> None:
    """``merge_held``: the checkpoint's air with the next bag, as ``MergedStream(held=...)`` reads them."""
    one = write_monitoring(tmp_path / "one", _record(0, 30, np.array([2e-4, -1e-4]), 6.0, 1))
    two = write_monitoring(tmp_path / "two", _record(7200, 30, np.array([-8e-3, -8e-3]), 6.0, 2))
    held = read_monitoring(one).temperature
    held = held.take(np.asarray(held.log_ns) >= held.log_ns[40])  # the air past a record: from 40 min on
    with MonitoringStream(two, batch=97) as stream:
        live = _published(list(merge_held(_merged_pieces(stream), held)))
    with MergedStream([two], held=air_piece(held, CHANNELS), batch=97) as merged:
        offline = _decoded(list(merged))
    assert _per_topic(live) == _per_topic(offline)
    assert [m[0] for m in live] == sorted(m[0] for m in live)
    # at equal log time the held copy goes first (the bag's own copy of the day's air is then the duplicate)
    first_air = [m for m in live if m[1] == AIR]
    assert len(first_air) == len(held) + 360
    for a, b in itertools.pairwise(first_air):
        assert a[0] < b[0] or (a[0] == b[0] and a[2] == b[2])  # equal log: the same reading twice


def test_the_nodes_copy_drops_the_held_air_and_the_end_writes_the_tail(tmp_path: Path) -> None:
    """``prepare`` copies the checkpoint without its held air; ``finish`` writes a state with a new tail."""
    one = write_monitoring(tmp_path / "one", _record(0, 30, np.array([2e-4, -1e-4]), 6.0, 1))
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(one), "--checkpoint", str(ck)]) == 0
    config, surrogate = load_config(None), load_surrogate()
    chain = prepare(config, surrogate, ck, tmp_path / "node.npz")
    held = Shadow.resume(ck).held_air
    assert chain.held is not None and held is not None and len(chain.held) == len(held) > 200
    np.testing.assert_array_equal(chain.held.stamp_ns, held.stamp_ns)  # integer ns
    assert "held_air" not in load_state(tmp_path / "node.npz") and chain.notes == []
    state = load_state(tmp_path / "node.npz")
    tail = held.take(np.arange(len(held)) < 7)
    # load-cell messages played and none used (older than the checkpoint's data): the file as it was
    before = ck.read_bytes()
    assert chain.finish(state, tail, [{"signature": "s", "bag": "x"}], forces_fed=5) is None
    assert ck.read_bytes() == before  # left untouched: compared byte for byte
    chain.finish(state, tail, [{"signature": "s", "bag": "x"}])
    np.testing.assert_array_equal(Shadow.resume(ck).held_air.temp_c, tail.temp_c)  # held, copied
    assert [e["bag"] for e in Shadow.resume(ck).taken_bags] == [str(one), "x"]  # the first run's, this one
    chain.finish(state, None)
    assert Shadow.resume(ck).held_air is None
    # an unusable checkpoint is set aside (checkpoint_unusable: fresh) and said, the node starts fresh
    ck.write_bytes(b"not a checkpoint")
    fresh = prepare(config.replace(checkpoint_unusable="fresh"), surrogate, ck, tmp_path / "node2.npz")
    assert not ck.exists() and not (tmp_path / "node2.npz").exists() and fresh.held is None
    assert len(fresh.notes) == 1 and "set aside" in fresh.notes[0]


def test_the_checkpoint_service_needs_a_checkpoint_path() -> None:
    """A node without ``checkpoint_path`` answers the checkpoint service with a failure and the reason."""
    from types import SimpleNamespace

    from test_ros_node import _in_process_node

    with _in_process_node() as node:
        answer = node._on_checkpoint(None, SimpleNamespace(success=True, message=""))
        assert not answer.success and "checkpoint_path is empty" in answer.message


def test_a_live_replay_in_a_checkpoint_chain_is_one_merged_replay(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """Offline, live, offline through one checkpoint: the merged replay's answer, nothing late.

    Three records two hours apart, each bag with the day's air (6 h). The live replay of the second
    took the first bag's held air first and its own air to 6 h: every one of its forces ``late``,
    exit 1. Now it holds what the offline chain holds, and the third bag's offline replay from its
    checkpoint ends where one replay of the three bags does.
    """
    steps = ([2e-4, -1e-4], [-8e-3, -8e-3], [-1.6e-2, -1.6e-2])
    bags = [
        write_monitoring(tmp_path / f"b{k}", _record(7200 * k, 30, np.array(s), 6.0, k + 1))
        for k, s in enumerate(steps)
    ]

    def replay(*args: object, rc: int = 0) -> dict:
        assert main(["replay", *map(str, args), "--json"]) == rc
        return json.loads(capfd.readouterr().out)  # fd-level: the player's executor needs a real stderr

    ck, offline_ck = tmp_path / "ck.npz", tmp_path / "offline.npz"
    replay(bags[0], "--checkpoint", ck)
    replay(bags[0], "--checkpoint", offline_ck)
    live = replay(bags[1], "--live", "--checkpoint", ck)
    before = ck.read_bytes()
    again = replay(bags[1], "--live", "--checkpoint", ck)  # taken by the live run: no node, nothing written
    assert again["messages"]["total"] == 0 and [e["bag"] for e in again["already_taken"]] == [str(bags[1])]
    assert ck.read_bytes() == before  # left untouched: compared byte for byte
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(again["posterior"][key], live["posterior"][key], rtol=1e-9)
    offline = replay(bags[1], "--checkpoint", offline_ck)
    merged = replay(bags[0], bags[1])
    assert live["rejected"]["late"] == 0 and live["messages"]["used_by_topic"]["frc_01"] == 180
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(live["posterior"][key], merged["posterior"][key], rtol=1e-9)
    assert live["windows"]["at_end"] == offline["windows"]["at_end"]
    assert live["windows"]["at_end"]["held_air"] > 200
    assert [e["window"] for e in live["events"]] == [e["window"] for e in merged["events"]] != []
    # the live run's checkpoint is the offline chain's: the same held air, the same state after it
    held, held_offline = Shadow.resume(ck).held_air, Shadow.resume(offline_ck).held_air
    np.testing.assert_array_equal(held.stamp_ns, held_offline.stamp_ns)  # integer ns
    # and its parameters: the node's named its private copy (gone after the run) and a period of a year
    live_params = json.loads(str(load_state(ck)["config"]))
    offline_params = json.loads(str(load_state(offline_ck)["config"]))
    assert live_params == {**offline_params, "checkpoint_path": str(ck)}
    third = replay(bags[2], "--checkpoint", ck)
    whole = replay(*bags)
    assert third["rejected"]["late"] == 0
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(third["posterior"][key], whole["posterior"][key], rtol=1e-9)
    assert [e["kind"] for e in third["events"]] == ["gap", "gap"]  # both lowerings, each at its record


def test_the_player_gets_the_posteriors_the_node_published_before_it_matched() -> None:
    """The player gets the posteriors published before its readers matched (TRANSIENT_LOCAL).

    A node resumed holding a record after a gap says its widened interval at start, maybe before the
    player's readers match. With VOLATILE readers the player never got it and the replay waited for
    it until its timeout ("timed out after 60 s waiting for 29 posterior messages": the real records'
    later bag played after the public records' checkpoint). The player's posterior readers ask for
    the node's TRANSIENT_LOCAL history (``posterior_reader_qos``).
    """
    import rclpy
    from std_msgs.msg import Float64MultiArray

    from bridge_shadow.contract import COVARIANCE_TOPIC, MEAN_TOPIC
    from bridge_shadow.ros.launcher import wait_until
    from bridge_shadow.ros.live_replay import Player
    from bridge_shadow.ros.node import posterior_qos

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("early_publisher", context=context)
        topics = (MEAN_TOPIC, COVARIANCE_TOPIC)
        pubs = [node.create_publisher(Float64MultiArray, t, posterior_qos(100)) for t in topics]
        for k in range(3):
            for pub in pubs:
                pub.publish(Float64MultiArray(data=[float(k), -float(k)]))
        with Player(latched_depth=100) as player:  # created after the three were published
            got = lambda: player.received(MEAN_TOPIC) == player.received(COVARIANCE_TOPIC) == 3  # noqa: E731
            wait_until(got, 20.0, "3 + 3")
            raws = [raw for _, raw in player.records[MEAN_TOPIC]]
            firsts = [deserialize_message(raw, Float64MultiArray).data[0] for raw in raws]
            assert firsts == [0.0, 1.0, 2.0]  # exact: small integers through CDR
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_held_air_past_the_bag_follows_it_and_an_undecodable_tail_message_is_left_out() -> None:
    """Held air past the bag follows it; ``decode_air`` skips a message it cannot read, and counts it.

    The held air after the bag's last message goes on as a piece of its own; a tail message that
    cannot be decoded is left out of the checkpoint's held air, as the node drops it (malformed).
    """
    pieces = _pieces(np.random.default_rng(6))
    raw = _raw_pieces(pieces)
    last = int(max(p[3][-1] for p in raw))
    air = pieces[-1].temperature
    later = air.take(np.arange(len(air)) < 5)
    later.log_ns = later.stamp_ns = last + (1 + np.arange(5, dtype=np.int64)) * 10**9
    out = list(merge_held(raw, later))
    assert len(out) == len(raw) + 1 and np.all(out[-1][0] == AIR)
    np.testing.assert_array_equal(out[-1][3], later.log_ns)  # integer ns
    assert _per_topic(_published(out[:-1])) == _per_topic(_published(raw))  # the bag's own, untouched
    topic, pos, raws, logs = out[-1]
    broken = [raws[0], raws[1], [raws[AIR][0][:10], *raws[AIR][1:]]]  # the first one cut short
    tail, bad = decode_air([(topic, pos, broken, logs)])
    assert bad == 1 and tail is not None and len(tail) == 4
    np.testing.assert_array_equal(tail.stamp_ns, later.stamp_ns[1:])  # integer ns
    np.testing.assert_array_equal(tail.temp_c, later.temp_c[1:])  # decoded from its bytes: a copy


def test_a_stamp_decoded_past_the_int32_seconds_is_published_as_it_decoded(tmp_path: Path) -> None:
    """Several bags played live are serialized again: a stamp whose ``nanosec`` is 1e9 or more, too.

    A header of ``sec`` 2**31 - 1 and ``nanosec`` 3e9 decodes to a stamp past the int32 seconds;
    serialized again from that, it stopped ``replay BAG BAG --live`` with a traceback (ValueError:
    stamp out of the int32 seconds range) where the direct replay takes it, and one BAG --live
    publishes its bytes. Now it goes out as what it decoded to, from the bags and as held air.
    """
    from bridge_shadow.bagio import BagOutputWriter
    from bridge_shadow.contract import FORCE_TOPICS, FORCE_TYPE, TEMPERATURE_TOPIC, TEMPERATURE_TYPE
    from bridge_shadow.ros.live_replay import _encoded_pieces

    day = write_monitoring(tmp_path / "day", _record(0, 30, np.array([0.0, 0.0]), 1.0, 4))
    far = [(2**31 - 1) * 10**9, 10**9 - 1]  # stamps (ns): the first one gets nanosec 3e9 below

    def odd(raw: bytes) -> bytes:  # sec 2**31 - 1, nanosec 3e9
        return raw[:4] + (2**31 - 1).to_bytes(4, "little") + (3 * 10**9).to_bytes(4, "little") + raw[12:]

    log = [1_700_000_100 * 10**9, 1_700_000_200 * 10**9]
    with BagOutputWriter(tmp_path / "odd") as bag:
        raws = encode_stamped_floats(np.array(far), "frc", np.zeros((2, 6)))
        bag.write_many_raw(FORCE_TOPICS["frc_01"], FORCE_TYPE, log, [odd(raws[0]), raws[1]])
        raws = encode_stamped_floats(np.array(far), "air", np.ones((2, 2)))
        bag.write_many_raw(TEMPERATURE_TOPIC, TEMPERATURE_TYPE, log, [odd(raws[0]), raws[1]])
    with MergedStream([day, tmp_path / "odd"], required=False) as stream:
        pieces = list(stream)
    stamps = [int(s) for p in pieces for s in p.forces["frc_01"].stamp_ns]
    assert (2**31 - 1) * 10**9 + 3 * 10**9 in stamps  # past the int32 seconds, as decoded
    assert _per_topic(_published(list(_encoded_pieces(pieces)))) == _per_topic(_decoded(pieces))
    held = TemperatureSeries.concat([p.temperature for p in pieces])  # as a checkpoint's held air
    held = held.take(held.stamp_ns > 2**31 * 10**9)
    assert len(held) == 1
    out = list(merge_held([], held))
    assert [m[2] for m in _published(out)] == [int(held.stamp_ns[0])]


def test_a_replay_with_volatile_posterior_readers_does_not_wait_for_what_they_missed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """``qos_depth: 0`` (KEEP_ALL): the node's posteriors are VOLATILE, kept for no late reader.

    A node resumed holding a record after a gap publishes its widened posterior at start, before
    the player's readers may have matched; the player then waited for that posterior to its
    timeout (exit 2, one run in two of a chain's third bag here, of the public records' checkpoint
    and a later record). Here the readers' matching late is made certain: what they got before the
    node's first diagnostics is dropped. Now the player waits for what the node published after
    asking it at discovery, and ends where the offline chain does.
    """
    from bridge_shadow.contract import COVARIANCE_TOPIC, DIAGNOSTICS_TOPIC, MEAN_TOPIC
    from bridge_shadow.ros import live_replay
    from bridge_shadow.ros.launcher import wait_until

    steps = ([2e-4, -1e-4], [-8e-3, -8e-3], [-1.6e-2, -1.6e-2])
    bags = [
        write_monitoring(tmp_path / f"b{k}", _record(7200 * k, 10, np.array(s), 6.0, k + 1))
        for k, s in enumerate(steps)
    ]
    ck = tmp_path / "ck.npz"
    for bag in bags[:2]:
        assert main(["replay", str(bag), "--checkpoint", str(ck)]) == 0
    assert Shadow.resume(ck).pending_gap_ns() is not None  # the node says its widened interval at start
    before = ck.read_bytes()
    params = tmp_path / "keep_all.yaml"
    params.write_text("bridge_shadow:\n  ros__parameters:\n    qos_depth: 0\n")
    discover = live_replay._discover

    def matched_late(player: live_replay.Player, node: object, timeout_s: float) -> float:
        took = discover(player, node, timeout_s)
        # the node's first diagnostics come a second after it spins, its start posterior before them
        wait_until(lambda: player.received(DIAGNOSTICS_TOPIC) > 0, timeout_s, "the node's diagnostics")
        player.records[MEAN_TOPIC].clear()
        player.records[COVARIANCE_TOPIC].clear()
        return took

    monkeypatch.setattr(live_replay, "_discover", matched_late)
    volatile = live_replay.run_live(bags[2], params, checkpoint=ck, timeout_s=20.0)
    monkeypatch.undo()
    ck.write_bytes(before)
    capfd.readouterr()
    assert main(["replay", str(bags[2]), "--checkpoint", str(ck), "--json"]) == 0  # the offline chain's step
    offline = json.loads(capfd.readouterr().out)
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(volatile["posterior"][key], offline["posterior"][key], rtol=1e-9)
    assert volatile["rejected"]["late"] == 0 and volatile["windows"]["at_end"] == offline["windows"]["at_end"]


def test_a_checkpoint_set_aside_is_said_whatever_its_name(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An unusable checkpoint named ``resumed.npz``, set aside (``fresh``), is said as any other.

    ``prepare`` left out the notes of opening that a user need not hear of by their first word
    ("resumed from ...", "checkpoint ...: none yet"); the note of a file set aside opens with the
    file's name, and ``replay --live --checkpoint resumed.npz`` set it aside without a word (the
    offline replay says it).
    """
    monkeypatch.chdir(tmp_path)  # named as a user names it, relative
    config, surrogate = load_config(None).replace(checkpoint_unusable="fresh"), load_surrogate()
    for name in ("resumed.npz", "checkpoint one.npz", "resumed/day.npz"):
        ck = Path(name)
        ck.parent.mkdir(exist_ok=True)
        ck.write_bytes(b"not a checkpoint")
        chain = prepare(config, surrogate, ck, tmp_path / "node.npz")
        assert len(chain.notes) == 1 and "set aside" in chain.notes[0] and not ck.exists()
    # what is not news stays out: none yet, a checkpoint resumed
    one = write_monitoring(tmp_path / "one", _record(0, 30, np.array([2e-4, -1e-4]), 6.0, 1))
    ck = Path("resumed.npz")
    assert prepare(config, surrogate, ck, tmp_path / "node.npz").notes == []
    assert main(["replay", str(one), "--checkpoint", str(ck)]) == 0
    assert prepare(config, surrogate, ck, tmp_path / "node.npz").notes == []


def test_a_live_chain_run_that_fails_leaves_the_checkpoint_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A live chain run that fails (here its node, at start) leaves the named checkpoint whole, and says so.

    The node's own last lines say "checkpoint written to" its private copy, which goes with the
    run's temporary directory: the error names the checkpoint the user gave, left as it was.
    """
    from bridge_shadow.ros import live_replay
    from bridge_shadow.ros.launcher import NodeError

    bags = [
        write_monitoring(tmp_path / f"b{k}", _record(7200 * k, 10, np.zeros(2), 6.0, k + 1)) for k in (0, 1)
    ]
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(bags[0]), "--checkpoint", str(ck)]) == 0
    before = ck.read_bytes()

    def broken(*_args: object, **_kw: object) -> dict:
        raise NodeError("bridge_shadow_node exited with code 1: checkpoint written to /tmp/x/checkpoint.npz")

    monkeypatch.setattr(live_replay.NodeProcess, "start", broken)  # no node needed to fail
    with pytest.raises(NodeError, match=r"ck\.npz is left as it was: the node wrote only a copy"):
        live_replay.run_live(bags[1], checkpoint=ck, timeout_s=20.0)
    assert ck.read_bytes() == before  # the bytes of the file as it was: nothing written


def test_a_newer_bag_whose_load_cells_all_failed_is_written_by_the_live_chain(tmp_path: Path) -> None:
    """The node used none of the bag's forces (all NaN) but its air, newer than the checkpoint's data.

    ``finish`` took it for a bag of older data and left the checkpoint as it was: the live chain
    lost the bag's air and counts, which the offline chain (``replay_bag``) writes.
    """
    from test_checkpoint_safety import _between, _data, _params

    data = _data(55)
    first = write_monitoring(tmp_path / "a", _between(data, 0, 30))
    part = _between(data, 30, 55)
    stamps = part.forces[CHANNELS[0]].stamp_ns
    dead = MonitoringData.from_arrays(
        stamps, np.full((len(stamps), 2), np.nan), part.temperature.stamp_ns, part.temperature.temp_c
    )
    params = _params(tmp_path / "p.yaml")
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(first), "--params", str(params), "--checkpoint", str(ck)]) == 0
    config, surrogate = load_config(str(params)), load_surrogate()
    chain = prepare(config, surrogate, ck, tmp_path / "node.npz")
    # the node's state after the bag: its copy of the checkpoint, the bag fed (no end-of-data close)
    node = Shadow.resume(tmp_path / "node.npz", config, surrogate)
    node.run(dead, flush=False)
    assert sum(node.used[ch] for ch in CHANNELS) == chain.used_before and node.used["air_temperature"]
    fed = 2 * len(stamps)
    assert chain.finish(node.state_dict(), None, [{"signature": "s", "bag": "fault"}], fed) is not None
    resumed = Shadow.resume(ck)
    assert resumed.clock_ns == node.clock_ns == int(part.temperature.stamp_ns[-1])
    assert [e["bag"] for e in resumed.taken_bags] == [str(first), "fault"]


def test_a_bag_played_again_after_an_interrupted_run_holds_its_air_tail(tmp_path: Path) -> None:
    """None of the bag's forces used, the clock where it was, but air past its last force the file lacks.

    (A rerun after a run stopped past a periodic write that took all the bag's forces.) Taken for a
    bag of older data, the checkpoint was left without that air, which the next bag's replay merges in.
    """
    from test_checkpoint_safety import _between, _data, _params

    data = _data(50)
    first = write_monitoring(tmp_path / "a", _between(data, 0, 30))
    params = _params(tmp_path / "p.yaml")
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(first), "--params", str(params), "--checkpoint", str(ck)]) == 0
    config, surrogate = load_config(str(params)), load_surrogate()
    chain = prepare(config, surrogate, ck, tmp_path / "node.npz")
    state = load_state(tmp_path / "node.npz")  # the node used nothing of the bag
    tail = _between(data, 30, 50).temperature  # newer than the checkpoint's data
    assert chain.held is None and int(tail.stamp_ns[0]) > Shadow.resume(ck).clock_ns
    assert chain.finish(state, tail, [{"signature": "s", "bag": "c"}], forces_fed=5) is not None
    resumed = Shadow.resume(ck)
    np.testing.assert_array_equal(resumed.held_air.stamp_ns, tail.stamp_ns)  # integer ns
    assert [e["bag"] for e in resumed.taken_bags] == [str(first), "c"]
