"""Checkpoints are never lost or overwritten without being asked, and never resumed wrongly.

- ``replay --params`` with a ``checkpoint_path`` (the live node's) neither reads nor writes it;
  ``--checkpoint PATH`` names one explicitly (resume, then write).
- A checkpoint records the parameters that shape its state and the surrogate; resuming under
  others is refused, naming each difference.
- An empty, truncated, foreign or malformed file gives one line naming it and is left as it was;
  ``checkpoint_unusable: fresh`` sets it aside (kept) and starts from the prior.
- Temporary files of killed writers are removed at start; a failed write leaves none.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import write_monitoring
from bridge_shadow.cli import main
from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.estimate.startup import open_shadow
from bridge_shadow.estimate.state.checkpoint import CheckpointError, save_state
from bridge_shadow.model.surrogate_file import Surrogate, placeholder_surrogate

T0 = 1_700_000_040 * 10**9
CFG = dict(warmup_windows=5, window_min_samples=2)


def _data(minutes: int = 30):
    from bridge_shadow.series import MonitoringData

    rng = np.random.default_rng(5)
    sur = placeholder_surrogate()
    stamps = T0 + np.arange(minutes * 6, dtype=np.int64) * 10 * 10**9  # forces every 10 s
    t_stamps = T0 + np.arange(minutes, dtype=np.int64) * 60 * 10**9
    temp = 8.0 + 0.1 * np.arange(minutes)
    forces = sur.reactions(np.array([2e-4, -1e-4])) + rng.normal(0.0, 60.0, (len(stamps), 2))
    return MonitoringData.from_arrays(stamps, forces, t_stamps, temp)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def saved(tmp_path_factory) -> tuple[Path, ShadowConfig, Surrogate]:
    """A real checkpoint of a short run (window_s 60, the placeholder surrogate)."""
    path = tmp_path_factory.mktemp("ckpt") / "state.npz"
    cfg = ShadowConfig(**CFG)
    sur = placeholder_surrogate()
    shadow = Shadow(cfg, sur)
    shadow.run(_data())
    shadow.save_checkpoint(path)
    return path, cfg, sur


def test_resume_under_other_parameters_is_refused_naming_them(saved) -> None:
    path, cfg, sur = saved
    before = _digest(path)
    assert Shadow.resume(path, cfg, sur).n_windows > 20  # the same parameters resume
    with pytest.raises(CheckpointError) as err:
        Shadow.resume(path, cfg.replace(window_s=30.0, prior_sigma_m=[1e-3, 1e-3]), sur)
    text = str(err.value)
    assert text.startswith(f"{path}: saved under other parameters")
    assert "window_s 60 (now 30)" in text and "prior_sigma_m [0, 0] (now [0.001, 0.001])" in text
    other = Surrogate(sur.A * 1.1, sur.u0)
    with pytest.raises(CheckpointError, match="the surrogate's A and u0"):
        Shadow.resume(path, cfg, other)
    # a parameter that does not shape the state may change
    assert Shadow.resume(path, cfg.replace(mahalanobis_probability=0.99), sur).n_windows > 20
    assert _digest(path) == before


def _broken(kind: str, good: Path, target: Path) -> Path:
    if kind == "empty":
        target.write_bytes(b"")
    elif kind == "truncated":
        target.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    elif kind == "random":
        target.write_bytes(np.random.default_rng(0).bytes(4096))
    elif kind == "other_npz":
        np.savez(target, a=np.zeros(3))
        target = target.with_suffix(".npz") if not target.name.endswith(".npz") else target
    elif kind == "missing_entries":
        np.savez(target, version=np.array(1), config=np.array("{}"))
    elif kind == "directory":
        target.mkdir()
    return target


BROKEN = ["empty", "truncated", "random", "other_npz", "missing_entries", "directory"]


@pytest.mark.parametrize("kind", BROKEN)
def test_an_unusable_checkpoint_gives_one_line_naming_it_and_is_left_alone(saved, tmp_path, kind) -> None:
    good, cfg, sur = saved
    path = _broken(kind, good, tmp_path / "state.npz")
    before = _digest(path) if path.is_file() else None
    with pytest.raises(CheckpointError) as err:
        open_shadow(cfg.replace(checkpoint_path=str(path)), sur)
    text = str(err.value)
    assert text.startswith(str(path)) and "\n" not in text
    assert "pickled" not in text  # the old message for random bytes misled
    if before is not None:
        assert _digest(path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["state.npz"]  # nothing beside it


def test_fresh_sets_an_unusable_checkpoint_aside_and_keeps_it(saved, tmp_path) -> None:
    _, cfg, sur = saved
    path = tmp_path / "state.npz"
    path.write_bytes(b"not a checkpoint")
    shadow, notes = open_shadow(cfg.replace(checkpoint_path=str(path), checkpoint_unusable="fresh"), sur)
    assert shadow.n_windows == 0 and not path.exists()
    (aside,) = tmp_path.glob("state.npz.unusable-*")
    assert aside.read_bytes() == b"not a checkpoint"
    assert any(aside.name in line for line in notes)


def test_orphan_temporaries_of_killed_writers_are_removed_at_start(saved, tmp_path) -> None:
    _, cfg, sur = saved
    code = "import os; print(os.getpid())"
    dead = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    orphan = tmp_path / f".state.npz.{int(dead.stdout)}.tmp"
    alive = tmp_path / f".state.npz.{os.getppid()}.tmp"  # a running process may be writing it
    orphan.write_bytes(b"half")
    alive.write_bytes(b"busy")
    _, notes = open_shadow(cfg.replace(checkpoint_path=str(tmp_path / "state.npz")), sur)
    assert not orphan.exists() and alive.exists()
    assert any(orphan.name in line for line in notes)


def test_a_failed_write_leaves_nothing_behind(tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(CheckpointError, match="cannot write the checkpoint"):
        save_state({"version": 1}, blocker / "state.npz")
    (tmp_path / "dir.npz").mkdir()
    with pytest.raises(CheckpointError, match="is a directory"):
        save_state({"version": 1}, tmp_path / "dir.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.npz", "file"]
    # at start: the file in the way named (it read "cannot write a checkpoint there (File exists)")
    from bridge_shadow.estimate.state.checkpoint import check_target

    with pytest.raises(CheckpointError, match=f"there: {blocker} is a file, not a folder$"):
        check_target(blocker / "sub" / "state.npz")


def test_a_periodic_write_that_fails_is_a_warning_and_is_tried_again(tmp_path) -> None:
    """A full disk or a mount gone read-only must not stop the monitoring (it stopped the node).

    The checkpoint's place is taken by a directory for the first half of the data: the windows go
    on as without a checkpoint, the failure is a warning with its time, and once the place is free
    the next period writes the state and the warning is gone.
    """
    from bridge_shadow.series import MonitoringData

    target = tmp_path / "state.npz"
    data = _data(120)
    half = T0 + 60 * 60 * 10**9
    parts = []
    for keep in (lambda s: s < half, lambda s: s >= half):
        f = [data.forces[ch] for ch in data.forces]
        sel = keep(f[0].stamp_ns)
        t_sel = keep(data.temperature.stamp_ns)
        parts.append(
            MonitoringData.from_arrays(
                f[0].stamp_ns[sel],
                np.column_stack([f[0].force_n[sel], f[1].force_n[sel]]),
                data.temperature.stamp_ns[t_sel],
                data.temperature.temp_c[t_sel],
            )
        )
    cfg = ShadowConfig(**CFG, checkpoint_period_s=600.0)
    plain = Shadow(cfg, placeholder_surrogate())
    shadow = Shadow(cfg.replace(checkpoint_path=str(target)), placeholder_surrogate())
    target.mkdir()
    first = shadow.run(parts[0], chunk=60, flush=False)  # a poll every 20 s of data
    alone = plain.run(parts[0], flush=False)
    assert plain.n_updates == shadow.n_updates > 30
    np.testing.assert_allclose(first.mean_m, alone.mean_m, rtol=1e-12, atol=1e-15)  # the same windows
    lines = [w for w in shadow.warnings() if w.startswith("checkpoint not written")]
    assert len(lines) == 1 and "is a directory" in lines[0] and "every 600 s" in lines[0], lines
    assert shadow.diagnostics()["level"] == "WARN"
    target.rmdir()
    shadow.run(parts[1], chunk=60, flush=False)
    assert target.is_file() and not any(w.startswith("checkpoint") for w in shadow.warnings())
    resumed = Shadow.resume(target, cfg.replace(checkpoint_path=str(target)), placeholder_surrogate())
    assert resumed.clock_ns > half  # a state of the second half, written by a later period


def _between(data, lo_min: float, hi_min: float):
    """The part of ``data`` stamped in minutes [lo_min, hi_min) after T0."""
    from bridge_shadow.series import MonitoringData

    lo, hi = T0 + int(lo_min * 60e9), T0 + int(hi_min * 60e9)
    f = [data.forces[ch] for ch in data.forces]
    sel = (f[0].stamp_ns >= lo) & (f[0].stamp_ns < hi)
    t = data.temperature
    t_sel = (t.stamp_ns >= lo) & (t.stamp_ns < hi)
    forces = np.column_stack([f[0].force_n[sel], f[1].force_n[sel]])
    return MonitoringData.from_arrays(f[0].stamp_ns[sel], forces, t.stamp_ns[t_sel], t.temp_c[t_sel])


def test_messages_rejected_for_their_stamps_are_said_out_loud(saved, tmp_path) -> None:
    """Overlapping bags, or a checkpoint ahead of the records, lost messages with no warning.

    A resumed shadow fed the records again rejected every one (its counts were the checkpoint's
    too, so 'all rejected' never fired); bags overlapping by a third lost a third of each topic.
    """
    path, cfg, sur = saved
    again = Shadow.resume(path, cfg, sur)
    again.run(_data(), flush=False)
    lines = [w for w in again.warnings() if w.startswith("topic ")]
    assert len(lines) == 3 and all("messages rejected" in w and "clock is ahead" in w for w in lines), lines
    assert "topic frc_01: all 180 messages rejected" in lines[0]
    data = _data(90)
    shadow = Shadow(cfg, sur)
    shadow.run(_between(data, 0, 60), flush=False)
    shadow.run(_between(data, 40, 90), flush=False)  # its first 20 of 50 minutes are old
    lines = [w for w in shadow.warnings() if w.startswith("topic ")]
    assert len(lines) == 3, lines
    assert lines[0].startswith("topic frc_01: 120 of 660 messages (18 %) rejected for their stamps"), lines
    alone = Shadow(cfg, sur)
    alone.run(_between(data, 0, 60), flush=False)
    alone.run(_between(data, 60, 90), flush=False)
    assert not [w for w in alone.warnings() if w.startswith("topic ")]


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory) -> Path:
    return write_monitoring(tmp_path_factory.mktemp("bag") / "small", _data(60))


def _params(path: Path, **values: object) -> Path:
    import yaml

    body = {**CFG, **values}
    path.write_text(yaml.safe_dump({"bridge_shadow": {"ros__parameters": body}}))
    return path


def test_replay_leaves_the_live_nodes_checkpoint_alone(saved, small_bag, tmp_path, capsys) -> None:
    live = tmp_path / "live.npz"
    live.write_bytes(saved[0].read_bytes())
    before = _digest(live)
    params = _params(tmp_path / "p.yaml", checkpoint_path=str(live))
    assert main(["replay", str(small_bag), "--params", str(params), "--json"]) == 0
    assert _digest(live) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["live.npz", "p.yaml"]


def test_replay_checkpoint_option_resumes_and_refuses_other_parameters(small_bag, tmp_path, capsys) -> None:
    import json

    ckpt = tmp_path / "replay.npz"
    params = _params(tmp_path / "p.yaml")
    assert main(["replay", str(small_bag), "--params", str(params), "--checkpoint", str(ckpt), "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert ckpt.is_file()
    # the same bag again, resumed: it is known as taken (``test_taken_bags.py``), none is used twice.
    # The checkpoint holds the state before the end-of-bag close (a next bag goes on with the last
    # record open): this run closes those windows again, from the same data, to the same posterior;
    # the counts say so: this run's are those windows, the rest is under "resumed"
    assert main(["replay", str(small_bag), "--params", str(params), "--checkpoint", str(ckpt), "--json"]) == 0
    out = capsys.readouterr()
    again = json.loads(out.out)
    assert "taken whole into" in out.err
    assert again["messages"]["used"] == 0
    assert again["resumed"]["windows"] + again["windows"]["closed"] == first["windows"]["closed"]
    assert again["windows"]["closed"] <= 2  # the record's last window or two, no more
    np.testing.assert_allclose(again["posterior"]["mean_m"], first["posterior"]["mean_m"], rtol=1e-12, atol=0)
    assert again["resumed"]["messages_used"] == first["messages"]["used"]
    before = _digest(ckpt)
    other = _params(tmp_path / "q.yaml", window_s=30.0)
    assert main(["replay", str(small_bag), "--params", str(other), "--checkpoint", str(ckpt)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "window_s 60 (now 30)" in err[0] and str(ckpt) in err[0]
    assert _digest(ckpt) == before


@pytest.fixture(scope="module")
def two_records(munich_data: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[object, dict]:
    """The reference record and a record 4 h on, 20 mm lower, and ``replay --json`` of them as one bag.

    Made once for both splits of the test below (the same bag and replay for each).
    """
    import contextlib
    import io
    import json

    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.twin.real_records import Piece, build

    sc = build(
        munich_data / "Settlements",
        load_surrogate().A,
        [Piece("ref", 0.0), Piece("ref", 4.0, (-0.02, -0.02), 6.5)],
    )
    whole = write_monitoring(tmp_path_factory.mktemp("two_records") / "whole", sc.data)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["replay", str(whole), "--json"]) == 0
    return sc, json.loads(out.getvalue())


@pytest.mark.realdata
@pytest.mark.parametrize("split_h", [0.1, 4.07])
def test_a_recording_split_into_bags_inside_a_record_replays_as_one(
    two_records: tuple, tmp_path: Path, capsys, split_h: float
) -> None:
    """The reference record and a record 4 h on, 20 mm lower, written as two bags split inside a record.

    ``replay --checkpoint`` of one bag after the other must equal one replay of both. The
    checkpoint was written after the end-of-bag close of the open windows: the next bag's data of
    the window cut at the split came late (7022 messages at 0.1 h, 4622 at 4.07 h, rejected with
    no warning), the test car's window of the first record was used as data and the first part
    warned of vehicles parked at a record's end. Now the checkpoint holds the state before that
    close.
    """
    import json

    sc, whole = two_records
    cut = int(sc.starts_ns[0] + split_h * 3600e9)
    write_monitoring(tmp_path / "p1", sc.data.select(lambda t: t < cut))
    write_monitoring(tmp_path / "p2", sc.data.select(lambda t: t >= cut))

    def replay(*args: str) -> dict:
        assert main(["replay", *args, "--json"]) == 0
        return json.loads(capsys.readouterr().out)

    ckpt = str(tmp_path / "c.npz")
    replay(str(tmp_path / "p1"), "--checkpoint", ckpt)
    second = replay(str(tmp_path / "p2"), "--checkpoint", ckpt)
    assert second["rejected"].get("late", 0) == 0
    np.testing.assert_allclose(second["posterior"]["mean_m"], whole["posterior"]["mean_m"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(
        second["posterior"]["covariance_m2"], whole["posterior"]["covariance_m2"], rtol=1e-9, atol=0
    )
    assert [e["window"] for e in second["events"]] == [e["window"] for e in whole["events"]]
    assert second["rejected_windows"] == whole["rejected_windows"]  # every window, the checkpoint's too


def test_a_replay_resumed_from_a_held_record_counts_this_run_apart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A checkpoint of one short record, still held for the traffic screen, is a resume too.

    It has closed no window but has taken every message of its record; the next bag's replay
    reported both bags' counts as its own (the public records chained as two bags: ``145192 in,
    290441 used``) and no ``resumed``, because the resume was recognised by closed windows.
    """
    import json

    from bridge_shadow.estimate import load_config
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.series import MonitoringData

    def open_shadow_windows(path: Path) -> int:
        return Shadow.resume(path, load_config(), load_surrogate()).n_windows

    rng = np.random.default_rng(9)
    level = load_surrogate().reactions(np.zeros(2))
    bags = []
    for i, start_h in enumerate((0.0, 4.0)):  # two 12-minute records 4 h apart, 1 Hz
        stamps = T0 + int(start_h * 3600e9) + np.arange(720, dtype=np.int64) * 10**9
        forces = level + rng.normal(0.0, 60.0, (720, 2))
        data = MonitoringData.from_arrays(stamps, forces, stamps[::10], np.full(72, 8.0 + i))
        bags.append(write_monitoring(tmp_path / f"record{i}", data))
    ck = tmp_path / "ck.npz"
    assert main(["replay", str(bags[0]), "--checkpoint", str(ck), "--json"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert first["messages"]["used"] == 720 * 2 + 72
    # the checkpoint holds the state before the end-of-data close: the record held, no window closed
    assert open_shadow_windows(ck) == 0
    assert main(["replay", str(bags[1]), "--checkpoint", str(ck), "--json"]) == 0
    out = capsys.readouterr()
    js = json.loads(out.out)
    msgs = js["messages"]
    assert msgs["total"] == 720 * 2 + 72 and msgs["used"] + msgs["rejected"] == msgs["total"]
    assert js["resumed"]["messages_used"] == first["messages"]["used"]
    assert f"resumed from {ck}: {first['messages']['used']} messages, 0 windows" in out.err
    # windows and updates add up over the chain less what each run's end-of-data close made,
    # which the next run makes again: as one replay of both bags (read merged)
    assert main(["replay", str(bags[0]), str(bags[1]), "--json"]) == 0
    both = json.loads(capsys.readouterr().out)
    for key, at in (("closed", "closed"), ("updates", "updates")):
        chain = first["windows"][key] - first["windows"]["at_end"][at] + js["windows"][key]
        assert chain == both["windows"][key], key
    assert first["windows"]["at_end"]["closed"] == first["windows"]["closed"] > 0  # the record held whole


def test_the_resume_note_counts_messages_not_windows(tmp_path: Path) -> None:
    """The note's message count is the messages taken: used and rejected as messages.

    The rejected counts hold window reasons too; a chain of the real records said "290447
    messages" where 290441 were used and none rejected, the six more its traffic windows.
    """
    from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS
    from bridge_shadow.series import MonitoringData

    data = _data()
    f = data.forces["frc_01"]
    keep = np.ones(len(f.stamp_ns), bool)
    keep[60:65] = False  # minute 10 keeps one sample of frc_01: a sparse window
    stamp = np.r_[f.stamp_ns[keep], f.stamp_ns[3]]  # and one duplicate message
    forces = dict(data.forces)
    forces["frc_01"] = type(f)(stamp, np.r_[f.force_n[keep], f.force_n[3]], f.frame_id[0], stamp)
    shadow = Shadow(ShadowConfig(**CFG), placeholder_surrogate())
    shadow.run(MonitoringData(forces, data.temperature))
    rejected = shadow.rejected
    assert rejected["sparse_window"] >= 1 and rejected["duplicate"] == 1
    path = tmp_path / "state.npz"
    shadow.save_checkpoint(path)
    _, notes = open_shadow(ShadowConfig(**CFG, checkpoint_path=str(path)), placeholder_surrogate())
    taken = sum(shadow.used.values()) + sum(n for r, n in rejected.items() if r in MESSAGE_REASONS)
    assert any(f": {taken} messages, " in line for line in notes), notes
