"""The real-record streams' score: which rejected windows lose a state (``twin.loadtest_score``)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bridge_shadow.twin.loadtest_score import car_excursions, score_stream
from bridge_shadow.twin.real_records import Piece, Scenario, build, car_stretches_ns

W = 60 * 1_000_000_000


def _result(windows: dict[int, str]) -> SimpleNamespace:
    """A replay's outputs: window end (in W) -> reason (``""`` used)."""
    outputs = [SimpleNamespace(end_ns=k * W, reason=r) for k, r in sorted(windows.items())]
    return SimpleNamespace(
        outputs=outputs, events=[], changes=[], mean_m=np.zeros(2), covariance_m2=np.eye(2) * 1e-6
    )


def test_a_parked_car_on_a_state_then_held_is_an_excursion_and_nothing_else_is() -> None:
    """Rejected windows of changed records count as car excursions only under the car, on a kept state.

    The later record at 100 W holds -10 mm, then -20 mm from 104.5 W; the recorded car stands over
    101.5-108.5 W. Under the car and followed by a used window of the same state: an excursion
    (the windows ending at 102 and 109 W). Under the car but followed by another state (104 W: the
    -10 mm state's last minutes are lost, as a short raise under the car was in the inside study's
    stream #93), straddling the change (105 W), or with no car (112 W): a state's windows lost.
    """
    pieces = (Piece("ref", 0.0), Piece("lowered", 1.0), Piece("lowered", 1.1, (-0.01, -0.01)))
    sc = Scenario(None, pieces, [0, 100 * W, 209 * W // 2], ((203 * W // 2, 217 * W // 2),))
    windows = {k: "" for k in (*range(1, 11), 101, 103, 106, 107, 110, 111, 113)}
    windows |= {102: "outlier", 104: "outlier", 105: "outlier", 109: "outlier", 112: "outlier"}
    s = score_stream(sc, _result(windows))
    assert s.lost_windows == 5
    assert s.lost_under_car == 2
    assert s.lost_car_free == 3
    # without the car every rejected window of a changed record loses a state
    bare = score_stream(Scenario(None, pieces, sc.starts_ns), _result(windows))
    assert (bare.lost_windows, bare.lost_car_free) == (5, 5)


def test_a_window_across_slices_of_one_state_is_in_one_piece() -> None:
    """A record cut into slices (as ``lowered_over`` cuts one) is one state where its slices' states agree.

    The later record at 100 W in half-window slices: -10 mm up to 104.5 W, then -12 mm from there
    (a jack's first slice), the car over 100.5-105.5 W. The window ending at 102 W straddles two
    slices of -10 mm: under the car, the next used window of that state, an excursion
    (``car_excursions``; it counted as a state's window lost while only one piece was one
    state). The window ending at 105 W straddles -10 and -12 mm slices: a state's window.
    """
    pieces = [Piece("ref", 0.0)]
    starts = [0]
    for i in range(10):
        x = -0.01 if i < 9 else -0.012
        pieces.append(Piece("lowered", 1.0, (x, x)))
        starts.append(100 * W + i * W // 2)
    sc = Scenario(None, tuple(pieces), starts, ((201 * W // 2, 211 * W // 2),))
    windows = {k: "" for k in (*range(1, 11), 101, 103, 104, 106)}
    windows |= {102: "outlier", 105: "outlier"}
    res = _result(windows)
    assert car_excursions(sc, res, [102 * W, 105 * W], W) == 1  # a count of windows
    assert car_excursions(sc, res, [102 * W], W) == 1
    assert car_excursions(sc, res, [105 * W], W) == 0


@pytest.mark.realdata
def test_the_recorded_car_is_placed_with_its_piece_and_cut_with_it(munich_data) -> None:
    """Each record's parked car (minutes 1.5-8.5 as recorded) moves with the piece, cut to its minutes."""
    folder = munich_data / "Settlements"
    parked = {
        name: max(stretches, key=lambda ab: ab[1] - ab[0])
        for name, stretches in car_stretches_ns(folder).items()
    }
    for a, b in parked.values():
        assert 6.0 * W < b - a < 8.0 * W  # the car stood about seven minutes in both records
    sc = build(folder, np.eye(2), [Piece("ref", 0.0), Piece("lowered", 3.0, cut_min=(0.0, 5.0))])
    later = [ab for ab in sc.car_ns if ab[0] >= sc.starts_ns[1]]
    assert later
    assert max(b for _, b in later) <= sc.starts_ns[1] + 5 * W  # cut with the record at minute 5
    first_parked = [ab for ab in sc.car_ns if ab[1] <= sc.starts_ns[1]]
    assert max(b - a for a, b in first_parked) == parked["ref"][1] - parked["ref"][0]  # integer ns
