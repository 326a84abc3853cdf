"""Streamed replay: the chunked reader equals the whole read, the streamed shadow equals ``Shadow.run``.

Memory cannot be timed in a test, so its structure is asserted: the reader never holds more
than a batch of decoded messages (sqlite3), pieces come strictly in arrival order, feed chunks
have exactly the requested size, and the plot history stays under its capacity.
"""

from __future__ import annotations

import itertools
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import read_monitoring, write_monitoring
from bridge_shadow.bagio.stream import MonitoringStream
from bridge_shadow.contract import CHANNELS
from bridge_shadow.replay import Prefetch, WindowHistory, arrival_chunks, replay_bag
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

T0 = 1_646_667_315_000_000_000


def _tied_data(n: int = 400, seed: int = 3) -> MonitoringData:
    """Build three topics with shared log times, in-topic repeats and frame_ids of several lengths.

    Ties across topics test the arrival order, repeats within a topic the storage order, and
    frame_ids of different lengths messages of one topic with different sizes; log time != stamp.
    """
    rng = np.random.default_rng(seed)
    log = T0 + np.repeat(np.arange(n // 2, dtype=np.int64), 2) * 500_000_000  # each log time twice
    frames = np.array(["frc_01", "frc_01_spare", ""], dtype=object)[rng.integers(0, 3, n)]
    f1 = ForceSeries(log + 3, rng.normal(2.6e5, 50, n), frames, log)
    f2 = ForceSeries(log[::2] - 5, rng.normal(2.2e5, 50, n // 2), "frc_02", log[::2])
    t_log = log[::8]
    temp = TemperatureSeries(t_log, rng.normal(5, 3, len(t_log)), np.zeros(len(t_log)), log_ns=t_log)
    return MonitoringData({"frc_01": f1, "frc_02": f2}, temp)


def _concat(pieces: list[MonitoringData]) -> MonitoringData:
    def cat(series: list, names: tuple[str, ...]) -> list[np.ndarray]:
        return [np.concatenate([getattr(s, a) for s in series]) for a in names]

    forces = {
        ch: ForceSeries(*cat([p.forces[ch] for p in pieces], ("stamp_ns", "force_n", "frame_id", "log_ns")))
        for ch in CHANNELS
    }
    names = ("stamp_ns", "temp_c", "variance", "frame_id", "log_ns")
    return MonitoringData(forces, TemperatureSeries(*cat([p.temperature for p in pieces], names)))


def _assert_same(a: MonitoringData, b: MonitoringData) -> None:
    """Exact: the same messages cut and joined again (copies, no arithmetic)."""
    for x, y in [(a.forces[ch], b.forces[ch]) for ch in CHANNELS] + [(a.temperature, b.temperature)]:
        np.testing.assert_array_equal(x.stamp_ns, y.stamp_ns)
        np.testing.assert_array_equal(x.log_ns, y.log_ns)
        value = "force_n" if isinstance(x, ForceSeries) else "temp_c"
        np.testing.assert_array_equal(getattr(x, value), getattr(y, value))
        assert list(x.frame_id) == list(y.frame_id)


def _arrival(data: MonitoringData) -> tuple[np.ndarray, np.ndarray]:
    """(topic, log) of every message in arrival order, as ``Shadow.run`` orders them."""
    logs = [data.forces[ch].log_ns for ch in CHANNELS] + [data.temperature.log_ns]
    topic = np.concatenate([np.full(len(x), i) for i, x in enumerate(logs)])
    order = np.argsort(np.concatenate(logs), kind="stable")
    return topic[order], np.concatenate(logs)[order]


def _drop_timestamp_index(bag: Path) -> None:
    for db3 in bag.glob("*.db3"):
        with sqlite3.connect(db3) as db:
            db.execute("DROP INDEX timestamp_idx")


@pytest.mark.parametrize(
    ("storage", "compress", "backend"),
    [
        ("sqlite3", False, "sqlite3"),
        ("mcap", False, "mcap"),
        ("mcap", True, "mcap"),
        ("sqlite3", False, "rosbags"),
    ],
)
def test_chunked_read_equals_whole_read(tmp_path: Path, storage: str, compress: bool, backend: str) -> None:
    data = _tied_data()
    bag = write_monitoring(tmp_path / "bag", data, storage, compress=compress)
    if backend == "rosbags":  # a sqlite3 bag the slice reader refuses: rosbags streams it
        _drop_timestamp_index(bag)
    whole = read_monitoring(bag)
    _assert_same(whole, data)
    for batch in (7, 64, 100_000):
        with MonitoringStream(bag, batch=batch) as stream:
            pieces = list(stream)
            assert stream.backend == backend
            if backend == "sqlite3":  # a slice never holds more than a batch, ties aside (2 per log time x 3)
                assert stream.peak_pending <= max(batch, 6)
        _assert_same(_concat(pieces), whole)
        # each piece lies wholly before the next in arrival order (log time strictly increases)
        for a, b in itertools.pairwise(pieces):
            assert _arrival(a)[1].max() < _arrival(b)[1].min()
        if batch == 7 and backend != "mcap":
            assert len(pieces) > 20


@pytest.mark.parametrize(
    ("storage", "compress", "backend"),
    [("sqlite3", False, "sqlite3"), ("mcap", True, "mcap"), ("sqlite3", False, "rosbags")],
)
def test_raw_pieces_are_the_bag_bytes_in_arrival_order(
    tmp_path: Path, storage: str, compress: bool, backend: str
) -> None:
    """What the live player publishes: every stored message once, byte for byte, arrival order."""
    from bridge_shadow.bagio import read_raw_topics
    from bridge_shadow.contract import INPUT_TOPICS
    from bridge_shadow.ros.live_replay import merge_log_order

    bag = write_monitoring(tmp_path / "bag", _tied_data(), storage, compress=compress)
    if backend == "rosbags":
        _drop_timestamp_index(bag)
    whole = read_raw_topics(bag, INPUT_TOPICS)  # rosbags' own reader, whole
    names = list(INPUT_TOPICS)
    topic, pos, _ = merge_log_order([whole[t][0] for t in names])
    expected = [whole[names[i]][1][j] for i, j in zip(topic.tolist(), pos.tolist(), strict=True)]
    with MonitoringStream(bag, batch=64) as stream:
        pieces = list(stream.raw_pieces())
        assert stream.backend == backend
        if backend == "sqlite3":
            assert stream.peak_pending <= 64 + 6
    got, last = [], -1
    for blocks in pieces:
        logs = [np.empty(0, np.int64) if b is None else b.log_ns for b in blocks]
        assert min(x.min() for x in logs if len(x)) > last  # each piece after the one before
        last = max(x.max() for x in logs if len(x))
        t, p, _ = merge_log_order(logs)
        raws = [[] if b is None else b.raws() for b in blocks]
        got += [raws[i][j] for i, j in zip(t.tolist(), p.tolist(), strict=True)]
    assert len(pieces) > 5 or backend == "mcap"  # one MCAP chunk (about 1 MB) holds this bag
    assert got == expected


def test_feed_chunks_cut_arrival_order_exactly() -> None:
    data = _tied_data(n=300)
    topic, _ = _arrival(data)
    pieces = [data]
    chunks = list(arrival_chunks(pieces, chunk=41))
    assert [c.messages for c in chunks] == [41] * (len(topic) // 41) + [len(topic) % 41]
    # chunk k holds, per topic, exactly the messages of that topic among arrival positions [41 k, 41 (k + 1))
    for k, c in enumerate(chunks):
        counts = np.bincount(topic[41 * k : 41 * (k + 1)], minlength=3)
        assert [len(c.forces[0][0]), len(c.forces[1][0]), len(c.temperature[0])] == counts.tolist()
    np.testing.assert_array_equal(  # integer ns, cut and joined again
        np.concatenate([c.forces[1][0] for c in chunks]), data.forces["frc_02"].stamp_ns
    )


def test_window_history_stays_bounded_and_evenly_spaced() -> None:
    hist = WindowHistory(capacity=100)
    hist.extend(range(100_000))
    assert len(hist.kept) <= 100 and hist.seen == 100_000
    steps = np.diff(hist.kept)
    assert np.all(steps == hist.stride) and hist.kept[0] == 0 and hist.kept[-1] >= 100_000 - hist.stride


def test_prefetch_hands_on_items_errors_and_stops() -> None:
    with Prefetch(range(10), depth=2) as items:
        assert list(items) == list(range(10))

    def failing():
        yield 1
        raise ValueError("bad slice")

    with Prefetch(failing()) as items, pytest.raises(ValueError, match="bad slice"):
        list(items)
    produced = []

    def endless():
        for i in range(10**9):
            produced.append(i)
            yield i

    with Prefetch(endless(), depth=2) as items:
        assert next(iter(items)) == 0
    assert len(produced) <= 5  # the reader stopped when the consumer left, a bounded number ahead


@pytest.mark.parametrize("bag_name", ["baseline_1d", "demo_3d"])
def test_streamed_replay_equals_in_memory_run(root: Path, bag_name: str) -> None:
    """sqlite3 (baseline_1d) and zstd MCAP (demo_3d): same posterior, windows, rejections, outputs."""
    from bridge_shadow.estimate import Shadow, load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    bag = root / "bags" / bag_name
    config, surrogate = load_config(None), load_surrogate()
    ref = Shadow(config, surrogate).run(read_monitoring(bag))
    # a small feed chunk and read batch, read in a thread, on the sqlite3 bag: none of it may matter
    chunk, batch, prefetch = (997, 333, True) if bag_name == "baseline_1d" else (200_000, None, False)
    res, stats = replay_bag(
        bag, Shadow(config, surrogate), chunk=chunk, batch=batch, keep_all=True, prefetch=prefetch
    )
    np.testing.assert_allclose(res.mean_m, ref.mean_m, rtol=1e-12, atol=0)
    np.testing.assert_allclose(res.covariance_m2, ref.covariance_m2, rtol=1e-12, atol=0)
    assert (res.messages, res.windows, res.updates) == (ref.messages, ref.windows, ref.updates)
    assert res.rejected == ref.rejected and res.used == ref.used
    assert stats.messages == ref.messages and stats.windows_out == len(ref.outputs) == len(res.outputs)
    np.testing.assert_allclose(res.history()["mean_m"], ref.history()["mean_m"], rtol=1e-12, atol=1e-18)


def test_cli_import_stays_light() -> None:
    """``bridge-shadow --help`` imports neither scipy.stats (through filterpy) nor rclpy."""
    code = (
        "import sys, bridge_shadow.cli as c; c.build_parser(); "
        "heavy = ('scipy.stats', 'filterpy', 'rclpy', 'matplotlib', 'rosbags'); "
        "heavy = [m for m in heavy if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


@pytest.mark.parametrize("args", [["--help"], ["replay", "bags/baseline_1d"]])
def test_closed_stdout_pipe_ends_quietly(root: Path, args: list[str]) -> None:
    """``bridge-shadow ... | head -1`` where head has gone: no traceback; exit 141 (128 + SIGPIPE).

    argparse itself ignores write errors of ``--help``: that exits 0 when stdout is unbuffered.
    """
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first write
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "bridge_shadow.cli", *args],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            cwd=root,
            timeout=120,
        )
    finally:
        os.close(write_end)
    assert proc.stderr == ""
    assert proc.returncode == 141 or (args == ["--help"] and proc.returncode == 0)


def test_head_1_takes_the_first_line_and_the_replay_ends_with_141(root: Path) -> None:
    """``replay BAG | head -1`` exits 141, as the README says.

    The first line (what is replayed, with which model) leaves at once, the reader takes it and
    goes; the result, written when the replay is done, meets the closed pipe.
    """
    proc = subprocess.Popen(
        [sys.executable, "-m", "bridge_shadow.cli", "replay", "bags/baseline_1d"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=root,
    )
    assert proc.stdout is not None and proc.stderr is not None
    first = proc.stdout.readline()  # head -1
    proc.stdout.close()
    assert first.startswith("replay bags/baseline_1d: surrogate ")
    assert proc.wait(120) == 141
    assert proc.stderr.read() == ""


def test_sqlite_stream_refuses_what_it_cannot_order(tmp_path: Path) -> None:
    """No timestamp index: the slice reader is not used (rosbags streams it; see the read test)."""
    from bridge_shadow.bagio.sqlite_stream import SqliteSlices, SqliteStreamUnsupported

    bag = write_monitoring(tmp_path / "bag", _tied_data(n=20), "sqlite3")
    copy = tmp_path / "copy"
    shutil.copytree(bag, copy)
    _drop_timestamp_index(copy)
    with pytest.raises(SqliteStreamUnsupported, match="no index"):
        SqliteSlices(list(copy.glob("*.db3")), ["/bridge/frc_01/force"])
    with SqliteSlices(list(bag.glob("*.db3")), ["/bridge/frc_01/force"]) as slices:
        assert sum(len(b[0].log_ns) for b in slices if b[0] is not None) == 20


def test_batched_float_arrays_are_rosbags_bytes(tmp_path: Path) -> None:
    """``float64_array_raws`` (one template, data patched) equals rosbags' serialization per message."""
    from bridge_shadow.bagio import BagOutputWriter, get_typestore
    from bridge_shadow.contract import FLOAT_ARRAY_TYPE

    ts = get_typestore()
    rng = np.random.default_rng(5)
    cov = rng.normal(size=(4, 2, 2))
    with BagOutputWriter(tmp_path / "out") as writer:
        raws = writer.float64_array_raws(cov, ["row", "col"])
        flat = writer.float64_array_raws(cov[:, 0, :], [])
    for k in range(4):
        dims = [
            ts.types["std_msgs/msg/MultiArrayDimension"](label=lab, size=2, stride=stride)
            for lab, stride in (("row", 4), ("col", 2))
        ]
        layout = ts.types["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)
        msg = ts.types[FLOAT_ARRAY_TYPE](layout=layout, data=cov[k].ravel())
        assert raws[k] == bytes(ts.serialize_cdr(msg, FLOAT_ARRAY_TYPE))
        bare = ts.types[FLOAT_ARRAY_TYPE](
            layout=ts.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0), data=cov[k, 0]
        )
        assert flat[k] == bytes(ts.serialize_cdr(bare, FLOAT_ARRAY_TYPE))


def test_damaged_mcap_chunk_is_one_bag_error(tmp_path: Path) -> None:
    """A zstd chunk that no longer decompresses: CorruptBagError from the stream and the whole read."""
    from bridge_shadow.bagio import CorruptBagError
    from bridge_shadow.bagio.mcap_stream import McapChunks

    bag = write_monitoring(tmp_path / "bag", _tied_data(n=2000), "mcap", compress=True)
    (file,) = bag.glob("*.mcap")
    with McapChunks([file], []) as chunks:
        chunk = chunks._chunks[0]
    with open(file, "r+b") as fh:  # the zstd frame header: start, end, size, crc, "zstd", length
        fh.seek(chunk.body + 8 + 8 + 8 + 4 + 4 + len("zstd") + 8)
        fh.write(b"\x13" * 8)
    with pytest.raises(CorruptBagError, match="corrupt"):
        list(MonitoringStream(bag))
    with pytest.raises(CorruptBagError, match="corrupt"):
        read_monitoring(bag)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_chunked_read_of_a_bag_written_topic_by_topic(tmp_path: Path, storage: str) -> None:
    """Read rows stored out of log-time order (each topic written whole, in turn).

    MCAP chunks then overlap in time and sqlite3 rowids are out of log order; the pieces still
    equal the whole read, in arrival order.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    from bridge_shadow.bagio import encode_stamped_floats, get_typestore
    from bridge_shadow.contract import FORCE_TOPICS, FORCE_TYPE, TEMPERATURE_TOPIC, TEMPERATURE_TYPE

    data = _tied_data(n=16_000)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(tmp_path / "bag", version=9, storage_plugin=plugin) as writer:
        for ch in reversed(CHANNELS):  # frc_02 first: storage order is not arrival order
            f = data.forces[ch]
            conn = writer.add_connection(FORCE_TOPICS[ch], FORCE_TYPE, typestore=get_typestore())
            values = np.zeros((len(f), 6))
            values[:, 2] = f.force_n
            for t, raw in zip(
                f.log_ns.tolist(), encode_stamped_floats(f.stamp_ns, f.frame_id, values), strict=True
            ):
                writer.write(conn, t, raw)
        t = data.temperature
        conn = writer.add_connection(TEMPERATURE_TOPIC, TEMPERATURE_TYPE, typestore=get_typestore())
        raws = encode_stamped_floats(t.stamp_ns, t.frame_id, np.column_stack([t.temp_c, t.variance]))
        for stamp, raw in zip(t.log_ns.tolist(), raws, strict=True):
            writer.write(conn, stamp, raw)
    whole = read_monitoring(tmp_path / "bag")
    _assert_same(whole, data)
    with MonitoringStream(tmp_path / "bag", batch=1000) as stream:
        pieces = list(stream)
        assert stream.backend == storage
    _assert_same(_concat(pieces), whole)
    for a, b in itertools.pairwise(pieces):
        assert _arrival(a)[1].max() < _arrival(b)[1].min()
