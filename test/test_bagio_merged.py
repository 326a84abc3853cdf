"""Bags that overlap in time read as one: ``bagio.merged.MergedStream`` equals the bag holding everything.

A twin record (forces at 1 Hz, air temperature once a minute) is written whole and split two
ways: by topic (forces in one bag, air in another, as a load-test day's records and its air
temperature came) and at random log times into three bags whose spans overlap (each message in
one of them). Read merged, in pieces of a few thousand messages, the bags give the whole bag's
messages in the same order: log and header stamps and frame ids exactly, values to rtol 1e-12
(they are copied, never computed), the same feed chunks, and ``required`` over their union.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bridge_shadow.bagio import MissingTopicError, write_monitoring
from bridge_shadow.bagio.merged import MergedStream, open_monitoring
from bridge_shadow.bagio.stream import MonitoringStream
from bridge_shadow.contract import CHANNELS
from bridge_shadow.replay.chunks import arrival_chunks
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

BATCH = 3_000


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The twin record, its whole bag, and the same messages split by topic and at random times."""
    from bridge_shadow.model.surrogate_file import placeholder_surrogate
    from bridge_shadow.twin.simulate import simulate

    folder = tmp_path_factory.mktemp("merged")
    data, _ = simulate(days=0.25, rate_hz=1.0, seed=3, surrogate=placeholder_surrogate())
    whole = write_monitoring(folder / "whole", data)
    none = _pick(data, lambda log: np.zeros(len(log), bool))
    by_topic = [
        write_monitoring(folder / "forces", MonitoringData(data.forces, none.temperature)),
        write_monitoring(folder / "air", MonitoringData(none.forces, data.temperature), "mcap"),
    ]
    # three bags cut at random log times, each message in the part of its time or a neighbour's,
    # so the bags' spans overlap by hours and every bag holds each topic
    rng = np.random.default_rng(7)
    t0 = int(data.forces["frc_01"].log_ns[0])
    t1 = int(data.forces["frc_01"].log_ns[-1])
    cuts = np.sort(rng.integers(t0, t1, 2))

    def part_of(log: np.ndarray) -> np.ndarray:
        region = np.searchsorted(cuts, log)
        return np.clip(region + rng.integers(-1, 2, len(log)), 0, 2)

    parts = {ch: part_of(s.log_ns) for ch, s in data.forces.items()}
    parts["air"] = part_of(data.temperature.log_ns)
    random = []
    for k, storage in enumerate(("sqlite3", "mcap", "sqlite3")):
        sel = {key: p == k for key, p in parts.items()}
        random.append(write_monitoring(folder / f"part_{k}", _pick_each(data, sel), storage))
    spans = []
    for bag in random:
        with MonitoringStream(bag) as stream:
            spans.append((stream.first_ns, stream.last_ns))
    assert spans[1][0] < spans[0][1] and spans[2][0] < spans[1][1]  # they overlap in time
    return {"data": data, "whole": whole, "by_topic": by_topic, "random": random}


def _pick(data: MonitoringData, keep: Any) -> MonitoringData:
    return _pick_each(
        data, {**{ch: keep(s.log_ns) for ch, s in data.forces.items()}, "air": keep(data.temperature.log_ns)}
    )


def _pick_each(data: MonitoringData, sel: dict[str, np.ndarray]) -> MonitoringData:
    forces = {
        ch: ForceSeries(s.stamp_ns[sel[ch]], s.force_n[sel[ch]], s.frame_id[sel[ch]], s.log_ns[sel[ch]])
        for ch, s in data.forces.items()
    }
    t, m = data.temperature, sel["air"]
    return MonitoringData(
        forces, TemperatureSeries(t.stamp_ns[m], t.temp_c[m], t.variance[m], t.frame_id[m], t.log_ns[m])
    )


