"""Faults of the load cells said out loud: every message rejected to the end, one cell's jump.

Found with the 2022-04-11 records (a helper session's data-quality streams): the 10 mm record
with both load cells delivering NaN throughout, or one value held, ended at the reference state,
0 ± 3.7 mm against the -10 mm it held, with no event and no warning. No window of it closed, so
neither the rejected windows nor a silent channel (whose partner delivered) showed it. And a jump
of one cell's offset read as a confirmed settlement with nothing to say that one cell moved alone.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from archive_fixtures import seamed_record, write_archive

from bridge_shadow.archive.join import join_bags
from bridge_shadow.archive.reduce import reduce_bag
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.inputs.ledger import TopicLedger
from bridge_shadow.model.surrogate_file import load_surrogate, placeholder_surrogate
from bridge_shadow.replay import replay_bag
from bridge_shadow.series import ForceSeries, MonitoringData
from bridge_shadow.timefmt import iso_utc

DEAD = "no usable load-cell message after"


def _dead_from(
    data: MonitoringData, from_ns: int, value: float | None = None, to_ns: int | None = None
) -> MonitoringData:
    """Both load cells' values over ``[from_ns, to_ns)`` NaN (or ``value`` held), stamps as they were."""
    forces = {}
    for ch, s in data.forces.items():
        f = s.force_n.copy()
        dead = (s.stamp_ns >= from_ns) & (
            s.stamp_ns < (to_ns if to_ns is not None else np.iinfo(np.int64).max)
        )
        f[dead] = np.nan if value is None else value
        forces[ch] = ForceSeries(s.stamp_ns, f, s.frame_id, log_ns=s.log_ns)
    return MonitoringData(forces, data.temperature)


@pytest.mark.realdata
@pytest.mark.parametrize("held", [False, True])
def test_a_record_whose_every_message_is_rejected_is_said_with_its_times(
    munich_data: Path, held: bool
) -> None:
    """The lowered record with both cells NaN (or each holding one value) throughout: said.

    A WARN line says from when the load cells gave nothing usable and that the state since is
    unknown; with a good record after it, the line goes and the lowering is found.
    """
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    sc = build(munich_data / "Settlements", sur.A, [Piece("ref", 0.0), Piece("lowered", 0.733)])
    start = sc.starts_ns[1]
    good = Shadow(load_config(), sur)
    good.run(sc.data)
    assert not [w for w in good.warnings() if DEAD in w]  # the record as it was: one event, no line
    assert len(good.event_records()) == 1
    shadow = Shadow(load_config(), sur)
    shadow.run(_dead_from(sc.data, start, 250e3 if held else None))
    (line,) = [w for w in shadow.warnings() if DEAD in w]
    assert "the settlement since is unknown" in line
    assert ("frozen" if held else "nonfinite") in line
    # the last usable message: the reference record's end (NaN), or the held value's first seconds
    last_ok = max(led.last_ok_ns for led in shadow.ledgers[:2])
    ref_end = int(max(s.stamp_ns[s.stamp_ns < start].max() for s in sc.data.forces.values()))
    assert (last_ok - start) < 60e9 if held else last_ok == ref_end
    assert iso_utc(last_ok) in line
    # a good record after it: the line goes, the lowering is found there
    pieces = [Piece("ref", 0.0), Piece("lowered", 0.733), Piece("lowered", 1.5)]
    more = build(munich_data / "Settlements", sur.A, pieces)
    shadow = Shadow(load_config(), sur)
    shadow.run(_dead_from(more.data, start, None, more.starts_ns[2]))
    assert not [w for w in shadow.warnings() if DEAD in w]
    np.testing.assert_allclose(shadow.posterior[0], [-0.01, -0.01], atol=1.5e-3)


