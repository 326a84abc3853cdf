"""Bag I/O: round trips in both storages, CDR codec against rosbags, typed errors on bad bags."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2 import StoragePlugin as Plugin

from bridge_shadow.bagio import (
    BagError,
    BagExistsError,
    BagNotFoundError,
    BagOutputWriter,
    CorruptBagError,
    MissingTopicError,
    NotABagError,
    UnexpectedTypeError,
    bag_summary,
    decode_buffer,
    decode_stamped_floats,
    encode_stamped_floats,
    get_typestore,
    iter_raw,
    read_monitoring,
    write_monitoring,
)
from bridge_shadow.contract import (
    COVARIANCE_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE_TOPICS,
    FORCE_TYPE,
    MEAN_TOPIC,
    TEMPERATURE_TOPIC,
    TEMPERATURE_TYPE,
)
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

T0 = 1_646_667_315_601_000_000  # 2022-03-07T15:35:15.601Z
STORAGES = ("sqlite3", "mcap")


def _data(n: int = 500, seed: int = 1) -> MonitoringData:
    """Forces with irregular stamps and frame_ids of several lengths, log time != stamp."""
    rng = np.random.default_rng(seed)
    stamp = T0 + np.cumsum(rng.integers(1, 20_000_000, n))
    frames = np.array(["frc_01", "frc_01_spare", "", "a" * 13, "ü"], dtype=object)[rng.integers(0, 5, n)]
    f1 = ForceSeries(stamp, 2.6e5 + rng.normal(0, 50, n), frames, log_ns=stamp + 1_000)
    f2 = ForceSeries(stamp[::2] - 7, rng.normal(2.2e5, 50, len(stamp[::2])), "frc_02")
    f2.force_n[3] = np.nan
    temp = TemperatureSeries(stamp[::10], rng.normal(5, 3, len(stamp[::10])), np.full(len(stamp[::10]), 0.01))
    return MonitoringData({"frc_01": f1, "frc_02": f2}, temp)


def _assert_same(a: MonitoringData, b: MonitoringData) -> None:
    """Exact: the same messages through a bag and back (copies, no arithmetic)."""
    for ch in ("frc_01", "frc_02"):
        x, y = a.forces[ch], b.forces[ch]
        np.testing.assert_array_equal(x.stamp_ns, y.stamp_ns)
        np.testing.assert_array_equal(x.log_ns, y.log_ns)
        np.testing.assert_array_equal(x.force_n, y.force_n)  # bit-exact, NaN included
        assert list(x.frame_id) == list(y.frame_id)
    x, y = a.temperature, b.temperature
    for name in ("stamp_ns", "log_ns", "temp_c", "variance"):
        np.testing.assert_array_equal(getattr(x, name), getattr(y, name))
    assert list(x.frame_id) == list(y.frame_id)


@pytest.mark.parametrize(("storage", "compress"), [("sqlite3", False), ("mcap", False), ("mcap", True)])
def test_round_trip_is_exact(tmp_path: Path, storage: str, compress: bool) -> None:
    data = _data()
    write_monitoring(tmp_path / "bag", data, storage, compress=compress)
    _assert_same(data, read_monitoring(tmp_path / "bag"))
    summary = bag_summary(tmp_path / "bag")
    assert summary["storage"] == storage
    assert summary["topics"][FORCE_TOPICS["frc_02"]] == {"type": FORCE_TYPE, "count": 250}
    assert summary["start_ns"] == min(s.log_ns.min() for s in data.forces.values())


@pytest.mark.parametrize("storage", STORAGES)
def test_messages_in_log_time_order_and_vectorized_decode_equals_rosbags(
    tmp_path: Path, storage: str
) -> None:
    data = _data()
    write_monitoring(tmp_path / "bag", data, storage)
    items = list(iter_raw(tmp_path / "bag"))
    logs = [t for _, _, t, _ in items]
    assert logs == sorted(logs) and len(items) == data.n_messages
    ts = get_typestore()
    got = read_monitoring(tmp_path / "bag")
    for ch, topic in FORCE_TOPICS.items():
        msgs = [ts.deserialize_cdr(raw, FORCE_TYPE) for t, _, _, raw in items if t == topic]
        ref_stamp = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs]
        # exact: both decode the same bytes (copies, no arithmetic)
        np.testing.assert_array_equal(got.forces[ch].stamp_ns, ref_stamp)
        np.testing.assert_array_equal(got.forces[ch].force_n, [m.wrench.force.z for m in msgs])
        assert list(got.forces[ch].frame_id) == [m.header.frame_id for m in msgs]
    temps = [ts.deserialize_cdr(raw, TEMPERATURE_TYPE) for t, _, _, raw in items if t == TEMPERATURE_TOPIC]
    np.testing.assert_array_equal(got.temperature.temp_c, [m.temperature for m in temps])
    np.testing.assert_array_equal(got.temperature.variance, [m.variance for m in temps])


def test_numpy_encoder_is_byte_identical_to_rosbags_serializer() -> None:
    ts = get_typestore()
    Time, Header = ts.types["builtin_interfaces/msg/Time"], ts.types["std_msgs/msg/Header"]
    Vec, Wrench = ts.types["geometry_msgs/msg/Vector3"], ts.types["geometry_msgs/msg/Wrench"]
    stamps = np.array([T0, 0, 2**31 * 10**9 - 1, T0 + 999_999_999])
    frames = ["frc_01", "", "abc", "frame_of_seven!"]
    values = np.arange(24, dtype=float).reshape(4, 6) * 1.1 - 3
    raws = encode_stamped_floats(stamps, frames, values)
    for raw, stamp, frame, v in zip(raws, stamps.tolist(), frames, values, strict=True):
        header = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id=frame)
        wrench = Wrench(force=Vec(x=v[0], y=v[1], z=v[2]), torque=Vec(x=v[3], y=v[4], z=v[5]))
        msg = ts.types[FORCE_TYPE](header=header, wrench=wrench)
        assert raw == bytes(ts.serialize_cdr(msg, FORCE_TYPE))
        temp = ts.types[TEMPERATURE_TYPE](header=header, temperature=v[0], variance=v[1])
        (traw,) = encode_stamped_floats(np.array([stamp]), frame, v[None, :2])
        assert traw == bytes(ts.serialize_cdr(temp, TEMPERATURE_TYPE))
    # one frame_id for all, as a str or as an array of it (one block, without sorting the strings)
    one = encode_stamped_floats(stamps, np.array(["frc_01"] * 4, dtype=object), values)
    assert one == encode_stamped_floats(stamps, "frc_01", values)
    for raw, stamp, v in zip(one, stamps.tolist(), values, strict=True):
        header = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="frc_01")
        wrench = Wrench(force=Vec(x=v[0], y=v[1], z=v[2]), torque=Vec(x=v[3], y=v[4], z=v[5]))
        assert raw == bytes(ts.serialize_cdr(ts.types[FORCE_TYPE](header=header, wrench=wrench), FORCE_TYPE))
    assert encode_stamped_floats(stamps[:0], "frc_01", values[:0]) == []
    assert encode_stamped_floats(stamps[:0], np.array([], dtype=object), values[:0]) == []


def test_decoder_reads_big_endian_cdr_and_rejects_garbage() -> None:
    ts = get_typestore()
    Time, Header = ts.types["builtin_interfaces/msg/Time"], ts.types["std_msgs/msg/Header"]
    msg = ts.types[TEMPERATURE_TYPE](
        header=Header(stamp=Time(sec=12, nanosec=34), frame_id="air"), temperature=-6.5, variance=0.25
    )
    big = bytes(ts.serialize_cdr(msg, TEMPERATURE_TYPE, little_endian=False))
    little = bytes(ts.serialize_cdr(msg, TEMPERATURE_TYPE))
    stamp, frames, values = decode_stamped_floats([big, little], 2)
    np.testing.assert_array_equal(stamp, [12 * 10**9 + 34] * 2)  # exact: decoded bytes, no arithmetic
    assert list(frames) == ["air", "air"]
    np.testing.assert_array_equal(values, [[-6.5, 0.25], [-6.5, 0.25]])
    with pytest.raises(ValueError, match="too short"):
        decode_stamped_floats([little[:20]], 2)
    bad = bytearray(little)
    bad[12] = 200  # string length runs past the floats
    with pytest.raises(ValueError, match="string length"):
        decode_stamped_floats([bytes(bad)], 2)


def test_a_few_messages_decode_one_by_one_as_the_blocks_do() -> None:
    """Small batches (a live node's drains) go through ``struct``; the same as the numpy blocks.

    Both byte orders, frame_ids of several lengths, both layouts (rosbags serializes them); and
    every malformation the blocks reject, the one-by-one path rejects too.
    """
    from bridge_shadow.bagio.cdr import SMALL_BATCH, CdrFormatError

    ts = get_typestore()
    Time, Header = ts.types["builtin_interfaces/msg/Time"], ts.types["std_msgs/msg/Header"]
    rng = np.random.default_rng(3)
    raws = []
    for i in range(SMALL_BATCH):
        header = Header(
            stamp=Time(sec=int(rng.integers(-5, 2**31 - 1)), nanosec=int(rng.integers(0, 10**9))),
            frame_id=["frc_01", "a", "air_temperature", "ü"][i % 4],
        )
        msg = ts.types[TEMPERATURE_TYPE](header=header, temperature=rng.normal(), variance=rng.random())
        raws.append(bytes(ts.serialize_cdr(msg, TEMPERATURE_TYPE, little_endian=bool(i % 3))))
    lengths = np.array([len(r) for r in raws])
    blocks = decode_buffer(np.frombuffer(b"".join(raws), np.uint8), np.cumsum(lengths) - lengths, lengths, 2)
    few = decode_stamped_floats(raws, 2)
    # exact: both read the same bytes (integer stamps, float64s copied, no arithmetic)
    np.testing.assert_array_equal(few[0], blocks[0])
    assert few[1].dtype == object and list(few[1]) == list(blocks[1])
    np.testing.assert_array_equal(few[2], blocks[2])
    good = raws[1]
    broken = [good[:20], b"\x01" + good[1:], good[:1] + b"\x05" + good[2:]]
    long_name = bytearray(good)
    long_name[12] = 200  # string length runs past the floats
    zero = bytearray(good)
    zero[12:16] = b"\x00\x00\x00\x00"
    for bad in [*broken, bytes(long_name), bytes(zero)]:
        batch = [good, bad]
        with pytest.raises(CdrFormatError):
            decode_stamped_floats(batch, 2)
        ln = np.array([len(r) for r in batch])
        with pytest.raises(CdrFormatError):
            decode_buffer(np.frombuffer(b"".join(batch), np.uint8), np.cumsum(ln) - ln, ln, 2)


def test_a_batch_of_alike_messages_decodes_as_one_block_as_one_by_one() -> None:
    """``_decode_uniform`` (one length, byte order and frame_id) equals ``_decode_few``, else declines."""
    from bridge_shadow.bagio.cdr import UNIFORM_MIN, CdrFormatError, _decode_few, _decode_uniform

    ts = get_typestore()
    Time, Header = ts.types["builtin_interfaces/msg/Time"], ts.types["std_msgs/msg/Header"]
    rng = np.random.default_rng(5)

    def wrench(frame: str, little: bool) -> bytes:
        header = Header(
            stamp=Time(sec=int(rng.integers(-5, 2**31 - 1)), nanosec=int(rng.integers(0, 10**9))),
            frame_id=frame,
        )
        vec = ts.types["geometry_msgs/msg/Vector3"]
        w = ts.types["geometry_msgs/msg/Wrench"](
            force=vec(x=rng.normal(), y=rng.normal(), z=2e5 * rng.random()), torque=vec(x=0.0, y=0.0, z=-1.5)
        )
        return bytes(
            ts.serialize_cdr(ts.types[FORCE_TYPE](header=header, wrench=w), FORCE_TYPE, little_endian=little)
        )

    for little in (True, False):
        for frame in ("frc_01", "ü", "a_long_frame_identifier"):
            raws = [wrench(frame, little) for _ in range(UNIFORM_MIN + 7)]
            block = _decode_uniform(raws, 6)
            assert block is not None
            one_by_one = _decode_few(raws, 6)
            np.testing.assert_array_equal(block[0], one_by_one[0])  # exact: integer stamps from the bytes
            assert list(block[1]) == list(one_by_one[1]) == [frame] * len(raws)
            np.testing.assert_array_equal(block[2], one_by_one[2])  # float64s copied, no arithmetic
            assert block[2].dtype == np.float64 and block[2].dtype.isnative
            np.testing.assert_array_equal(decode_stamped_floats(raws, 6)[0], one_by_one[0])  # integer ns
    raws = [wrench("frc_01", True) for _ in range(UNIFORM_MIN)]
    for odd in (wrench("frc_02", True), wrench("frc_01", False), wrench("frc_001", True)):
        mixed = [*raws[:-1], odd]  # another frame_id, byte order, length: not alike
        assert _decode_uniform(mixed, 6) is None
        # float64s copied from the same bytes by both paths, no arithmetic: exact
        np.testing.assert_array_equal(decode_stamped_floats(mixed, 6)[2], _decode_few(mixed, 6)[2])
    padded = bytearray(raws[-1])
    padded[16 + len("frc_01") + 1] = 0xAB  # the alignment byte after the frame_id's NUL
    mixed = [*raws[:-1], bytes(padded)]  # read one by one up to the floats: not alike either
    assert _decode_uniform(mixed, 6) is None
    assert list(decode_stamped_floats(mixed, 6)[1]) == list(_decode_few(mixed, 6)[1])
    broken = [r[:20] for r in raws]  # alike, and all too short: declined, then refused as before
    assert _decode_uniform(broken, 6) is None
    with pytest.raises(CdrFormatError, match="too short"):
        decode_stamped_floats(broken, 6)


def test_optional_topics_and_missing_topic(tmp_path: Path) -> None:
    data = _data(50)
    with BagOutputWriter(tmp_path / "forces_only") as bag:
        for ch in ("frc_01", "frc_02"):
            s = data.forces[ch]
            raws = encode_stamped_floats(
                s.stamp_ns, ch, np.column_stack([np.zeros((len(s), 2)), s.force_n, np.zeros((len(s), 3))])
            )
            bag.write_many_raw(FORCE_TOPICS[ch], FORCE_TYPE, s.stamp_ns, raws)
    with pytest.raises(MissingTopicError, match="/bridge/air_temperature"):
        read_monitoring(tmp_path / "forces_only")
    got = read_monitoring(tmp_path / "forces_only", required=list(FORCE_TOPICS.values()))
    assert len(got.temperature) == 0
    np.testing.assert_array_equal(got.forces["frc_02"].force_n, data.forces["frc_02"].force_n)  # a copy


@pytest.mark.parametrize("storage", STORAGES)
def test_unexpected_type(tmp_path: Path, storage: str) -> None:
    ts = get_typestore()
    plugin = Plugin.SQLITE3 if storage == "sqlite3" else Plugin.MCAP
    with Writer(tmp_path / "wrong", version=9, storage_plugin=plugin) as w:
        conn = w.add_connection(TEMPERATURE_TOPIC, "std_msgs/msg/Float64", typestore=ts)
        w.write(
            conn,
            T0,
            bytes(ts.serialize_cdr(ts.types["std_msgs/msg/Float64"](data=1.0), "std_msgs/msg/Float64")),
        )
    with pytest.raises(UnexpectedTypeError, match="std_msgs/msg/Float64"):
        read_monitoring(tmp_path / "wrong", required=False)


def test_missing_path_and_not_a_bag(tmp_path: Path) -> None:
    with pytest.raises(BagNotFoundError, match="no such bag"):
        read_monitoring(tmp_path / "nope")
    (tmp_path / "dir").mkdir()
    with pytest.raises(NotABagError, match=r"metadata\.yaml\)$"):  # nothing there to convert
        read_monitoring(tmp_path / "dir")
    (tmp_path / "x.csv").write_text("a,b\n")
    convert = "make a bag of them with `bridge-shadow import-csv FILE... --out BAG`"
    with pytest.raises(NotABagError, match=re.escape(convert)):
        bag_summary(tmp_path / "x.csv")
    with pytest.raises(NotABagError) as info:  # a folder of CSV records: import-csv reads it as it is
        read_monitoring(tmp_path)
    assert str(info.value).endswith(f"bag of them with `bridge-shadow import-csv {tmp_path} --out BAG`")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "metadata.yaml").write_text("{: not yaml")
    with pytest.raises(CorruptBagError, match="junk"):
        read_monitoring(tmp_path / "junk")
    # YAML, but no rosbag2 metadata: said so first (it read "corrupt or truncated bag while opening:
    # Invalid bag metadata: string indices must be integers, not 'str'.")
    for text in ("junk", "rosbag2_bagfile_information: {version: 9}"):
        (tmp_path / "junk" / "metadata.yaml").write_text(text)
        with pytest.raises(CorruptBagError, match=r"junk: metadata\.yaml is not rosbag2 metadata"):
            read_monitoring(tmp_path / "junk")


@pytest.mark.parametrize("storage", STORAGES)
@pytest.mark.parametrize("keep", [0.02, 0.5, 0.95])
def test_truncated_storage_gives_one_line_error(tmp_path: Path, storage: str, keep: float) -> None:
    write_monitoring(tmp_path / "bag", _data(), storage)
    (db,) = [p for p in (tmp_path / "bag").iterdir() if p.suffix in (".db3", ".mcap")]
    content = db.read_bytes()
    db.write_bytes(content[: int(len(content) * keep)])
    for action in (read_monitoring, bag_summary, lambda p: list(iter_raw(p))):
        with pytest.raises(CorruptBagError) as info:
            action(tmp_path / "bag")
        assert str(tmp_path / "bag") in str(info.value) and "\n" not in str(info.value)


def test_missing_storage_file(tmp_path: Path) -> None:
    write_monitoring(tmp_path / "bag", _data(20), "mcap")
    next((tmp_path / "bag").glob("*.mcap")).unlink()
    with pytest.raises(CorruptBagError, match="missing"):
        read_monitoring(tmp_path / "bag")


def test_overwrite_only_replaces_bags(tmp_path: Path) -> None:
    write_monitoring(tmp_path / "bag", _data(20))
    with pytest.raises(BagExistsError, match="exists already"):
        write_monitoring(tmp_path / "bag", _data(20))
    write_monitoring(tmp_path / "bag", _data(30, seed=2), "mcap", overwrite=True)
    assert bag_summary(tmp_path / "bag")["storage"] == "mcap"
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "keep.py").write_text("x = 1\n")
    with pytest.raises(BagExistsError, match="not a bag"):
        write_monitoring(tmp_path / "src", _data(20), overwrite=True)
    assert (tmp_path / "src" / "keep.py").exists()
    with pytest.raises(BagError, match="storage"):
        write_monitoring(tmp_path / "other", _data(20), "rosbag1")
    with pytest.raises(BagError, match="mcap"):
        write_monitoring(tmp_path / "other", _data(20), "sqlite3", compress=True)


@pytest.mark.parametrize("storage", STORAGES)
def test_output_writer_messages_deserialize(tmp_path: Path, storage: str) -> None:
    cov = np.array([[4e-8, 1e-8], [1e-8, 9e-8]])
    with BagOutputWriter(tmp_path / "out", storage) as bag:
        bag.write_wrench("/bridge_shadow/compensated/frc_01", T0, T0 - 5, "frc_01", 2.6e5)
        bag.write_float64_array(MEAN_TOPIC, T0 + 1, [7e-4, -7e-4], ["support"])
        bag.write_float64_array(COVARIANCE_TOPIC, T0 + 1, cov, ["row", "col"])
        bag.write_diagnostics(
            DIAGNOSTICS_TOPIC,
            T0 + 2,
            T0 + 2,
            [
                {
                    "name": "bridge_shadow: inputs",
                    "level": 1,
                    "message": "stale",
                    "values": {"rejected_nan": 3},
                }
            ],
        )
        with pytest.raises(UnexpectedTypeError):
            bag.write_temperature(MEAN_TOPIC, T0, T0, "x", 1.0)
    ts = get_typestore()
    with Reader(tmp_path / "out") as reader:
        msgs = {c.topic: ts.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages()}
    w = msgs["/bridge_shadow/compensated/frc_01"]
    assert (w.wrench.force.z, w.header.frame_id, w.header.stamp.nanosec) == (2.6e5, "frc_01", 601_000_000 - 5)
    np.testing.assert_array_equal(msgs[MEAN_TOPIC].data, [7e-4, -7e-4])  # written, read back: a copy
    assert [d.label for d in msgs[MEAN_TOPIC].layout.dim] == ["support"]
    c = msgs[COVARIANCE_TOPIC]
    assert [(d.label, d.size, d.stride) for d in c.layout.dim] == [("row", 2, 4), ("col", 2, 2)]
    np.testing.assert_array_equal(np.asarray(c.data).reshape(2, 2), cov)  # written, read back: a copy
    (status,) = msgs[DIAGNOSTICS_TOPIC].status
    assert (status.level, status.message, status.values[0].key, status.values[0].value) == (
        1,
        "stale",
        "rejected_nan",
        "3",
    )


def test_bare_storage_file_is_readable(tmp_path: Path) -> None:
    data = _data(40)
    write_monitoring(tmp_path / "bag", data, "mcap")
    mcap = next((tmp_path / "bag").glob("*.mcap"))
    shutil.copy(mcap, tmp_path / "bare.mcap")
    _assert_same(data, read_monitoring(tmp_path / "bare.mcap"))


def test_undecodable_message_is_a_corrupt_bag(tmp_path: Path) -> None:
    good = encode_stamped_floats(np.array([T0, T0 + 1]), "frc_01", np.ones((2, 6)))
    with BagOutputWriter(tmp_path / "bag") as bag:
        bag.write_raw(FORCE_TOPICS["frc_01"], FORCE_TYPE, T0, good[0])
        bag.write_raw(FORCE_TOPICS["frc_01"], FORCE_TYPE, T0 + 1, good[1][:30])  # cut inside the floats
    with pytest.raises(CorruptBagError, match="/bridge/frc_01/force does not decode"):
        read_monitoring(tmp_path / "bag", required=False)


@pytest.mark.parametrize("compress", [False, True])
def test_mcap_index_fast_path_equals_rosbags_iteration(tmp_path: Path, compress: bool) -> None:
    from bridge_shadow.bagio.mcap_direct import read_mcap_topics
    from bridge_shadow.bagio.mcap_format import mcap_files

    data = _data(3000)
    write_monitoring(tmp_path / "bag", data, "mcap", compress=compress)
    blocks, types = read_mcap_topics(
        mcap_files(tmp_path / "bag"), set(FORCE_TOPICS.values()) | {TEMPERATURE_TOPIC}
    )
    assert types[TEMPERATURE_TOPIC] == TEMPERATURE_TYPE
    with Reader(tmp_path / "bag") as reader:
        for conn in reader.connections:
            ref = list(reader.messages(connections=[conn]))
            assert blocks[conn.topic].raws() == [raw for _, _, raw in ref]
            np.testing.assert_array_equal(blocks[conn.topic].log_ns, [t for _, t, _ in ref])  # integer ns


def test_mcap_fallback_to_rosbags_gives_the_same_data(tmp_path: Path, monkeypatch) -> None:
    import bridge_shadow.bagio.reader as reader_module
    from bridge_shadow.bagio.mcap_format import McapLayoutError

    data = _data(300)
    write_monitoring(tmp_path / "bag", data, "mcap")

    def refuse(*_args: object) -> None:
        raise McapLayoutError("layout not handled")

    monkeypatch.setattr(reader_module, "read_mcap_topics", refuse)
    _assert_same(data, read_monitoring(tmp_path / "bag"))


def test_decode_buffer_gathers_scattered_messages() -> None:
    raws = encode_stamped_floats(
        np.array([5, 6, 7]), ["a", "bbbbbbbbbbbb", "a"], np.arange(18.0).reshape(3, 6)
    )
    junk = b"\xff" * 5
    buf = np.frombuffer(junk + raws[2] + junk + raws[0] + raws[1], dtype=np.uint8)
    starts = np.array([5 + len(raws[2]) + 5, 5 + len(raws[2]) + 5 + len(raws[0]), 5])
    lengths = np.array([len(r) for r in raws])
    stamp, frames, values = decode_buffer(buf, starts, lengths, 6)
    np.testing.assert_array_equal(stamp, [5, 6, 7])  # exact: decoded bytes, no arithmetic
    assert list(frames) == ["a", "bbbbbbbbbbbb", "a"]
    np.testing.assert_array_equal(values, np.arange(18.0).reshape(3, 6))  # float64s copied


def test_a_uniform_frame_id_view_is_read_only_and_shared() -> None:
    """``uniform_frames`` (kept for the last few asked) is a read-only view: sharing it is safe."""
    from bridge_shadow.bagio.cdr import concat_frames, frame_value, uniform_frames

    a = uniform_frames("frc_01", 25)
    assert a is uniform_frames("frc_01", 25) and a.shape == (25,) and frame_value(a) == "frc_01"
    assert list(a) == ["frc_01"] * 25 and list(uniform_frames("frc_01", 3)) == ["frc_01"] * 3
    with pytest.raises(ValueError, match="read-only"):
        a[0] = "frc_02"
    joined = concat_frames([a, uniform_frames("frc_01", 5)])
    assert frame_value(joined) == "frc_01" and len(joined) == 30
