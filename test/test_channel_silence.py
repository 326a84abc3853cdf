"""A force channel that falls silent (or out of range) while the other delivers is said out loud.

Found with the 2022-04-11 records: the 10 mm record copied 1.25 h on, the south bearing raised
10 mm and the north one lowered 10 mm more through the calibrated ``A``, reads below zero on the
north cell (a bearing that would lift off). Every north message of that record was rejected as
out of range, its 13 windows as ``missing_topic``, and the replay ended at the reference state
with a +-3.7 mm interval 20 mm from the truth: no warning, no event, exit 0 (the ledger spoke only
when *every* message of a topic was rejected).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.inputs.silence import MIN_SILENT_WINDOWS, ChannelSilence
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.ros.diagnostics import statuses
from bridge_shadow.timefmt import iso_utc
from bridge_shadow.twin.real_records import Piece, build

W = 60 * 10**9


def _follow(samples: list[tuple[int, int, int]]) -> ChannelSilence:
    s = ChannelSilence()
    for k, a, b in samples:
        s.note(k, np.array([a, b]))
    return s


def test_one_window_at_a_records_edge_is_no_stretch_two_in_a_row_are() -> None:
    edge = _follow([(0, 100, 0), (1, 100, 100), (2, 100, 100), (3, 0, 100), (4, 100, 100)])
    assert edge.stretches(0) == [] and edge.stretches(1) == []
    two = _follow([(0, 100, 100), (1, 100, 0), (2, 100, 0), (3, 100, 100), (4, 100, 0)])
    assert two.stretches(1) == [(1, 2)] and two.stretches(0) == []
    assert MIN_SILENT_WINDOWS == 2


def test_a_stretch_ends_where_the_channel_returns_or_the_windows_stop() -> None:
    # windows 5..6 then, after a gap (no window held data), 20..22: two stretches, not one
    s = _follow([(5, 50, 0), (6, 50, 0), (20, 50, 0), (21, 50, 0), (22, 50, 0), (23, 50, 50)])
    assert s.stretches(1) == [(5, 6), (20, 22)]
    # both channels empty is no window of data; one empty with the other empty too is not "alone"
    both = _follow([(0, 0, 0), (1, 0, 0), (2, 0, 0)])
    assert both.stretches(0) == [] and both.stretches(1) == []


def test_the_state_round_trips_inside_a_stretch() -> None:
    steps = [(0, 9, 9), (1, 9, 0), (2, 9, 0), (3, 9, 0), (4, 9, 9), (5, 0, 9), (6, 0, 9)]
    whole = _follow(steps)
    half = _follow(steps[:2])
    again = ChannelSilence()
    again.load_state_dict(half.state_dict())
    for k, a, b in steps[2:]:
        again.note(k, np.array([a, b]))
    assert again.stretches(0) == whole.stretches(0) == [(5, 6)]
    assert again.stretches(1) == whole.stretches(1) == [(1, 3)]


@pytest.mark.realdata
def test_a_north_cell_below_zero_for_a_whole_record_is_warned_and_the_state_marked_unknown(
    munich_data: Path,
) -> None:
    sur = load_surrogate()
    pieces = [Piece("ref", 0.0), Piece("lowered", 1.25, (0.01, -0.01))]
    sc = build(munich_data / "Settlements", sur.A, pieces)
    later = sc.data.forces["frc_02"]
    in_later = later.stamp_ns >= sc.starts_ns[1]
    assert np.all(later.force_n[in_later] <= 0.0)  # the premise: the north cell reads below zero

    shadow = Shadow(load_config(), sur)
    res = shadow.run(sc.data)
    n_later = int(np.ceil((sc.data.time_span_ns()[1] - sc.starts_ns[1]) / W))
    assert res.rejected["missing_topic"] >= n_later - 1
    lines = [w for w in res.warnings if w.startswith("topic frc_02: nothing usable")]
    assert len(lines) == 1, res.warnings
    line = lines[0]
    assert "out_of_range" in line and "lifted off" in line
    assert "rejected over the whole run" in line  # the ledger's counts are the run's, not the stretch's
    n_said = int(line.split("nothing usable in ")[1].split()[0])
    assert n_later - 1 <= n_said <= n_later
    assert not any(w.startswith("topic frc_01: nothing usable") for w in res.warnings)

    state = shadow.diagnostics()["state"]
    assert "frc_02 delivered nothing usable" in state["text"]
    assert state["unseen_from"] == iso_utc(sc.starts_ns[1] // W * W)
    ages = {"frc_01": 0.1, "frc_02": 0.1, "air_temperature": 0.1}
    est, inputs, *_ = statuses(shadow.diagnostics(), ages)
    assert est.level == 1 and inputs.level == 1  # WARN on /diagnostics, naming the topic
    assert "topic frc_02" in inputs.message


@pytest.mark.realdata
def test_the_reference_and_lowered_records_raise_no_silence(munich_data: Path) -> None:
    """Both real records and a record hours later: both channels deliver in every window."""
    sur = load_surrogate()
    pieces = [Piece("ref", 0.0), Piece("lowered", 0.73), Piece("lowered", 4.0, (-0.01, -0.01), 6.5)]
    sc = build(munich_data / "Settlements", sur.A, pieces)
    shadow = Shadow(load_config(), sur)
    res = shadow.run(sc.data)
    assert shadow.silence.stretches(0) == [] and shadow.silence.stretches(1) == []
    assert not any("nothing usable" in w for w in res.warnings)
    assert "unseen_from" not in shadow.diagnostics()["state"]