def _topics(pieces: list[MonitoringData]) -> list[dict[str, np.ndarray]]:
    """Per topic, the pieces' columns concatenated."""
    out = []
    for ch in CHANNELS:
        s = [p.forces[ch] for p in pieces]
        out.append(
            {
                k: np.concatenate([getattr(x, k) for x in s])
                for k in ("log_ns", "stamp_ns", "force_n", "frame_id")
            }
        )
    t = [p.temperature for p in pieces]
    out.append(
        {
            k: np.concatenate([getattr(x, k) for x in t])
            for k in ("log_ns", "stamp_ns", "temp_c", "variance", "frame_id")
        }
    )
    return out


def assert_same_messages(got: list[MonitoringData], ref: list[MonitoringData]) -> None:
    """Per topic the same messages in the same order; pieces each wholly before the next."""
    for g, r in zip(_topics(got), _topics(ref), strict=True):
        assert len(g["log_ns"]) == len(r["log_ns"]) > 0
        for key, a in r.items():
            if a.dtype.kind in "iO":
                np.testing.assert_array_equal(g[key], a, err_msg=key)
            else:
                np.testing.assert_allclose(g[key], a, rtol=1e-12, atol=0, err_msg=key)
    spans = []
    for p in got:
        logs = np.concatenate([p.forces[ch].log_ns for ch in CHANNELS] + [p.temperature.log_ns])
        assert len(logs)
        spans.append((logs.min(), logs.max()))
    assert all(a[1] <= b[0] for a, b in itertools.pairwise(spans))  # arrival order across pieces


@pytest.mark.parametrize("split", ["by_topic", "random"])
def test_merged_bags_read_as_the_bag_holding_everything(record: dict[str, Any], split: str) -> None:
    """Bags split by topic or at random overlapping times, in either order: the whole bag's messages."""
    bags = record[split]
    with MonitoringStream(record["whole"], batch=BATCH) as whole:
        ref = list(whole)
        first, last = whole.first_ns, whole.last_ns
    for order in (bags, bags[::-1]):
        with MergedStream(order, batch=BATCH) as merged:
            assert (merged.first_ns, merged.last_ns) == (first, last)
            assert set(merged.backend.split("+")) == {"sqlite3", "mcap"}
            got = list(merged)
            # bounded memory: about a piece per bag, never the record
            assert merged.peak_pending < 3 * len(bags) * BATCH < record["data"].n_messages
        assert len(got) > 3
        assert_same_messages(got, ref)
    # fed in chunks as replay feeds: the same calls as the whole bag's
    with MergedStream(bags, batch=BATCH) as merged, MonitoringStream(record["whole"], batch=BATCH) as whole:
        for a, b in zip(arrival_chunks(merged, 5_000), arrival_chunks(whole, 5_000), strict=True):
            assert a.messages == b.messages and a.last_log_ns == b.last_log_ns
            for x, y in zip([*a.forces, a.temperature], [*b.forces, b.temperature], strict=True):
                np.testing.assert_array_equal(x[0], y[0])  # integer stamps (ns)
                np.testing.assert_allclose(x[1], y[1], rtol=1e-12, atol=0)
                np.testing.assert_array_equal(x[2], y[2])  # frame ids (strings)


def _one_kind(path: Path, data: MonitoringData, forces: bool) -> Path:
    """Write only the forces or only the air temperature (no connection for the other topics)."""
    from bridge_shadow.bagio import BagOutputWriter, encode_stamped_floats
    from bridge_shadow.contract import FORCE_TOPICS, FORCE_TYPE, TEMPERATURE_TOPIC, TEMPERATURE_TYPE

    with BagOutputWriter(path) as bag:
        if forces:
            for ch in CHANNELS:
                s = data.forces[ch]
                values = np.column_stack([np.zeros((len(s), 2)), s.force_n, np.zeros((len(s), 3))])
                bag.write_many_raw(
                    FORCE_TOPICS[ch], FORCE_TYPE, s.log_ns, encode_stamped_floats(s.stamp_ns, ch, values)
                )
        else:
            t = data.temperature
            raws = encode_stamped_floats(t.stamp_ns, "air", np.column_stack([t.temp_c, t.variance]))
            bag.write_many_raw(TEMPERATURE_TOPIC, TEMPERATURE_TYPE, t.log_ns, raws)
    return path


