"""The last windows read a state the estimate does not hold: said, never silent (issue 19).

Found by a reviewing helper session (stop 79, its stream families kept as scratch): the reference
record three times back to back from the data's start (one 36-minute recording, unscreened), 10
mm lower from the second copy, a vehicle of 30 kN in minutes 2-4. The noise model, young and
fitted on windows that carried the vehicle and the recorded test car, read a lag-one correlation
of 0.97; the detector held the step's windows and let them go as data (GLR 5.8 against 27.6), and
the stream ended at -0.97 / -1.02 mm ± 8.3 for -10, its last 24 windows at -10 mm, no event and
no warning. Since stop 81 the young noise model's windows are searched for a new level on their
own (``Shadow._young_level``, ``test_young_level.py``): the helper's kin with 120 s windows end at
the new state with one event; since stop 82 that stream itself too (its new level, the test car's
plateaus on it, was not beyond twice any vehicle within the young phase's 30 windows; the level
rule reads on while the last window lies beyond any vehicle below the first ones,
``Shadow._level_unsettled``). Where the estimate still does not follow (a vehicle of 20 kN parked
across the step), ``report.latest_level`` compares
the last ``event_confirm_windows`` windows used, read on their own through ``A``, with the
posterior, and a state outside its 95 % interval by more than any vehicle on the reactions' sum
is a warning (the CLI, the JSON, ``/diagnostics`` WARN).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config, report
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.loadtest_score import score_stream
from bridge_shadow.twin.real_records import Piece, Scenario, build, with_vehicle

W = 60 * 10**9
STEP = (-0.01, -0.01)
#: The helper's streams: (first record, window s, vehicle kN, its minutes after the data's start).
HIDDEN = {
    "60 s windows, 30 kN in minutes 2-4": ("ref", 60.0, 30.0, (2.0, 4.0)),
    # the new level's lowest windows beyond twice any vehicle (its mean is not: the test car's
    # plateaus on it); until stop 82 -0.99 mm +- 8.3 for -10, warned only
    "120 s windows, 30 kN in minutes 2-4": ("ref", 120.0, 30.0, (2.0, 4.0)),
    "120 s windows, 20 kN in minutes 1-7": ("ref", 120.0, 20.0, (1.0, 7.0)),
    "lowered first, 120 s windows, 25 kN in minutes 1-7": ("lowered", 120.0, 25.0, (1.0, 7.0)),
}
#: A stream the estimate does not follow, warned of: a vehicle parked across the step (the
#: helper's family A). (The helper's first stream, warned until stop 82, is in ``HIDDEN`` now.)
WARNED = {
    "20 kN in minutes 10-25": ("ref", 20.0, (10.0, 25.0)),
}
ACROSS = WARNED["20 kN in minutes 10-25"]


@pytest.fixture(scope="module")
def surrogate():
    return load_surrogate()


def _stream(folder: Path, surrogate, record: str, kn: float, minutes: tuple[float, float]) -> Scenario:
    """``record`` three times back to back from the data's start, 10 mm lower from the second copy."""
    pieces = [Piece(record, 0.0), Piece(record, 0.2, STEP), Piece(record, 0.4, STEP)]
    sc = build(folder / "Settlements", surrogate.A, pieces)
    sc.data = with_vehicle(sc.data, sc.starts_ns[0], 1e3 * kn, *minutes)
    return sc


def _latest_lines(lines: list[str]) -> list[str]:
    return [x for x in lines if x.startswith("the last ") and "outside the posterior's" in x]


@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(HIDDEN))
def test_a_settlement_the_young_noise_model_took_for_noise_is_followed(
    munich_data: Path, surrogate, name: str
) -> None:
    """Covered with one event, nothing left to say (stop 80: warned only; before: neither).

    The 60 s stream is the helper's first: warned only until stop 82 (-0.97 mm ± 8.3 for -10).
    """
    record, window_s, kn, minutes = HIDDEN[name]
    sc = _stream(munich_data, surrogate, record, kn, minutes)
    shadow = Shadow(load_config().replace(window_s=window_s), surrogate)
    res = shadow.run(sc.data)
    s = score_stream(sc, res, window_s)
    assert s.covered and len(res.events) == 1, (1e3 * res.mean_m, res.warnings)
    assert np.all(np.abs(res.mean_m - sc.truth_m) < 2.5e-3), 1e3 * res.mean_m
    assert report.latest_level(shadow) is None and not _latest_lines(res.warnings)


