"""A bag replayed again after its own run's checkpoint: known, said, nothing changed (``replay.taken``).

Before, the rerun (the same command twice, a script's retry) rejected every message as older than
the checkpoint's data, exited 1 as after a bag of older data, and wrote the checkpoint again with
the rejects counted.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_checkpoint_safety import _between, _data, _params

from bridge_shadow.bagio import write_monitoring
from bridge_shadow.cli import main
from bridge_shadow.estimate import Shadow
from bridge_shadow.replay import taken as taken_mod
from bridge_shadow.replay.taken import bag_signature, find_taken, recorded


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Minutes 0-30, 30-60 and 0-20 of one stream of forces every 10 s, each a bag."""
    root = tmp_path_factory.mktemp("taken")
    data = _data(60)
    return {
        "a": write_monitoring(root / "a", _between(data, 0, 30)),
        "b": write_monitoring(root / "b", _between(data, 30, 60)),
        "older": write_monitoring(root / "older", _between(data, 0, 20)),
    }


def _replay(capsys, *argv: str) -> tuple[int, dict, str]:
    code = main(["replay", *argv, "--json"])
    out = capsys.readouterr()
    return code, json.loads(out.out) if out.out.strip() else {}, out.err


def test_the_same_bag_again_is_known_and_changes_nothing(bags, tmp_path: Path, capsys) -> None:
    params = str(_params(tmp_path / "p.yaml"))
    ck = tmp_path / "ck.npz"
    code, first, _ = _replay(capsys, str(bags["a"]), "--params", params, "--checkpoint", str(ck))
    assert code == 0 and first["messages"]["used"] > 0
    before = _digest(ck)
    code, again, err = _replay(capsys, str(bags["a"]), "--params", params, "--checkpoint", str(ck))
    assert code == 0, err
    assert f"taken whole into {ck} already" in err and "the checkpoint is left as it was" in err
    assert _digest(ck) == before  # the file left untouched: compared byte for byte
    assert again["messages"]["total"] == 0 and not any(again["rejected"].values())
    assert [e["bag"] for e in again["already_taken"]] == [str(bags["a"])]
    # the checkpoint's answer: the first run's, its end-of-data close made again
    np.testing.assert_allclose(again["posterior"]["mean_m"], first["posterior"]["mean_m"], rtol=1e-9)
    np.testing.assert_allclose(
        again["posterior"]["covariance_m2"], first["posterior"]["covariance_m2"], rtol=1e-9
    )
    assert again["resumed"]["windows"] + again["windows"]["closed"] == first["windows"]["closed"]


def test_a_chain_knows_every_bag_it_took_and_nothing_else(bags, tmp_path: Path, capsys) -> None:
    params = str(_params(tmp_path / "p.yaml"))
    ck = tmp_path / "ck.npz"
    for name in ("a", "b"):
        code, js, err = _replay(capsys, str(bags[name]), "--params", params, "--checkpoint", str(ck))
        assert code == 0 and js["messages"]["used"] > 0 and "taken whole" not in err, err
    before = _digest(ck)
    for argv in ([bags["a"]], [bags["a"], bags["b"]], [bags["b"]]):
        code, js, err = _replay(capsys, *map(str, argv), "--params", params, "--checkpoint", str(ck))
        assert code == 0 and "taken whole into" in err and js["messages"]["total"] == 0, err
    assert _digest(ck) == before
    # a bag of older data it did not take, and a copy of one it took (not known: the files are
    # others): replayed, every message rejected, exit 1, as before, and now the checkpoint is left
    # as it was (written, it counted the rejects and took the bag)
    copy = tmp_path / "copy_of_a"
    shutil.copytree(bags["a"], copy)
    for bag in (bags["older"], copy):
        code, js, err = _replay(capsys, str(bag), "--params", params, "--checkpoint", str(ck))
        assert code == 1 and "resumed from" in err and "taken whole" not in err
        assert js["messages"]["used"] == 0 and js["messages"]["rejected"] == js["messages"]["total"] > 0
        assert js["checkpoint_kept"] and "the checkpoint is left as it was" in err
        assert _digest(ck) == before
    entries = Shadow.resume(ck).taken_bags
    assert [e["bag"] for e in entries] == [str(bags["a"]), str(bags["b"])]


def test_outputs_of_a_bag_taken_are_refused_in_one_line(bags, tmp_path: Path, capsys) -> None:
    params = str(_params(tmp_path / "p.yaml"))
    ck = tmp_path / "ck.npz"
    assert _replay(capsys, str(bags["a"]), "--params", params, "--checkpoint", str(ck))[0] == 0
    before = _digest(ck)
    for extra in (["--out", str(tmp_path / "out")], ["--plots", str(tmp_path / "plots")]):
        code = main(["replay", str(bags["a"]), "--params", params, "--checkpoint", str(ck), *extra])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and "without --checkpoint" in err[0], err
    assert _digest(ck) == before and not (tmp_path / "out").exists()