def test_required_topics_hold_over_the_union_of_the_bags(record: dict[str, Any], tmp_path: Path) -> None:
    """Forces in one bag, air in the other: all three required topics are there, in neither alone."""
    data = record["data"]
    forces = _one_kind(tmp_path / "forces", data, forces=True)
    air = _one_kind(tmp_path / "air", data, forces=False)
    with pytest.raises(MissingTopicError, match="air_temperature"):
        MonitoringStream(forces, required=True)
    with pytest.raises(MissingTopicError, match="frc_01"):
        MonitoringStream(air, required=True)
    with MergedStream([forces, air], required=True) as merged:
        assert len(merged.present) == 3
        assert _topics(list(merged))[2]["log_ns"].size == len(data.temperature)
    with pytest.raises(MissingTopicError, match="air_temperature"):
        MergedStream([forces, forces], required=True)
    with open_monitoring([forces, air], required=True) as stream:
        assert isinstance(stream, MergedStream)
    with open_monitoring([forces], required=False) as stream:
        assert isinstance(stream, MonitoringStream)


def test_a_sqlite3_bag_of_none_of_the_topics_adds_nothing(record: dict[str, Any], tmp_path: Path) -> None:
    """A bag of other topics among several (``--params`` with ``topic_*`` renamed): nothing of it is read.

    An MCAP bag gave nothing; a sqlite3 one failed on its first slice ("corrupt or truncated bag while
    reading messages: 'NoneType' object is not subscriptable": the slice query held no aggregate and
    found no row), the direct replay and the live one alike.
    """
    from bridge_shadow.contract import TEMPERATURE_TOPIC

    data = record["data"]
    forces = _one_kind(tmp_path / "forces", data, forces=True)  # sqlite3, the contract's force topics
    air = _one_kind(tmp_path / "air", data, forces=False)
    names = ["/site/south_bearing/force", "/site/north_bearing/force", TEMPERATURE_TOPIC]
    with MonitoringStream(forces, topics=names, required=False) as none:
        assert none.backend == "sqlite3" and not none.present and list(none) == []
    with MergedStream([forces, air], topics=names, required=False) as merged:
        got = _topics(list(merged))
    assert got[0]["log_ns"].size == got[1]["log_ns"].size == 0
    np.testing.assert_array_equal(got[2]["log_ns"], data.temperature.log_ns)  # integer ns


def test_equal_log_times_keep_the_bags_order(tmp_path: Path) -> None:
    """Two bags with messages of one topic at the same log times: ties in the order the bags are given."""
    n = 50
    log = np.arange(n, dtype=np.int64) * 10**9 + 1_700_000_000 * 10**9
    bags = []
    for k in range(2):
        f = ForceSeries(log + k, np.full(n, float(k)), np.array(["frc"] * n, dtype=object), log)
        t = TemperatureSeries(
            np.empty(0, np.int64), np.empty(0), np.empty(0), np.empty(0, dtype=object), np.empty(0, np.int64)
        )
        bags.append(write_monitoring(tmp_path / f"b{k}", MonitoringData({ch: f for ch in CHANNELS}, t)))
    for order in (bags, bags[::-1]):
        with MergedStream(order, required=False, batch=7) as merged:
            got = _topics(list(merged))[0]
        np.testing.assert_array_equal(got["log_ns"], np.repeat(log, 2))  # integer ns
        first = 0.0 if order is bags else 1.0
        # 0.0 and 1.0 written and read back (copies through CDR, no arithmetic): which bag came first
        np.testing.assert_array_equal(got["force_n"], np.tile([first, 1.0 - first], n))


