"""``synth`` in bounded memory: long records segment by segment, archives of bridges and days.

A record longer than a segment is simulated in segments (``twin.stream``) whose world (weather,
settlement path) is the whole record's: so the segmented record's air temperature equals the
whole record's up to the sensor noise, and its stamps run on without a seam. Segments here are
made small (``segment_samples``) so the test stays lean; the sizes are what changes, not the code.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from bridge_shadow.bagio import read_monitoring
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.twin.config import TwinConfig
from bridge_shadow.twin.simulate import simulate
from bridge_shadow.twin.stream import merge_truths, record_segments, write_stream_bag

DAYS, RATE = 2.0, 0.05  # 8,640 force samples per channel


def test_segments_tile_the_record_and_keep_its_world(tmp_path: Path) -> None:
    """Stamps of the segments tile the whole record's; the weather is continuous across segments."""
    sur = placeholder_surrogate()
    whole, _ = simulate(DAYS, RATE, seed=3, surrogate=sur)
    bag, truth = write_stream_bag(
        tmp_path / "bag", record_segments(DAYS, RATE, segment_samples=1000, seed=3, surrogate=sur)
    )
    assert truth["segments"] == 9
    data = read_monitoring(bag)
    t_whole, t_seg = whole.temperature, data.temperature
    # every temperature stamp of the record, once, in order (dropouts differ: other random streams)
    assert np.all(np.diff(t_seg.stamp_ns) > 0)
    common, iw, iseg = np.intersect1d(t_whole.stamp_ns, t_seg.stamp_ns, return_indices=True)
    assert len(common) > 0.9 * len(t_whole)
    diff = t_whole.temp_c[iw] - t_seg.temp_c[iseg]
    sd = TwinConfig().temp_sensor_sd_k
    ok = np.isfinite(diff)
    # the same weather: only the two sensors' noise differs (sd * sqrt(2)); a restarted weather would not
    assert np.max(np.abs(diff[ok])) < 6 * np.sqrt(2) * sd
    assert truth["counts"]["temperature_messages"] == len(t_seg)
    assert truth["counts"]["force_messages"]["frc_01"] == len(data.forces["frc_01"])
    # the force grid runs on over segment boundaries (every stamp is on the record's grid)
    step = round(1e9 / RATE)
    s = data.forces["frc_01"].stamp_ns
    assert np.all((s - s[0]) % step == 0)


def test_a_record_that_fits_one_segment_is_simulate_itself() -> None:
    """One segment: exactly ``simulate`` (so the bundled bags and their commands are unchanged)."""
    sur = placeholder_surrogate()
    ((data, truth),) = list(record_segments(DAYS, RATE, seed=4, surrogate=sur))
    ref, _ = simulate(DAYS, RATE, seed=4, surrogate=sur)
    np.testing.assert_array_equal(data.forces["frc_02"].stamp_ns, ref.forces["frc_02"].stamp_ns)  # integer ns
    np.testing.assert_allclose(data.forces["frc_02"].force_n, ref.forces["frc_02"].force_n, rtol=1e-12)
    assert merge_truths([truth]) is truth


def test_a_drift_runs_on_over_segments() -> None:
    """The settlement path is the record's: the last segment's drift is the record's, not restarted."""
    sur = placeholder_surrogate()
    segs = list(
        record_segments(
            DAYS, RATE, segment_samples=3000, seed=1, surrogate=sur, effects={"settlement_drift": 1e-4}
        )
    )
    truths = [t for _, t in segs]
    assert truths[-1]["settlement"]["end_m"][0] == pytest.approx(-1e-4 * DAYS, rel=1e-3)
    assert merge_truths(truths)["settlement"]["start_m"][0] == pytest.approx(0.0, abs=1e-12)


