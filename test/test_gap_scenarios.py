"""The gap diagnosis on withheld effects of the twin (issue 20), a few seeds of each scenario.

``benchmarks/gap_scenarios.py`` runs 50 seeds of each; here one or two pin the behaviour: the
withheld effect is in the top group, and the shadow's posterior after adding the named effects is
within 10 % of the true final settlement with a 95 % interval that covers it. The load-test days
are four 12-minute records hours apart (``twin.loadtest``); the shadow's handling of records hours
apart is part of what the posterior after checks. The fifth scenario, a sun-driven vertical
temperature difference, is pinned on ``bags/demo_3d`` by ``test/test_gap_shadow.py`` (named, and
the posterior after within 3 % of the paper's offset).
"""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.twin.scenarios import run_scenario

CASES = [("softer", 0), ("stiffer", 1), ("nonlinear", 2), ("first_step_only", 3)]


@pytest.mark.parametrize(("name", "seed"), CASES)
def test_load_test_day_names_the_withheld_support_and_follows_it(name: str, seed: int) -> None:
    out = run_scenario(name, seed)
    assert out.named, (name, out.group)
    assert out.within and out.covered, (out.after_m, out.sigma_m, out.truth_m)
    # the goal of issue 20 for steps two to three times the calibrated one: +-5 mm (95 %) at most
    # in the common mode when the later steps are extrapolated from the first
    if name in ("nonlinear", "first_step_only"):
        assert 1.96 * np.mean(out.sigma_m) <= 5e-3


def test_extrapolated_steps_are_covered_by_the_discrepancy() -> None:
    """Calibrated on the first 10 mm of a seating support, read at 20 and 30 mm (issue 20's goal).

    A strongly seating support (tangent stiffness proportional to the reaction, 1e7 / 2e7 N/m at
    the dead load): the model the gap writes (``--out-surrogate``) from the first imposed step
    carries a discrepancy beyond it; ``calibrate --check``'s reading of the later steps through it
    covers the truth with a 95 % interval of at most +-5 mm in the common mode, where the same model
    without the discrepancy misses.
    """
    from dataclasses import replace

    from bridge_shadow.calibrate.change import measured_change, record_level
    from bridge_shadow.calibrate.check import check_pair
    from bridge_shadow.effects import MODEL_FORM_EFFECTS
    from bridge_shadow.gap.diagnose import diagnose
    from bridge_shadow.gap.levels import slice_data
    from bridge_shadow.model.sensitivities import support_spring_change
    from bridge_shadow.twin.loadtest import RECORD_S, SeatingSupports
    from bridge_shadow.twin.scenarios import _as_built, _day

    fe, path = _as_built(None)
    k0 = (1e7, 2e7)
    reality, _ = support_spring_change(fe, k0, levelled=True)
    data, _, imposed = _day(5, reality, True, seating=SeatingSupports(k0, 1.0), structure=fe)
    dg = diagnose(data, fe, imposed=imposed, surrogate_path=path)
    after = dg.surrogate_after
    assert after is not None and after.discrepancy is not None and dg.summary["best"] in MODEL_FORM_EFFECTS
    starts = [r["start_ns"] for r in dg.summary["levels"]["records"]]
    level = [record_level(slice_data(data, s, s + round(RECORD_S * 1e9))) for s in starts]
    misses_without = 0
    for k, total in ((2, -0.020), (3, -0.030)):
        change = measured_change(level[0], level[k])
        imposed_m, sd = np.full(2, total), np.full(2, 5e-4)
        c = check_pair(f"0 -> {total}", change, after, imposed_m, sd)
        assert all(c.held()), (c.x_m, c.sd_m)
        assert 1.96 * c.common_sd_m <= 5e-3
        bare = check_pair("bare", change, replace(after, discrepancy=None), imposed_m, sd)
        misses_without += not all(bare.held())
    assert misses_without >= 1  # the discrepancy is what makes the extrapolation honest