def test_the_ledger_keeps_the_rejected_tail_through_its_state() -> None:
    """Accepted messages end the tail; rejected ones grow it; the state carries it (checkpoints)."""
    led = TopicLedger("frc_01", "frc_01", (1.0, 5e6, "N"))
    stamps = np.arange(10, dtype=np.int64) * 10**9
    led.note(np.ones(10, bool), np.ones(10), None, {}, {}, stamps)
    assert led.last_ok_ns == 9 * 10**9 and led.tail_n == 0
    ok = np.array([True, True, False, False])
    led.note(ok, np.ones(4), None, {}, {}, stamps[:4] + 10 * 10**9)
    assert (led.last_ok_ns, led.tail_n, led.tail_first_ns, led.tail_last_ns) == (
        11 * 10**9,
        2,
        12 * 10**9,
        13 * 10**9,
    )  # integer ns
    led.note(np.zeros(3, bool), np.ones(3), None, {}, {}, stamps[:3] + 20 * 10**9)
    assert (led.tail_n, led.tail_first_ns, led.tail_last_ns) == (5, 12 * 10**9, 22 * 10**9)
    assert led.dead_tail(10 * 10**9) == (5, 12 * 10**9, 22 * 10**9)
    assert led.dead_tail(11 * 10**9) is None
    again = TopicLedger("frc_01", "frc_01", (1.0, 5e6, "N"))
    again.load_state_dict(led.state_dict())
    assert again.dead_tail(10 * 10**9) == led.dead_tail(10 * 10**9)
    led.note(np.array([False, True]), np.ones(2), None, {}, {}, stamps[:2] + 30 * 10**9)
    assert led.tail_n == 0 and led.dead_tail(0) is None


def test_a_resumed_ledger_says_when_its_old_stamps_are_the_checkpoints_own() -> None:
    """Old stamps at or before the checkpoint's last taken one are named as such; any later, generic.

    A checkpoint chain of bags that each hold the day's air rejects the later bag's copy of what
    the first run took (``out_of_order``): the line says so. Old stamps after that point (a clock
    set back within this run) keep the line of every cause.
    """
    s = 10**9
    first = TopicLedger("air_temperature", None, (-60.0, 80.0, "C"))
    first.note(np.ones(10, bool), np.ones(10), None, {}, {}, np.arange(10, dtype=np.int64) * s)
    assert first.old_stamps_message() is None and first.resumed_ok_ns == -1

    def resumed(stamps: np.ndarray) -> TopicLedger:
        led = TopicLedger("air_temperature", None, (-60.0, 80.0, "C"))
        led.load_state_dict(first.state_dict())
        led.note(np.ones(20, bool), np.ones(20), None, {}, {}, np.arange(10, 30, dtype=np.int64) * s)
        ok = np.zeros(len(stamps), bool)
        led.note(ok, np.ones(len(stamps)), None, {}, {"out_of_order": len(stamps)}, stamps)
        return led

    copy = resumed(np.arange(5, dtype=np.int64) * s)  # the first run's readings again
    line = copy.old_stamps_message()
    assert line is not None and copy.rejected_before_resume == 5
    assert "5 of them stamped at or before the last one the checkpoint's run took" in line
    assert iso_utc(9 * s, "seconds") in line and "bags that overlap in time" not in line
    later = resumed(np.array([5, 6, 7, 15, 16], dtype=np.int64) * s)  # two after the checkpoint's last
    line = later.old_stamps_message()
    assert line is not None and later.rejected_before_resume == 3
    assert "checkpoint's run took" not in line and "bags that overlap in time" in line
    fresh = TopicLedger("air_temperature", None, (-60.0, 80.0, "C"))  # no checkpoint: generic
    fresh.note(np.ones(20, bool), np.ones(20), None, {}, {}, np.arange(10, 30, dtype=np.int64) * s)
    fresh.note(np.zeros(5, bool), np.ones(5), None, {}, {"out_of_order": 5}, np.arange(5, dtype=np.int64) * s)
    assert "bags that overlap in time" in (fresh.old_stamps_message() or "")


