"""The air past a bag's last force is held for a checkpoint chain: one merged replay's answer, nothing late.

``replay.air_tail.AirTail`` passes a stream's pieces on in arrival order, holding the air after the
last force seen until forces follow; ``replay_bag`` writes a chain's checkpoint before the held
tail and keeps the tail in it; the next bag's replay merges it with its own bag
(``MergedStream(held=...)``). The real records' case (the public records' bag with the day's air,
then a later record's bag) is in ``test_later_records_cli.py``; here the pieces, the merge and a
chain cut in small reads and chunks, with periodic checkpoint writes that must not replace the
held tail's.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import write_monitoring
from bridge_shadow.bagio.merged import MergedStream
from bridge_shadow.contract import CHANNELS
from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.replay import replay_bag
from bridge_shadow.replay.air_tail import AirTail, air_piece
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

T0 = 1_700_000_040 * 10**9
S = 10**9


def _arrival(pieces: list[MonitoringData]) -> list[tuple[int, int, int, float]]:
    """Every message of ``pieces`` as (log_ns, topic, stamp_ns, value), in arrival order.

    Compared exactly: stamps are integers and the values are copies passed on, never computed.
    """
    out = []
    for p in pieces:
        msgs = []
        for k, ch in enumerate(CHANNELS):
            f = p.forces[ch]
            msgs += [
                (int(lg), k, int(s), float(v))
                for lg, s, v in zip(f.log_ns, f.stamp_ns, f.force_n, strict=True)
            ]
        t = p.temperature
        msgs += [
            (int(lg), 2, int(s), float(v)) for lg, s, v in zip(t.log_ns, t.stamp_ns, t.temp_c, strict=True)
        ]
        out += sorted(msgs, key=lambda m: (m[0], m[1]))
    return out


def _pieces(rng: np.random.Generator) -> list[MonitoringData]:
    """Pieces of a stream: forces for a while, air throughout and beyond, some pieces air only."""
    logs_f = np.sort(rng.choice(np.arange(0, 400), 120, replace=False)) * S
    logs_a = np.arange(0, 900, 7) * S
    logs_a[5] = logs_f[-1]  # an air reading at the last force's log time comes after it
    logs_a.sort()
    cuts = [0, 100, 250, 380, 500, 700, 900]
    pieces = []
    for a, b in itertools.pairwise(cuts):
        f = logs_f[(logs_f >= a * S) & (logs_f < b * S)]
        t = logs_a[(logs_a >= a * S) & (logs_a < b * S)]
        forces = {
            ch: ForceSeries(f, rng.normal(size=len(f)), np.full(len(f), ch, dtype=object), f)
            for ch in CHANNELS
        }
        pieces.append(MonitoringData(forces, TemperatureSeries(t, rng.normal(size=len(t)), log_ns=t)))
    return pieces


def test_the_air_past_the_last_force_is_held_and_everything_else_goes_on_in_arrival_order() -> None:
    rng = np.random.default_rng(3)
    pieces = _pieces(rng)
    tail = AirTail(pieces)
    passed = list(tail)
    assert tail.tail is not None and tail.released == 0
    last_force = max(int(p.forces[ch].log_ns[-1]) for p in pieces for ch in CHANNELS if len(p.forces[ch]))
    # the tail: every air message from the last force's log time on, nothing else
    air = np.concatenate([p.temperature.log_ns for p in pieces])
    np.testing.assert_array_equal(tail.tail.log_ns, air[air >= last_force])
    # what went on, then the tail, is the stream in its arrival order, message for message
    whole = _arrival(pieces)
    assert _arrival([*passed, air_piece(tail.tail, CHANNELS)]) == whole
    assert max(m[0] for m in _arrival(passed)) <= last_force
    # air held between forces goes on before the next forces (the two air-only pieces of 100-250 s
    # would be held only if no force came after them; here forces do)
    assert all(p.n_messages for p in passed)


def test_air_past_the_limit_goes_on_and_only_the_rest_is_held() -> None:
    pieces = _pieces(np.random.default_rng(4))
    tail = AirTail(pieces, limit=30)
    passed = list(tail)
    assert tail.released > 30
    assert _arrival([*passed, air_piece(tail.tail, CHANNELS)]) == _arrival(pieces)
    assert len(tail.tail) < 31


def test_a_stream_without_forces_holds_all_its_air() -> None:
    t = np.arange(10, dtype=np.int64) * S
    none = np.empty(0, np.int64)
    piece = MonitoringData(
        {ch: ForceSeries(none, np.empty(0), np.empty(0, dtype=object), none) for ch in CHANNELS},
        TemperatureSeries(t, np.ones(10), log_ns=t),
    )
    tail = AirTail([piece, piece])
    assert list(tail) == [] and tail.tail is not None and len(tail.tail) == 20


def _record(start_s: int, minutes: int, step_m: np.ndarray, air_h: float, seed: int) -> MonitoringData:
    """A record of forces every 10 s from ``start_s`` on, and the air every minute for ``air_h`` hours."""
    rng = np.random.default_rng(seed)
    sur = placeholder_surrogate()
    stamps = T0 + (start_s + np.arange(minutes * 6, dtype=np.int64) * 10) * S
    forces = sur.reactions(step_m) + rng.normal(0.0, 60.0, (len(stamps), 2))
    t_stamps = T0 + np.arange(int(air_h * 60), dtype=np.int64) * 60 * S  # the day's air, from its start
    temp = 8.0 + 2.0 * np.sin(np.arange(len(t_stamps)) / 200.0)
    return MonitoringData.from_arrays(stamps, forces, t_stamps, temp)


@pytest.fixture(scope="module")
def day(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """Three bags of one day, each with the day's whole air (6 h): records at 0 h, 2 h and 4 h, lowered."""
    root = tmp_path_factory.mktemp("air_tail")
    one = write_monitoring(root / "one", _record(0, 30, np.array([2e-4, -1e-4]), 6.0, 1))
    two = write_monitoring(root / "two", _record(7200, 30, np.array([-8e-3, -8e-3]), 6.0, 2))
    three = write_monitoring(root / "three", _record(14400, 30, np.array([-1.6e-2, -1.6e-2]), 6.0, 3))
    return one, two, three