def test_the_records_of_a_day_each_with_the_days_air_are_told_apart(tmp_path: Path, capsys) -> None:
    """Two records 2 h apart, each bag with the day's air: the same topics, counts and span.

    Known by those alone, the second record's bag was taken for the first's: "taken whole already",
    and its settlement never replayed.
    """
    from test_air_tail import _record

    steps = ([2e-4, -1e-4], [-8e-3, -8e-3])
    day = [
        write_monitoring(tmp_path / f"r{k}", _record(7200 * k, 30, np.array(s), 6.0, k + 1))
        for k, s in enumerate(steps)
    ]
    meta = [bag_signature(b) for b in day]
    assert (meta[0]["messages"], meta[0]["start"], meta[0]["end"]) == (
        meta[1]["messages"],
        meta[1]["start"],
        meta[1]["end"],
    )
    assert meta[0]["signature"] != meta[1]["signature"]
    ck = tmp_path / "ck.npz"
    assert _replay(capsys, str(day[0]), "--checkpoint", str(ck))[0] == 0
    code, js, err = _replay(capsys, str(day[1]), "--checkpoint", str(ck))
    assert code == 0 and "taken whole" not in err and js["messages"]["used_by_topic"]["frc_01"] == 180
    assert [e["kind"] for e in js["events"]] == ["gap"]  # the lowering, at its record
    code, js, err = _replay(capsys, str(day[1]), "--checkpoint", str(ck))
    assert code == 0 and "taken whole into" in err and js["messages"]["total"] == 0
    # the text says so: the air the checkpoint holds goes into its own close, not this run's counts
    # (it read "the counts below are this run's, the held air's among them" over counts of zero)
    from bridge_shadow.commands.replay import _summary

    text = _summary(js)
    assert js["resumed"]["held_air"] > 200 and "the held air's among them" not in text
    assert (
        "nothing below is of this run but the end-of-data close made again, which feeds the air held" in text
    )


def test_recorded_names_the_latest_run_and_keeps_the_latest_bags(monkeypatch) -> None:
    entry = lambda s: {"bag": s, "signature": s, "messages": 1, "start": "", "end": ""}  # noqa: E731
    taken = recorded([], [entry("x"), entry("y")])
    assert [e["signature"] for e in taken] == ["x", "y"] and all(e["taken_at"] for e in taken)
    taken = recorded(taken, [entry("x")])  # taken again (a copy): one entry, the latest, last
    assert [e["signature"] for e in taken] == ["y", "x"]
    assert find_taken(taken, [entry("x"), entry("y")]) is not None
    assert find_taken(taken, [entry("x"), entry("z")]) is None and find_taken(taken, []) is None
    monkeypatch.setattr(taken_mod, "TAKEN_LIMIT", 3)
    taken = recorded(taken, [entry("p"), entry("q")])
    assert [e["signature"] for e in taken] == ["x", "p", "q"]


def test_a_checkpoints_list_is_read_alone_and_anything_else_is_none(bags, tmp_path: Path, capsys) -> None:
    """``load_entry``: the one entry the rerun looks at before it resumes the whole state."""
    from bridge_shadow.estimate.state.checkpoint import load_entry

    ck = tmp_path / "ck.npz"
    assert (
        _replay(
            capsys, str(bags["a"]), "--params", str(_params(tmp_path / "p.yaml")), "--checkpoint", str(ck)
        )[0]
        == 0
    )
    listed = json.loads(str(load_entry(ck, "taken_bags")))
    assert listed == Shadow.resume(ck).taken_bags and [e["bag"] for e in listed] == [str(bags["a"])]
    assert load_entry(ck, "no_such_entry") is None
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a checkpoint")
    assert (
        load_entry(junk, "taken_bags") is None and load_entry(tmp_path / "absent.npz", "taken_bags") is None
    )


def test_a_newer_bag_whose_load_cells_all_failed_is_taken_and_written(tmp_path: Path, capsys) -> None:
    """Minutes 30-55 with every force NaN (a logger fault), the air as it was: newer data, none older.

    Its forces all rejected (``nonfinite``), it was taken for a bag of older data: "the checkpoint
    is left as it was", while the periodic write (every ``checkpoint_period_s`` of data, the air
    moving the clock) had rewritten the file with the bag's messages counted, and the bag was not
    recorded: replayed again, it ran again.
    """
    from bridge_shadow.bagio.reader import bag_summary
    from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS
    from bridge_shadow.series import MonitoringData

    data = _data(55)
    a = write_monitoring(tmp_path / "a", _between(data, 0, 30))
    part = _between(data, 30, 55)
    stamps = part.forces[next(iter(part.forces))].stamp_ns
    dead = MonitoringData.from_arrays(
        stamps, np.full((len(stamps), 2), np.nan), part.temperature.stamp_ns, part.temperature.temp_c
    )
    fault = write_monitoring(tmp_path / "fault", dead)
    params = str(_params(tmp_path / "p.yaml"))
    ck = tmp_path / "ck.npz"
    assert _replay(capsys, str(a), "--params", params, "--checkpoint", str(ck))[0] == 0
    before = _digest(ck)
    code, js, err = _replay(capsys, str(fault), "--params", params, "--checkpoint", str(ck))
    assert code == 1 and js["messages"]["used_by_topic"]["air_temperature"] == len(part.temperature)
    kept = bool(js.get("checkpoint_kept")) or "the checkpoint is left as it was" in err
    assert not kept or _digest(ck) == before, "said left as it was, and the file was rewritten"
    # the checkpoint is the state at the bag's end, as a chain wrote it: both bags' messages counted
    state = Shadow.resume(ck)
    counted = sum(state.used.values()) + sum(n for r, n in state.rejected.items() if r in MESSAGE_REASONS)
    assert counted == bag_summary(a)["message_count"] + bag_summary(fault)["message_count"]
    assert [e["bag"] for e in state.taken_bags] == [str(a), str(fault)]
    code, again, err = _replay(capsys, str(fault), "--params", params, "--checkpoint", str(ck))
    assert code == 0 and "taken whole into" in err and again["messages"]["total"] == 0