def test_an_archive_says_it_as_the_serial_replay_does(tmp_path: Path) -> None:
    """Both cells dead from inside a bag to the end: the joined reductions say what the replay says.

    The serial replay's warnings, the dead-input line among them, line for line.
    """
    data, seams = seamed_record(days=1.6)
    t0 = int(data.forces["frc_01"].stamp_ns[0])
    data = _dead_from(data, t0 + int(0.5 * 86400e9))  # inside bag 1, reduced: its tail carried
    bags, whole = write_archive(tmp_path, data, seams)
    config, surrogate = load_config(), placeholder_surrogate()
    ref, _ = replay_bag(whole, Shadow(config, surrogate))
    ref_json = ref.to_json()
    assert [w for w in ref_json["warnings"] if DEAD in w]
    shadow = Shadow(config, surrogate)
    stats = join_bags(shadow, [reduce_bag(b, config, surrogate) for b in bags])
    got = shadow.result([], stats.messages, 1.0).to_json()
    assert got["warnings"] == ref_json["warnings"]


@pytest.mark.realdata
def test_an_event_on_one_load_cell_alone_names_a_sensor_fault(munich_data: Path) -> None:
    """An unchanged record hours on with the north cell 50 kN higher (an offset, no settlement).

    The shadow reads it as an event (the forces cannot tell), and says that one cell moved alone
    and a fault of that cell fits it; the real 10 mm lowering, which moves both, gets no such line.
    """
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    folder = munich_data / "Settlements"
    pair = build(folder, sur.A, [Piece("ref", 0.0), Piece("lowered", 0.733)])
    shadow = Shadow(load_config(), sur)
    shadow.run(pair.data)
    assert len(shadow.event_records()) == 1
    assert not [w for w in shadow.warnings() if "one load cell's reaction alone" in w]
    sc = build(folder, sur.A, [Piece("ref", 0.0), Piece("ref", 1.25)])
    north = sc.data.forces["frc_02"]
    shifted = ForceSeries(
        north.stamp_ns,
        north.force_n + np.where(north.stamp_ns >= sc.starts_ns[1], 50e3, 0.0),
        north.frame_id,
        log_ns=north.log_ns,
    )
    shadow = Shadow(load_config(), sur)
    shadow.run(MonitoringData({"frc_01": sc.data.forces["frc_01"], "frc_02": shifted}, sc.data.temperature))
    assert len(shadow.event_records()) == 1
    (line,) = [w for w in shadow.warnings() if "one load cell's reaction alone" in w]
    moved = re.search(r"frc_02 ([-+0-9.]+) kN, frc_01 ([-+0-9.]+) ±", line)
    assert moved is not None and "sensor fault" in line
    assert float(moved.group(1)) == pytest.approx(50.0, abs=2.0)  # the offset, read back
    assert abs(float(moved.group(2))) < 0.05 * 50.0