def test_merging_the_held_air_is_merging_the_bag_it_came_from(day: tuple[Path, Path, Path]) -> None:
    one, two, _ = day
    from bridge_shadow.bagio.reader import read_monitoring

    air = read_monitoring(one).temperature
    held = air_piece(air, CHANNELS)
    with MergedStream([two], held=held, batch=97) as with_held, MergedStream([one, two], batch=97) as both:
        got, want = list(with_held), list(both)
        assert with_held.first_ns == both.first_ns and with_held.last_ns == both.last_ns
    only_air = [m for m in _arrival(want) if m[1] == 2 or m[2] >= T0 + 7200 * S]  # bag one's forces out
    assert _arrival(got) == only_air


def test_a_checkpoint_chain_of_bags_whose_air_runs_past_their_forces_is_one_merged_replay(
    day: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    """Replay the bags one after the other through the checkpoint: the merged replay's answer, nothing late.

    Reads of 97 messages and chunks of 50 put the held air in many pieces; a periodic checkpoint
    every minute of data would, while the tail is fed for a bag's own result, replace the
    checkpoint holding it (the chain then lost the next record: all its forces late). The second
    bag's tail holds the first bag's held air and its own copy of it (the day's air is in every
    bag): the third bag's replay rejects the copies as the merged replay does.
    """
    sur = placeholder_surrogate()
    cfg = ShadowConfig(warmup_windows=5, window_min_samples=2)
    chained = cfg.replace(checkpoint_path=str(tmp_path / "ck.npz"), checkpoint_period_s=60.0)
    first, _ = replay_bag(day[0], Shadow(chained, sur), batch=97, chunk=50)
    alone, _ = replay_bag(day[0], Shadow(cfg, sur), batch=97, chunk=50)
    np.testing.assert_allclose(first.mean_m, alone.mean_m, rtol=1e-12)
    for k, bag in enumerate(day[1:], start=2):
        resumed = Shadow.resume(chained.checkpoint_path, chained, sur)
        assert resumed.held_air is not None and len(resumed.held_air) > 100  # the air past the record
        last, _ = replay_bag(bag, resumed, batch=97, chunk=50)
        merged, _ = replay_bag(list(day[:k]), Shadow(cfg, sur), batch=97, chunk=50)
        assert last.rejected["late"] == 0 and merged.rejected["late"] == 0
        assert last.used["frc_01"] == merged.used["frc_01"] == 180 * k  # every record's forces, all taken
        assert sum(last.rejected.values()) == sum(merged.rejected.values())
        np.testing.assert_allclose(last.mean_m, merged.mean_m, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(last.covariance_m2, merged.covariance_m2, rtol=1e-9, atol=1e-16)
    assert np.all(np.abs(last.mean_m + 1.6e-2) < 1e-3)  # the last record's state


def test_a_node_resumed_from_a_chains_checkpoint_takes_the_held_air_first(
    day: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    """A node started on a replay's checkpoint ingests the air the replay held, before any live data.

    Live data come after the checkpoint's, so the node cannot merge; it takes the held air at
    once (its windows close at the first poll) and says so, instead of dropping it.
    """
    import rclpy
    from rclpy.parameter import Parameter

    from bridge_shadow.cli import main
    from bridge_shadow.ros.node import ShadowNode

    one = day[0]
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(one), "--checkpoint", str(ck)]) == 0
    held = Shadow.resume(ck).held_air
    assert held is not None and len(held) > 200
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ShadowNode(context=context, parameter_overrides=[Parameter("checkpoint_path", value=str(ck))])
        try:
            assert node.shadow.held_air is None
            before = Shadow.resume(ck).used["air_temperature"]
            assert node.shadow.used["air_temperature"] == before + len(held)
            clock = node.shadow.clock_ns
            assert clock is not None and clock >= int(held.stamp_ns[-1])
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_shadow_run_holds_and_merges_the_air_as_replay_bag_does(
    day: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    """The in-memory ``Shadow.run`` chain: the same checkpoint tail, the merged replay's answer."""
    from bridge_shadow.bagio.reader import read_monitoring

    one, two, _ = day
    sur = placeholder_surrogate()
    cfg = ShadowConfig(warmup_windows=5, window_min_samples=2)
    chained = cfg.replace(checkpoint_path=str(tmp_path / "ck.npz"), checkpoint_period_s=60.0)
    Shadow(chained, sur).run(read_monitoring(one), chunk=50)
    resumed = Shadow.resume(chained.checkpoint_path, chained, sur)
    assert resumed.held_air is not None and len(resumed.held_air) > 200
    second = resumed.run(read_monitoring(two), chunk=50)
    assert resumed.held_air is None  # fed, not saved again
    merged, _ = replay_bag([one, two], Shadow(cfg, sur), batch=97, chunk=50)
    assert second.rejected["late"] == 0 and second.used["frc_01"] == 360
    np.testing.assert_allclose(second.mean_m, merged.mean_m, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(second.covariance_m2, merged.covariance_m2, rtol=1e-9, atol=1e-16)


def test_the_replay_says_what_the_checkpoint_holds_and_the_next_run_counts_it(
    day: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``windows.at_end.held_air`` and its text line; the next run's ``resumed.held_air``; counts add up."""
    import json

    from bridge_shadow.cli import main
    from bridge_shadow.commands.replay import _summary

    ck = str(tmp_path / "ck.npz")
    assert main(["replay", str(day[0]), "--checkpoint", ck, "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    held = Shadow.resume(ck).held_air
    assert held is not None and first["windows"]["at_end"]["held_air"] == len(held) > 200
    assert f"the checkpoint holds {len(held)} air readings unfed" in _summary(first)
    assert main(["replay", str(day[1]), "--checkpoint", ck, "--json"]) == 0
    second = json.loads(capsys.readouterr().out)
    assert second["resumed"]["held_air"] == len(held)
    msgs = second["messages"]
    assert msgs["used"] + msgs["rejected"] == msgs["total"]  # the held air is read, and counted, this run
    assert f"{len(held)} air readings held): the counts below are this run's, the held air's" in _summary(
        second
    )


def test_a_bag_replayed_after_a_checkpoint_of_later_data_exits_1(
    day: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The chain in the wrong order: the earlier bag gives nothing, and the exit code says so.

    The checkpoint of the later record holds its windows open, so closing them updated the
    estimate and the run exited 0, every force of the earlier bag rejected (WARN lines only).
    """
    import json

    from bridge_shadow.cli import main

    ck = str(tmp_path / "ck.npz")
    assert main(["replay", str(day[1]), "--checkpoint", ck]) == 0
    capsys.readouterr()
    assert main(["replay", str(day[0]), "--checkpoint", ck, "--json"]) == 1
    out = capsys.readouterr()
    js = json.loads(out.out)
    assert js["windows"]["updates"] > 0  # the later record's windows the checkpoint held open
    assert js["messages"]["used_by_topic"]["frc_01"] == js["messages"]["used_by_topic"]["frc_02"] == 0
    assert "error: none of this run's load-cell messages was used" in out.err


@pytest.mark.parametrize("feed", ["replay_bag", "Shadow.run"])
def test_a_periodic_checkpoint_in_the_next_bag_keeps_the_held_air_not_fed_yet(
    day: tuple[Path, Path, Path], tmp_path: Path, feed: str
) -> None:
    """A run of the next bag stopped after a periodic checkpoint write: the held air still to come is in it.

    Written without it, the real records' chain (the day's air, then a record's bag without air,
    stopped there and replayed again) lost the 25,219 air readings of the next record's replay.
    ``Shadow.run`` (the in-memory feed) lost them alike.
    """
    from bridge_shadow.bagio.reader import read_monitoring

    sur = placeholder_surrogate()
    cfg = ShadowConfig(warmup_windows=5, window_min_samples=2)
    chained = cfg.replace(checkpoint_path=str(tmp_path / "ck.npz"), checkpoint_period_s=60.0)
    replay_bag(day[0], Shadow(chained, sur), batch=97, chunk=50)
    held = Shadow.resume(chained.checkpoint_path, chained, sur).held_air
    assert held is not None
    shadow = Shadow.resume(chained.checkpoint_path, chained, sur)
    writes = []

    def stop_after_three(*args: object, **kwargs: object) -> object:
        writes.append(Shadow.save_checkpoint(shadow, *args, **kwargs))  # type: ignore[arg-type]
        if len(writes) == 3:
            raise KeyboardInterrupt
        return writes[-1]

    shadow.save_checkpoint = stop_after_three  # type: ignore[method-assign]
    with pytest.raises(KeyboardInterrupt):
        if feed == "replay_bag":
            replay_bag(day[1], shadow, batch=97, chunk=50)
        else:
            shadow.run(read_monitoring(day[1]), chunk=50)
    left = Shadow.resume(chained.checkpoint_path, chained, sur).held_air
    assert left is not None and 0 < len(left) < len(held)
    assert int(left.log_ns[-1]) == int(held.log_ns[-1])  # to the held air's end
    np.testing.assert_array_equal(left.log_ns, held.log_ns[held.log_ns >= left.log_ns[0]])


def test_a_chain_that_starts_with_a_bag_of_the_air_alone_is_one_merged_replay(
    day: tuple[Path, Path, Path], tmp_path: Path
) -> None:
    """The day's air in a bag of its own, replayed first: held whole, the records after it all taken.

    Fed whole before the checkpoint, it moved the data clock to the air's end: the real records'
    chain (the air, the reference record, the 10 mm record, each without air) lost all 144,000
    forces of the 10 mm record as ``late``, the state the prior's, where the merged replay has the
    -10 mm event.
    """
    from bridge_shadow.bagio.reader import read_monitoring

    air = write_monitoring(tmp_path / "air", air_piece(read_monitoring(day[0]).temperature, CHANNELS))
    sur = placeholder_surrogate()
    cfg = ShadowConfig(warmup_windows=5, window_min_samples=2)
    chained = cfg.replace(checkpoint_path=str(tmp_path / "ck.npz"))
    replay_bag(air, Shadow(chained, sur), batch=97, chunk=50, required=False)
    held = Shadow.resume(chained.checkpoint_path, chained, sur).held_air
    assert held is not None and len(held) == 360  # the whole air, unfed
    for bag in day[:2]:
        last, _ = replay_bag(bag, Shadow.resume(chained.checkpoint_path, chained, sur), batch=97, chunk=50)
    merged, _ = replay_bag([air, *day[:2]], Shadow(cfg, sur), batch=97, chunk=50)
    assert last.rejected["late"] == 0 and last.used["frc_01"] == merged.used["frc_01"] == 360
    np.testing.assert_allclose(last.mean_m, merged.mean_m, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(last.covariance_m2, merged.covariance_m2, rtol=1e-9, atol=1e-16)


def test_a_chains_bag_of_the_air_alone_is_no_failure(
    day: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``replay AIR --checkpoint CK``: the air held whole for the next bag, said, exit 0.

    It exited 1 ("no window updated the estimate") with a WARN "no load cell message": a chain's
    script (``replay B --checkpoint CK || exit``) stopped at the day's air, the way the README
    gives it. Without a checkpoint the air is kept nowhere: exit 1 as before.
    """
    import json

    from bridge_shadow.bagio.reader import read_monitoring
    from bridge_shadow.cli import main
    from bridge_shadow.replay.air_tail import mark_air_held_whole

    air = write_monitoring(tmp_path / "air", air_piece(read_monitoring(day[0]).temperature, CHANNELS))
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(air), "--checkpoint", str(ck), "--json"]) == 0
    out = capsys.readouterr()
    js = json.loads(out.out)
    held = Shadow.resume(ck).held_air
    assert held is not None and js["air_held_whole"] == len(held) == 360
    assert not [w for w in js["warnings"] if w.startswith("no load cell message")]
    assert "its 360 air readings are held in the checkpoint" in out.err and "error" not in out.err
    assert main(["replay", str(air), "--json"]) == 1  # no chain: nothing kept, nothing estimated
    assert "no load cell message" in capsys.readouterr().err
    # the rule: no load-cell message and air held (the live chain marks its JSON the same way)
    for forces, kept, marked in ((0, 360, True), (5, 360, False), (0, 0, False)):
        js = {"warnings": ["no load cell message: x", "other"]}
        mark_air_held_whole(js, forces, kept)
        assert ("air_held_whole" in js) == marked and len(js["warnings"]) == (1 if marked else 2)


def test_bags_that_each_hold_the_days_air_read_merged_are_said_to_repeat_it(
    day: tuple[Path, Path, Path],
) -> None:
    """The day's air in every bag, read merged: its copies are repeats, not a clock gone wrong.

    The line named a logger's clock set back, a checkpoint ahead of the data, and advised reading
    the bags merged, which the run had just done (a judging helper session, 84,990 copies of the
    real day's air in four bags read merged; the archive said "nothing lost" beside it).
    """
    sur = placeholder_surrogate()
    merged, _ = replay_bag(list(day), Shadow(ShadowConfig(warmup_windows=5, window_min_samples=2), sur))
    assert merged.rejected["duplicate"] > 600 and not merged.rejected["out_of_order"]
    (line,) = [w for w in merged.warnings if w.startswith("topic air_temperature:")]
    assert "repeat the stamp of the message taken just before them" in line
    assert "clock set back" not in line and "when given together" not in line


def test_a_chains_output_bag_ends_at_the_replays_answer(
    day: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``replay BAG --checkpoint CK --out OUT``: OUT's last posterior is the JSON's, as without a checkpoint.

    The end-of-data refit (lambda reselected) comes with no window output when the air past the
    last force has decided every window; the bag gets it on its own (``write_final_posterior``).
    A chain's replay wrote it before feeding the held tail, that is never (the tail's flush came
    after): each bag ended at the posterior before (the second here: -12.874 mm south against
    -12.876 mm), where ``replay --live --checkpoint --out`` records the node's final posterior.
    """
    import json

    from bridge_shadow.bagio import get_typestore, read_raw_topics
    from bridge_shadow.cli import main
    from bridge_shadow.contract import COVARIANCE_TOPIC, FLOAT_ARRAY_TYPE, MEAN_TOPIC

    ck = tmp_path / "ck.npz"
    topics = (MEAN_TOPIC, COVARIANCE_TOPIC)
    for k, bag in enumerate(day[:2]):
        out = tmp_path / f"out{k}"
        assert main(["replay", str(bag), "--checkpoint", str(ck), "--out", str(out), "--json"]) == 0
        js = json.loads(capsys.readouterr().out)
        raw = read_raw_topics(out, dict.fromkeys(topics, FLOAT_ARRAY_TYPE))
        last = [get_typestore().deserialize_cdr(raw[t][1][-1], FLOAT_ARRAY_TYPE).data for t in topics]
        post = js["posterior"]
        np.testing.assert_allclose(last[0], post["mean_m"], rtol=1e-12, atol=0)
        np.testing.assert_allclose(last[1].reshape(2, 2), post["covariance_m2"], rtol=1e-12, atol=0)