def test_a_bag_named_twice_in_one_run_is_recorded_once(bags, tmp_path: Path, capsys) -> None:
    """``replay a a b`` (a glob and a name, a script's list): the checkpoint lists each bag once."""
    params = str(_params(tmp_path / "p.yaml"))
    ck = tmp_path / "ck.npz"
    named = [bags["a"], bags["a"], bags["b"]]
    code, _, err = _replay(capsys, *map(str, named), "--params", params, "--checkpoint", str(ck))
    assert code == 0, err
    listed = [e["signature"] for e in Shadow.resume(ck).taken_bags]
    assert sorted(listed) == sorted({bag_signature(b)["signature"] for b in named})
    code, again, err = _replay(capsys, str(bags["a"]), "--params", params, "--checkpoint", str(ck))
    assert code == 0 and "taken whole into" in err and again["messages"]["total"] == 0


def test_a_bag_run_again_after_an_interrupted_run_holds_its_air_for_the_next(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    """A run stopped in its air tail's feed, after a periodic write that took all its forces, then run again.

    The rerun used none of the bag's forces (the periodic write had them) and was taken for a bag
    of older data: the checkpoint left as the interrupted run wrote it, without the air past the
    bag's last force that the next bag's replay merges in, and the bag never recorded.
    """
    from bridge_shadow.replay import bag as bag_mod
    from bridge_shadow.series import MonitoringData

    data, air = _data(50), _data(80).temperature
    a = write_monitoring(tmp_path / "a", _between(data, 0, 30))
    part = _between(data, 30, 50)
    stamps = part.forces[next(iter(part.forces))].stamp_ns
    late_air = air.stamp_ns >= stamps[0]
    forces = np.column_stack([f.force_n for f in part.forces.values()])
    c = write_monitoring(
        tmp_path / "c",
        MonitoringData.from_arrays(stamps, forces, air.stamp_ns[late_air], air.temp_c[late_air]),
    )
    params = str(_params(tmp_path / "p.yaml", checkpoint_period_s=60.0))
    ck = tmp_path / "ck.npz"
    assert _replay(capsys, str(a), "--params", params, "--checkpoint", str(ck))[0] == 0
    feed, calls = bag_mod.feed_shadow, []

    def stopped_in_the_tail(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:  # the bag's forces fed, its air tail next
            raise KeyboardInterrupt
        return feed(*args, **kwargs)

    monkeypatch.setattr(bag_mod, "feed_shadow", stopped_in_the_tail)
    assert _replay(capsys, str(c), "--params", params, "--checkpoint", str(ck))[0] == 130
    monkeypatch.setattr(bag_mod, "feed_shadow", feed)
    assert [e["bag"] for e in Shadow.resume(ck).taken_bags] == [str(a)]  # not taken: interrupted
    _replay(capsys, str(c), "--params", params, "--checkpoint", str(ck))
    state = Shadow.resume(ck)
    tail = air.stamp_ns[air.stamp_ns > stamps[-1]]  # the air past the bag's last force
    assert len(tail) and state.held_air is not None
    np.testing.assert_array_equal(state.held_air.stamp_ns, tail)  # integer ns
    assert [e["bag"] for e in state.taken_bags] == [str(a), str(c)]


def test_a_bag_named_by_its_directory_or_its_storage_file_is_one_bag(bags, tmp_path: Path, capsys) -> None:
    """Taken as a directory, given again as its bare ``.db3`` (or the other way): known.

    The directory's signature held its ``metadata.yaml`` too, so the bare file was another bag:
    every message rejected, exit 1.
    """
    params = str(_params(tmp_path / "p.yaml"))
    storage = next(bags["a"].glob("*.db3"))
    for first, again in ((bags["a"], storage), (storage, bags["a"])):
        ck = tmp_path / f"ck_{first.name}.npz"
        assert _replay(capsys, str(first), "--params", params, "--checkpoint", str(ck))[0] == 0
        code, js, err = _replay(capsys, str(again), "--params", params, "--checkpoint", str(ck))
        assert code == 0 and "taken whole into" in err and js["messages"]["total"] == 0, err
    assert bag_signature(bags["a"])["signature"] == bag_signature(storage)["signature"]
    assert bag_signature(bags["b"])["signature"] != bag_signature(storage)["signature"]
