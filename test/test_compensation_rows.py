"""The curve and its variance at windows known in both channels (both at once) equal the channel loop.

A live window is one row with a temperature in both channels; ``Compensation._curve_rows_known``
and ``_curve_variance_known`` evaluate both channels at once. The channel loop
(``_curve_rows_by_channel``, ``_curve_variance_by_channel``) is the definition: on the fits of a
bundled bag's replay (with and without the sun term), at temperatures inside and beyond the range
fitted, both give the same values, and a row without a temperature sends a batch down the loop.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import read_monitoring
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import load_surrogate


@pytest.fixture(scope="module", params=[False, True], ids=["no_sun", "sun_term"])
def fitted(root: Path, request) -> Shadow:
    data = read_monitoring(root / "bags" / "baseline_1d")
    shadow = Shadow(load_config().replace(sun_gradient=request.param), load_surrogate())
    shadow.run(data)
    assert shadow.fit is not None and shadow.compensation.sun == request.param
    return shadow


def test_both_channels_at_once_equal_the_channel_loop(fitted: Shadow) -> None:
    comp, fit = fitted.compensation, fitted.fit
    rng = np.random.default_rng(0)
    lo, hi = float(fit.t_lo.min()), float(fit.t_hi.max())
    temps = rng.uniform(lo - 15.0, hi + 15.0, (40, 2))  # inside and beyond the fitted range
    temps[:3] = [[comp.t_min - 3.0, comp.t_max + 4.0], [lo, hi], [comp.t_min, comp.t_max]]
    sun = rng.uniform(0.0, 1.0, 40)
    i0, bv = comp.basis_rows(temps, sun)
    assert (i0 >= 0).all()
    rows = comp.curve_rows(fit, temps, i0, bv)
    var = comp.curve_variance(fit, i0, bv)
    loop_rows = comp._curve_rows_by_channel(fit, temps, i0, bv)
    loop_var = comp._curve_variance_by_channel(fit, i0, bv)
    np.testing.assert_allclose(rows, loop_rows, rtol=1e-15, atol=0.0)
    np.testing.assert_allclose(var, loop_var, rtol=1e-15, atol=0.0)
    assert np.all(var > 0) and np.ptp(rows[:, 0]) > 0
    # one by one, as a live node evaluates them
    for j in range(0, 40, 7):
        one = comp.curve_rows(fit, temps[j : j + 1], i0[j : j + 1], bv[j : j + 1])
        np.testing.assert_allclose(one, loop_rows[j : j + 1], rtol=1e-15, atol=0.0)


def test_a_row_without_temperature_goes_down_the_channel_loop(fitted: Shadow) -> None:
    comp, fit = fitted.compensation, fitted.fit
    temps = np.array([[5.0, 6.0], [np.nan, 7.0], [8.0, np.nan]])
    i0, bv = comp.basis_rows(temps)
    assert (i0 < 0).sum() == 2
    rows = comp.curve_rows(fit, temps, i0, bv)
    var = comp.curve_variance(fit, i0, bv)
    # exact: a channel without a temperature is set to 0, not computed
    assert rows[1, 0] == 0.0 and rows[2, 1] == 0.0 and var[1, 0] == 0.0 and var[2, 1] == 0.0
    known = comp.curve_rows(fit, temps[:1], i0[:1], bv[:1])
    np.testing.assert_allclose(rows[:1], known, rtol=1e-15, atol=0.0)
    np.testing.assert_allclose(var[:1], comp.curve_variance(fit, i0[:1], bv[:1]), rtol=1e-15, atol=0.0)


def test_one_window_in_floats_equals_the_rows(fitted: Shadow) -> None:
    """``basis_one`` and ``curve_one`` (a live window in Python floats) give the rows' values.

    The basis is compared exactly: both paths run the one recursion (``spline.nonzero_at``). The
    curve and its variance do the same operations in numpy's order (sums of at most five terms
    left to right, the quadratic form row by row) and are equal bit for bit here, but numpy may
    sum in another order on another machine's SIMD units, so they are held to 1e-14.
    """
    comp, fit = fitted.compensation, fitted.fit
    rng = np.random.default_rng(1)
    lo, hi = float(fit.t_lo.min()), float(fit.t_hi.max())
    temps = rng.uniform(lo - 15.0, hi + 15.0, (60, 2))
    temps[:4] = [[comp.t_min - 3.0, comp.t_max + 4.0], [lo, hi], [comp.t_min, comp.t_max], [np.nan, 7.0]]
    temps[4] = [8.0, np.nan]
    sun = rng.uniform(0.0, 1.0, 60)
    i0, bv = comp.basis_rows(temps, sun)
    for j in range(60):
        one_i0, one_bv = comp.basis_one(temps[j].tolist(), float(sun[j]))
        assert one_i0 == i0[j].tolist() and one_bv == bv[j].tolist()
        one = comp.curve_one(fit, temps[j].tolist(), one_i0, one_bv)
        if j in (3, 4):  # a channel without a temperature: the general paths decide
            assert one is None
            continue
        assert one is not None
        rows = comp.curve_rows(fit, temps[j : j + 1], i0[j : j + 1], bv[j : j + 1])
        var = comp.curve_variance(fit, i0[j : j + 1], bv[j : j + 1])
        np.testing.assert_allclose(one[0], rows[0], rtol=1e-14, atol=0.0)
        np.testing.assert_allclose(one[1], var[0], rtol=1e-14, atol=1e-30)
    # no sun value given: the rows' sun covariate of 0
    assert comp.basis_one([5.0, 6.0])[1] == comp.basis_rows(np.array([[5.0, 6.0]]))[1][0].tolist()