def test_synth_archive_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``synth --archive``: bridges x daily bags, a truth per bridge; refuses to overwrite silently."""
    from bridge_shadow.cli import main

    out = tmp_path / "fleet"
    argv = ["synth", "--archive", str(out), "--bridges", "2", "--days", "1.5", "--rate", "0.02", "--json"]
    assert main(argv) == 0
    js = json.loads(capsys.readouterr().out)
    assert [b["bridge"] for b in js["bridges"]] == ["bridge_00", "bridge_01"]
    assert js["duration_s"] == pytest.approx(1.5 * 86400.0, rel=1e-12)  # SI, --days for people
    assert js["bag_duration_s"] == pytest.approx(86400.0, rel=1e-12)  # one bag a day by default
    assert sorted(p.name for p in (out / "bridge_01").iterdir()) == ["day_0000", "day_0001", "truth.yaml"]
    day0 = read_monitoring(out / "bridge_00" / "day_0000")
    day1 = read_monitoring(out / "bridge_00" / "day_0001")
    assert day0.forces["frc_01"].stamp_ns[-1] < day1.forces["frc_01"].stamp_ns[0]
    assert main(argv) == 2  # exists: one line, nothing touched
    assert "exists already" in capsys.readouterr().err


def _messages(bag: Path) -> list[tuple[str, int, bytes]]:
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return [(c.topic, t, bytes(raw)) for c, t, raw in reader.messages()]


def test_the_bulk_insert_writes_what_rosbags_writes_message_by_message(tmp_path: Path) -> None:
    """``write_merged`` into sqlite3 (one executemany) reads back as rosbags' own ``write`` per message."""
    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.bagio.writer import BagOutputWriter

    data, _ = simulate(0.02, 1.0, seed=4)
    bulk = write_monitoring(tmp_path / "bulk", data)
    got = _messages(bulk)
    types = {c.topic: c.msgtype for c in _connections(bulk)}
    with BagOutputWriter(tmp_path / "one", "sqlite3") as bag:  # the reference: rosbags' write
        for topic, t, raw in got:
            bag.write_raw(topic, types[topic], t, raw)
    assert len(got) == sum(len(s) for s in data.forces.values()) + len(data.temperature)
    assert _messages(tmp_path / "one") == got
    from rosbags.rosbag2 import Reader

    with Reader(bulk) as a, Reader(tmp_path / "one") as b:  # the metadata's counts and time range
        assert (a.message_count, a.start_time, a.end_time) == (b.message_count, b.start_time, b.end_time)
        assert sorted((c.topic, c.msgcount) for c in a.connections) == sorted(
            (c.topic, c.msgcount) for c in b.connections
        )


def _connections(bag: Path) -> list:
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return list(reader.connections)


def test_an_archive_written_on_dask_workers_equals_the_serial_one(tmp_path: Path) -> None:
    """``write_archive`` on two Dask worker processes: every bag's messages and truth as written serially.

    Worker processes, not the suite's one-thread ``engine``: the bags are simulated and written in
    other processes, as ``synth --archive`` on a local cluster does.
    """
    from bridge_shadow.engine import client_mapper, dask_client
    from bridge_shadow.twin.stream import BAGS_PER_CALL, write_archive

    args = {"bridges": 2, "days": 0.5, "rate_hz": 0.5, "seed": 5, "bag_days": 0.05}
    assert 2 * 10 > BAGS_PER_CALL  # more than one call of the mapper
    seen: list[float] = []
    serial = write_archive(tmp_path / "serial", **args)
    with dask_client(workers=2) as client:
        parallel = write_archive(
            tmp_path / "dask", mapper=client_mapper(client), progress=seen.append, **args
        )
    assert parallel == serial
    assert seen[-1] == 1.0 and seen == sorted(seen) and len(seen) == -(-20 // BAGS_PER_CALL)
    bags = sorted(p.relative_to(tmp_path / "serial") for p in (tmp_path / "serial").glob("bridge_*/day_*"))
    assert len(bags) == 20
    # simulated in other processes: stamps and counts exact, computed values to rounding
    for rel in bags:
        got, want = read_monitoring(tmp_path / "dask" / rel), read_monitoring(tmp_path / "serial" / rel)
        for ch in want.forces:
            np.testing.assert_array_equal(got.forces[ch].stamp_ns, want.forces[ch].stamp_ns)
            np.testing.assert_allclose(got.forces[ch].force_n, want.forces[ch].force_n, rtol=1e-12)
        np.testing.assert_array_equal(got.temperature.stamp_ns, want.temperature.stamp_ns)
        np.testing.assert_allclose(got.temperature.temp_c, want.temperature.temp_c, rtol=1e-12)
    for b in ("bridge_00", "bridge_01"):
        got, want = (
            yaml.safe_load((tmp_path / run / b / "truth.yaml").read_text()) for run in ("dask", "serial")
        )
        got, want = _leaves(got), _leaves(want)
        assert got.keys() == want.keys()
        for key, value in want.items():
            is_number = isinstance(value, float | int) and not isinstance(value, bool)
            assert got[key] == (pytest.approx(value, rel=1e-12, abs=1e-15) if is_number else value), key


def _leaves(tree: object, path: str = "") -> dict[str, object]:
    """Flatten nested dicts and lists to ``{path: leaf}`` (numbers compared with a tolerance)."""
    if isinstance(tree, dict):
        return {k: v for key, sub in tree.items() for k, v in _leaves(sub, f"{path}/{key}").items()}
    if isinstance(tree, list):
        return {k: v for i, sub in enumerate(tree) for k, v in _leaves(sub, f"{path}/{i}").items()}
    return {path: tree}