@pytest.mark.realdata
def test_a_cell_that_delivers_mostly_nan_is_said(munich_data: Path) -> None:
    """The south cell NaN for 59 s of every minute: the share rejected for its values is said."""
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    sc = build(munich_data / "Settlements", sur.A, [Piece("ref", 0.0), Piece("lowered", 0.733)])
    south = sc.data.forces["frc_01"]
    second = ((south.stamp_ns - south.stamp_ns[0]) // 10**9) % 60
    bad = ForceSeries(south.stamp_ns, np.where(second > 0, np.nan, south.force_n), south.frame_id)
    lines = {}
    for name, data in (
        ("clean", sc.data),
        ("nan", MonitoringData({**sc.data.forces, "frc_01": bad}, sc.data.temperature)),
    ):
        shadow = Shadow(load_config(), sur)
        shadow.run(data)
        lines[name] = [w for w in shadow.warnings() if "rejected for their values" in w]
    assert not lines["clean"]
    (line,) = lines["nan"]
    n = int(np.count_nonzero(second > 0))
    assert line.startswith(f"topic frc_01: {n} of {len(south)} messages (98 %)") and f"nonfinite {n}" in line


@pytest.mark.realdata
def test_a_cell_stuck_at_its_old_value_reads_no_change_from_its_first_seconds(munich_data: Path) -> None:
    """The north cell holding its reference value through the lowered record (a logger's hold).

    The gate takes a run's first 10 s before it can tell a held value from a load; those samples
    made the record's first window, north at the old value beside south's new one, and the gap's
    change read -3.8 / -2.6 mm at probability 1 against -10 mm. Once the run is found frozen its
    head is taken back: the north cell is silent for the whole record and said so, and no change
    is read from it.
    """
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    sc = build(munich_data / "Settlements", sur.A, [Piece("ref", 0.0), Piece("lowered", 0.733)])
    start = sc.starts_ns[1]
    north = sc.data.forces["frc_02"]
    late = north.stamp_ns >= start
    held = float(north.force_n[~late][-1]) + 0.5  # the old value, its run beginning with the record
    stuck = ForceSeries(
        north.stamp_ns, np.where(late, held, north.force_n), north.frame_id, log_ns=north.log_ns
    )
    shadow = Shadow(load_config(), sur)
    shadow.run(MonitoringData({"frc_01": sc.data.forces["frc_01"], "frc_02": stuck}, sc.data.temperature))
    assert shadow.rejected["frozen"] == int(np.count_nonzero(late))  # the head too
    assert not shadow.event_records()
    for change in shadow.unconfirmed_changes():
        assert not (change.windows and change.change_probability > 0.5), change
    assert [w for w in shadow.warnings() if w.startswith("topic frc_02: nothing usable in 13 windows")]


@pytest.mark.realdata
def test_an_air_temperature_in_fahrenheit_is_said(munich_data: Path) -> None:
    """A later record whose logger wrote °F: the jump no air makes is said; in °C nothing is."""
    from bridge_shadow.series import TemperatureSeries
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    pieces = [Piece("ref", 0.0), Piece("lowered", 0.733), Piece("lowered", 4.0, (-0.005, -0.005), 6.5)]
    sc = build(munich_data / "Settlements", sur.A, pieces)
    t = sc.data.temperature
    later = t.stamp_ns >= sc.starts_ns[2] - 600 * 10**9
    fahrenheit = TemperatureSeries(
        t.stamp_ns, np.where(later, 32.0 + 1.8 * t.temp_c, t.temp_c), t.variance, t.frame_id
    )
    lines = {}
    for name, temp in (("celsius", t), ("fahrenheit", fahrenheit)):
        shadow = Shadow(load_config(), sur)
        shadow.run(MonitoringData(sc.data.forces, temp))
        lines[name] = [w for w in shadow.warnings() if w.startswith("air temperature jumped")]
    assert not lines["celsius"]
    (line,) = lines["fahrenheit"]
    jump = float(re.search(r"jumped by \+([0-9.]+) K", line).group(1))
    assert 30.0 < jump < 60.0 and "(°F?)" in line


@pytest.mark.realdata
def test_a_south_cell_jump_inside_a_record_names_a_sensor_fault_too(munich_data: Path) -> None:
    """-20 kN on the south cell from minute 6 of the lowered record: a warm-up event, said as one cell's.

    The event is confirmed against the model's and the sun's uncertainty; a second cut at 3 sd of
    the reaction change missed it (2.8 sd) while the north cell's were said.
    """
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    sc = build(munich_data / "Settlements", sur.A, [Piece("ref", 0.0), Piece("lowered", 0.733)])
    south = sc.data.forces["frc_01"]
    jump = np.where(south.stamp_ns >= sc.starts_ns[1] + 6 * 60 * 10**9, -20e3, 0.0)
    shifted = ForceSeries(south.stamp_ns, south.force_n + jump, south.frame_id, log_ns=south.log_ns)
    shadow = Shadow(load_config(), sur)
    shadow.run(MonitoringData({"frc_01": shifted, "frc_02": sc.data.forces["frc_02"]}, sc.data.temperature))
    assert len(shadow.event_records()) == 2  # the lowering, and the jump read as a settlement
    (line,) = [w for w in shadow.warnings() if "one load cell's reaction alone" in w]
    moved = re.search(r"frc_01 ([-+0-9.]+) kN", line)
    assert moved is not None and float(moved.group(1)) == pytest.approx(-20.0, abs=3.0)