@pytest.mark.realdata
@pytest.mark.parametrize("name", sorted(WARNED))
def test_a_settlement_the_estimate_did_not_follow_is_said(munich_data: Path, surrogate, name: str) -> None:
    """Warned with the state the last windows read, within 1.5 mm of the truth (before stop 80: silent)."""
    config = load_config()
    sc = _stream(munich_data, surrogate, *WARNED[name])
    shadow = Shadow(config, surrogate)
    res = shadow.run(sc.data)
    latest = report.latest_level(shadow)
    lines = _latest_lines(res.warnings)
    assert latest is not None and len(lines) == 1, (1e3 * res.mean_m, res.warnings)
    # what the last windows read is the supports' state now: the test car's scatter, within 1.5 mm
    assert np.all(np.abs(latest["state_m"] - sc.truth_m) < 1.5e-3), 1e3 * latest["state_m"]
    assert latest["windows"] == config.event_confirm_windows
    assert abs(latest["sum_change_n"]) > config.traffic_vehicle_max_n
    diag = report.diagnostics(shadow)
    assert diag["level"] == "WARN" and lines[0] in diag["message"]
    # the JSON says which state the posterior stands for, and what the last windows read
    told = res.to_json()["posterior"]["state"]["latest_level"]
    assert np.allclose(told["state_m"], latest["state_m"], rtol=1e-12, atol=0.0)
    assert (
        told["since_ns"] == latest["since_ns"]
        and "may not be the supports' state now" in diag["state"]["text"]
    )


@pytest.mark.realdata
def test_the_state_is_the_last_windows_read_through_a(munich_data: Path, surrogate) -> None:
    """``state_m`` is ``A^-1 (mean of the last compensated windows - u0)``, from the outputs.

    The outputs carry each window's forces less the curve of its time; the check uses the curve
    of the end (refits move it by far less than the tolerance here: 0.3 mm is 1 kN).
    """
    sc = _stream(munich_data, surrogate, *ACROSS)
    shadow = Shadow(load_config(), surrogate)
    res = shadow.run(sc.data)
    latest = report.latest_level(shadow)
    assert latest is not None
    used = [o for o in res.outputs if o.updated][-latest["windows"] :]
    assert used[0].end_ns - W == latest["since_ns"] and used[-1].end_ns == latest["until_ns"]
    forces = np.mean([o.force_n for o in used], axis=0)
    expected = np.linalg.solve(surrogate.A, forces - surrogate.u0)
    assert np.allclose(latest["state_m"], expected, rtol=0.0, atol=3e-4), (latest["state_m"], expected)


@pytest.mark.realdata
@pytest.mark.parametrize(
    "pieces",
    [
        [Piece("ref", 0.0), Piece("lowered", 0.73)],
        [
            Piece("ref", 0.0),
            Piece("lowered", 0.73),
            Piece("lowered", 5.07, STEP),
            Piece("lowered", 6.9, (-0.02, -0.02)),
        ],
        [Piece("ref", 0.0), Piece("ref", 0.2, STEP), Piece("ref", 0.4, STEP)],
    ],
    ids=["the real pair", "the day", "three copies, no vehicle"],
)
def test_no_warning_where_the_estimate_holds_the_data(munich_data: Path, surrogate, pieces) -> None:
    """Where the estimate follows the data (each stream covered), the check is silent."""
    sc = build(munich_data / "Settlements", surrogate.A, pieces)
    shadow = Shadow(load_config(), surrogate)
    res = shadow.run(sc.data)
    assert score_stream(sc, res).covered
    assert report.latest_level(shadow) is None and not _latest_lines(res.warnings)
    assert "latest_level" not in res.to_json()["posterior"]["state"]


@pytest.mark.realdata
def test_the_last_windows_travel_in_a_checkpoint(munich_data: Path, surrogate) -> None:
    """Stopped in the last copy and resumed: the same windows, the same warning."""
    config = load_config().replace(traffic_hold_s=0.0)
    sc = _stream(munich_data, surrogate, *ACROSS)
    whole = Shadow(config, surrogate)
    whole.run(sc.data)
    stop = sc.starts_ns[2] + 8 * W
    first = Shadow(config, surrogate)
    first.run(sc.data.select(lambda t: t < stop), flush=False)
    resumed = Shadow.from_state_dict(first.state_dict(), config, surrogate)
    assert [w.k for w in resumed._latest] == [w.k for w in first._latest]
    assert len(resumed._latest) == config.event_confirm_windows
    resumed.run(sc.data.select(lambda t: t >= stop))
    a, b = report.latest_level(whole), report.latest_level(resumed)
    assert (a is None) == (b is None)
    if a is not None and b is not None:
        assert np.allclose(a["state_m"], b["state_m"], rtol=1e-9, atol=1e-12)
        assert a["since_ns"] == b["since_ns"]


@pytest.mark.realdata
def test_replay_live_says_it_as_the_direct_replay(munich_data: Path, surrogate, tmp_path) -> None:
    """The node (``replay --live``) reports the same latest-level warning as the direct replay.

    At 10 Hz (every 10th sample: the node's path is the same at any rate).
    """
    pytest.importorskip("rclpy")
    from test_loadtest_days import _live_and_direct

    sc = _stream(munich_data, surrogate, *ACROSS)
    data = sc.data.select(lambda stamps: np.arange(len(stamps)) % 10 == 0)
    live, direct = _live_and_direct(data, tmp_path)
    lines = _latest_lines(direct["warnings"])
    assert len(lines) == 1 and _latest_lines(live["warnings"]) == lines
    told = live["posterior"]["state"]["latest_level"]
    assert told["since_ns"] == direct["posterior"]["state"]["latest_level"]["since_ns"]
