"""Settlements inside one recording longer than the traffic hold: never silently data (issue 19).

A recording longer than ``traffic_hold_s`` is released unscreened, as continuous monitoring is: the
test car parked in it is data, and early in the data the noise model holds it as noise. Found by
a reviewing helper session (stop 77) on the reference record copied three times back to back, one
36-minute recording, 10 mm lower through ``A`` for the second copy and 20 mm for the third: the
detector could not confirm the first step against that noise, its 15 held windows became data of
the old state, the noise model then took the step in too, and the stream ended at -0.9 / -0.9 mm
± 9.4 for -20, with no event and no warning, exit 0.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.report import unconfirmed_changes
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.loadtest_score import score_stream
from bridge_shadow.twin.real_records import Piece, build

W = 60 * 10**9


@pytest.fixture(scope="module")
def surrogate():
    return load_surrogate()


@pytest.mark.realdata
def test_a_lowering_inside_one_long_recording_with_the_test_car_is_no_silent_data(
    munich_data: Path, surrogate
) -> None:
    """Three copies of the reference record back to back, 0, -10 and -20 mm: the end state held.

    A run held ``event_max_pending`` windows that moved the reactions' sum by more than any vehicle,
    clear of no change at 95 %, is a provisional change (weighed "changed" against "not changed"),
    not data of the old state: the stream ends within 10 % of -20 mm with an interval holding it,
    the first step reported (a likely change; since stop 79 both steps are events), no window lost.
    """
    step = (-0.01, -0.01)
    pieces = [Piece("ref", 0.0), Piece("ref", 0.2, step), Piece("ref", 0.4, (-0.02, -0.02))]
    sc = build(munich_data / "Settlements", surrogate.A, pieces)
    res = Shadow(load_config(), surrogate).run(sc.data)
    s = score_stream(sc, res)
    assert s.covered and s.within, (1e3 * res.mean_m, s)  # before: -0.9 mm ± 9.4 for -20
    assert not s.lost_windows and res.rejected["outlier"] == 0
    first = sc.starts_ns[1] // W
    reported = [e.window for e in res.events] + [c.window for c in res.changes if c.likely]
    assert any(abs(k - first) <= 1 for k in reported), (reported, first)  # before: nothing said
    # each step is an event (the young noise model's check, ``Shadow._young_step``), or, as the
    # first was before that check (-18.3 mm, probability 0.82), a change not confirmed, warned
    events = [e.window for e in res.events]
    for start in sc.starts_ns[1:]:
        assert any(abs(k - start // W) <= 1 for k in events) or res.warnings, (events, start // W)


def test_a_run_used_as_data_that_moved_beyond_any_vehicle_is_a_warning(surrogate) -> None:
    """A run used as data is significant when its GLR passed, or when it moved clear and far.

    Far: the reactions' sum beyond any vehicle (``traffic_vehicle_max_n``); clear: its size's 95 %
    region excludes zero. A drift (a jump only as far as its own rate carried it) never is.
    """
    shadow = Shadow(load_config(), surrogate)
    h = shadow.detector.h_event
    cov = np.diag([4e6, 4e6])  # (2 kN)^2 per bearing: the step's own uncertainty
    lowered = (surrogate.A @ np.array([-0.01, -0.01])).tolist()  # the sum about -67 kN
    car = [4e3, 5e3]  # +9 kN: a parked car's size, clear of zero
    runs = {
        "far": (lowered, 0.5 * h, False),
        "far drift": (lowered, 0.5 * h, True),
        "car": (car, 0.5 * h, False),
        "car, GLR passed": (car, 2.0 * h, False),
        "far, not clear": (lowered, 0.5 * h, False, 1e3),
    }
    likely = {}
    for i, (name, (step_n, glr, drift, *scale)) in enumerate(runs.items()):
        c = cov * (scale[0] ** 2 if scale else 1.0)
        shadow.unconfirmed_runs = [
            {
                "window": 100 * i,
                "windows": 15,
                "until_window": 100 * i + 14,
                "glr": glr,
                "drift": drift,
                "step_n": step_n,
                "step_cov_n2": c.tolist(),
            }
        ]
        (change,) = [c for c in unconfirmed_changes(shadow) if c.kind == "run_in_data"]
        likely[name] = change.likely
    want = {"far": True, "far drift": False, "car": False, "car, GLR passed": True, "far, not clear": False}
    assert likely == want


@pytest.mark.realdata
def test_a_change_the_posterior_interval_does_not_hold_is_a_warning(munich_data: Path, surrogate) -> None:
    """The data cannot tell a change from none; the interval holds only the old state: said.

    The reference record, then 4 h on (with the air of 6 h) the same record four times back to back,
    10 mm lower from the second copy. The shadow read the new state at -8 to -9 mm for 36 minutes;
    the end's refit, its noise model holding the test car's plateaus as a correlation near one,
    put the change at probability 0.11 and the estimate at -0.9 ± 7.3 mm, an interval without the
    state the data showed, and nothing was said (before stop 79, as found by a reviewing helper's
    grid; not fixed: the segments' levels under that noise cannot tell the two apart). Now the
    change is a warning that names the state it would mean (``state_if_changed_m``).
    """
    pieces = [Piece("ref", 0.0)]
    for i in range(4):
        dx = -0.01 if i >= 1 else 0.0
        pieces.append(Piece("ref", 4.0 + 0.2 * i, (dx, dx), temp_at_h=6.0 + 0.2 * i))
    sc = build(munich_data / "Settlements", surrogate.A, pieces)
    res = Shadow(load_config(), surrogate).run(sc.data)
    odd = [c for c in res.changes if c.state_if_changed_m is not None]
    assert odd, [c.to_json() for c in res.changes]
    c = odd[0]
    assert c.likely and 1e-3 < c.change_probability <= 0.5
    sd = np.sqrt(np.diag(res.covariance_m2))
    assert np.any(np.abs(c.state_if_changed_m - res.mean_m) > 1.96 * sd)  # outside the interval
    np.testing.assert_allclose(c.state_if_changed_m, sc.truth_m, atol=0.0025)  # the state the data showed
    assert any("does not hold the state it would mean" in w for w in res.warnings), res.warnings
    assert "state_if_changed_m" in c.to_json()
