"""Imposed steps that name no effect: the model after is their explanations' average, not the model.

A twin's load-test day whose supports have springs of 1e8 N/m under the as-built (rigid) model,
all three 10 mm steps given: the springs are likelier than the model as given, but not by the
naming factor (the jacks' 0.5 mm leave 5 % of stiffness open). The model after was the model as
given, its interval the noise's alone (about ±0.2 mm), the day's end 1.7 mm short: 0 of 12 seeds
covered (a reviewing helper's grid). And the statement said no explanation fits: the jacks' test
divided the model as given's jack error (0.55 mm, about one of the jacks' 0.5 mm) by the fit's
posterior sd of it (0.03 mm), 18 "sds". Now the test is against the jacks' accuracy, and the
model after averages every explanation by its probability.
"""

from __future__ import annotations

import numpy as np


def _day(seed: int):
    from bridge_shadow.model.sensitivities import support_spring_change
    from bridge_shadow.twin import scenarios

    fe, path = scenarios._as_built(None)
    reality, _ = support_spring_change(fe, (1e8, 1e8), levelled=True)
    data, truth, imposed = scenarios._day(seed, reality, False)
    return data, fe, path, imposed, np.array(truth["settlement_m"][-1])


def test_an_unnamed_explanation_is_averaged_in_and_the_interval_holds_the_truth() -> None:
    from bridge_shadow.gap.diagnose import diagnose
    from bridge_shadow.gap.posterior import IMPOSED_AVERAGE

    data, fe, path, imposed, truth = _day(1000)
    s = diagnose(data, fe, imposed=imposed, shadow=True, surrogate_path=path).summary
    imp = s["levels"]["imposed"]
    assert not imp["named"] and imp["best"] != "settlement_step"
    assert imp["misfit"] is None and "no explanation fits" not in s["statement"]
    assert "averages the explanations by their probability" in s["statement"]
    before, after = s["posterior"]["before"], s["posterior"]["after"]
    assert after["effects_added"] == [IMPOSED_AVERAGE] and "averaged over the imposed steps'" in after["what"]
    err_before = np.abs(np.asarray(before["mean_m"]) - truth)
    err_after = np.abs(np.asarray(after["mean_m"]) - truth)
    assert np.any(err_before > 1.96 * np.asarray(before["sigma_m"]))  # the model as given misses
    assert np.all(err_after <= 1.96 * np.asarray(after["sigma_m"])) and np.all(err_after < err_before)
    assert np.all(err_after <= 0.10 * np.abs(truth))


def test_the_jacks_test_reads_their_accuracy_not_the_fits_posterior() -> None:
    from bridge_shadow.gap.levels import MISFIT_SD
    from bridge_shadow.gap.residual import residual_of

    data, fe, path, imposed, _ = _day(1000)
    an = residual_of(data, fe, 60.0, None, imposed, 5e-4, path, "uncertainty").levels.imposed
    row = an.explanations["settlement_step"].summary()["imposed_error_m"]
    jacks = np.array([e["map"] for e in row.values()])
    posterior_sd = np.array([e["sd"] for e in row.values()])
    # the model as given needs about one accuracy of the jacks: many of the fit's own sds, not four of theirs
    assert np.max(np.abs(jacks)) < MISFIT_SD * 5e-4 < np.max(np.abs(jacks) / posterior_sd) * 5e-4
    assert an.misfit("settlement_step") is None