def test_replay_of_several_bags_reads_them_merged(
    record: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    """``bridge-shadow replay FORCES AIR``: the result of ``replay`` of the one bag, nothing late.

    One BAG is read as ever; several were refused by the argument parser (one BAG only), and fed
    one after the other would have lost the later bag's messages before the earlier one's end.
    Played live too (next test).
    """
    import json

    from bridge_shadow.cli import main

    runs = []
    for bags in ([record["whole"]], record["by_topic"][::-1], record["random"]):
        assert main(["replay", *map(str, bags), "--json"]) == 0
        runs.append(json.loads(capsys.readouterr().out))
    ref = runs[0]
    assert "bags" not in ref and ref["rejected"]["late"] == 0 and ref["windows"]["updates"] > 300
    for js in runs[1:]:
        assert len(js["bags"]) > 1 and js["bag"] == js["bags"][0]
        np.testing.assert_allclose(js["posterior"]["mean_m"], ref["posterior"]["mean_m"], rtol=1e-10, atol=0)
        np.testing.assert_allclose(
            js["posterior"]["covariance_m2"], ref["posterior"]["covariance_m2"], rtol=1e-10, atol=0
        )
        assert js["rejected"] == ref["rejected"] and js["windows"] == ref["windows"]
        assert js["messages"]["total"] == ref["messages"]["total"]


@pytest.mark.ros
def test_several_bags_played_live_are_the_direct_merged_replay(
    record: dict[str, Any], capfd: pytest.CaptureFixture[str]
) -> None:
    """``replay BAG BAG ... --live``: the node fed the bags merged by log time, the direct replay's answer.

    Refused before (``--live plays one BAG``): a day's records in bags of their own, overlapping in
    time, could reach the node only merged into one bag first or one by one through a checkpoint.
    The three bags cut at random times, each holding every topic, spans overlapping by hours.
    """
    import json

    from bridge_shadow.cli import main

    bags = list(map(str, record["random"]))
    assert main(["replay", *bags, "--json"]) == 0
    ref = json.loads(capfd.readouterr().out)
    assert main(["replay", *bags, "--live", "--json"]) == 0  # fd-level capture: the player needs a stderr
    live = json.loads(capfd.readouterr().out)
    assert live["bags"] == ref["bags"] == bags and live["bag"] == bags[0]
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(live["posterior"][key], ref["posterior"][key], rtol=1e-12, atol=0)
    assert live["windows"] == ref["windows"] and live["rejected"] == ref["rejected"]
    assert live["messages"]["total"] == ref["messages"]["total"] and ref["windows"]["updates"] > 300


def test_a_bag_is_read_only_once_the_merge_reaches_its_start(record: dict[str, Any], tmp_path: Path) -> None:
    """Memory holds about a piece per bag in progress, not a piece of every bag.

    The day's forces as eight bags one after the other and its air as one bag across them all:
    the merge read the first piece of every bag before it handed anything on (a day's air and
    forty 12-minute records: 469 MB against 165 MB for one bag); a bag is read now only once the
    merge has reached its first message. The messages are the whole bag's, in its order.
    """
    data = record["data"]
    t0 = int(data.forces["frc_01"].log_ns[0])
    t1 = int(data.forces["frc_01"].log_ns[-1]) + 1
    edges = [t0 + (t1 - t0) * k // 8 for k in range(9)]  # integers: float stamps lose 256 ns
    none = {"air": np.zeros(len(data.temperature.log_ns), bool)}
    bags = [
        write_monitoring(
            tmp_path / "air", MonitoringData(_pick(data, lambda log: log < 0).forces, data.temperature)
        )
    ]
    for k in range(8):
        sel = {ch: (s.log_ns >= edges[k]) & (s.log_ns < edges[k + 1]) for ch, s in data.forces.items()}
        bags.append(write_monitoring(tmp_path / f"forces_{k}", _pick_each(data, {**sel, **none})))
    batch = 500
    with MergedStream(bags, batch=batch) as merged:
        pieces = list(merged)
        peak = merged.peak_pending
    assert peak <= 3 * batch  # the air's piece and the forces bag in progress, not nine pieces
    got = np.concatenate([p.forces["frc_01"].log_ns for p in pieces])
    np.testing.assert_array_equal(got, data.forces["frc_01"].log_ns)  # integer ns
    air = np.concatenate([p.temperature.log_ns for p in pieces])
    np.testing.assert_array_equal(air, data.temperature.log_ns)  # integer ns
