"""The sun term averaged over its explanations by evidence (``sun_gradient_fit: average``, shipped).

- The deck's ``g`` and its variance are the moments of the mixture of three explanations, equally
  likely before the data (no term, one ``g`` of the deck, a ``g`` of each bearing's own), weighed by
  their Bayes factors: checked against draws from that mixture.
- The fit holds ``g`` at that average: the same levels and curve as the fit without a sun column
  on the data with ``slope g s`` taken out; the sun's row and column of the fit's inverse are the
  term's own, scaled to the average's sd.
- On the twin's sunny load-test day (a 4 K vertical difference at full sun, four records hours
  apart, 10 mm lower each time) the shipped shadow ends within 10 % where the shadow without the
  term does not (``benchmarks/loadtest_days.py --only twin``).
"""

from __future__ import annotations

import numpy as np
import pytest
from sun_helpers import sun_rows

from bridge_shadow.estimate import load_config
from bridge_shadow.estimate.compensation.fit import Compensation
from bridge_shadow.estimate.compensation.sums import FitSums


@pytest.mark.parametrize(
    "evidence",
    [(0.27, -0.46, 1.8, 1.3), (2.0, 0.5, 3.0, 0.8), (-3.4, -5.7, -0.4, 0.5), (1.0, 2.5, 2.2, 1.1)],
)
def test_the_averaged_g_is_the_mixture_of_the_three_explanations(evidence) -> None:
    """``w m`` and ``sqrt(w (s^2 + m^2) - (w m)^2)``: the mean and sd of draws from the mixture."""
    log_d, log_s, mean, sd = evidence
    g, scale = Compensation.averaged_sun(np.array(evidence))
    rng = np.random.default_rng(11)
    n = 400_000
    p = np.exp([0.0, log_d, log_s])
    which = rng.choice(3, n, p=p / p.sum())  # none, the deck's g, each bearing's own (not the deck's)
    draws = np.where(which == 1, rng.normal(max(mean, 0.0), sd, n), 0.0)
    assert g == pytest.approx(draws.mean(), abs=5.0 * draws.std() / np.sqrt(n))
    assert scale * sd == pytest.approx(draws.std(), rel=0.01)


def test_overwhelming_evidence_is_the_decks_g_and_none_is_no_term() -> None:
    """A Bayes factor of e^40 leaves the deck's posterior as it is; e^-40 takes the term out."""
    g, scale = Compensation.averaged_sun(np.array([40.0, 0.0, 2.0, 0.5]))
    assert g == pytest.approx(2.0, rel=1e-12) and scale == pytest.approx(1.0, rel=1e-6)
    g, scale = Compensation.averaged_sun(np.array([-40.0, 0.0, 2.0, 0.5]))
    assert g == pytest.approx(0.0, abs=1e-12) and scale == pytest.approx(0.0, abs=1e-6)
    g, _ = Compensation.averaged_sun(np.array([40.0, 0.0, -1.0, 0.5]))  # a cooling sun: g >= 0
    assert g == 0.0  # set: max(mean, 0)


def test_the_averaged_fit_is_the_fit_without_the_sun_on_data_without_its_force() -> None:
    """Held at ``g``, the sun's force ``slope g s`` is data: the plain fit of ``y - slope g s``."""
    slope = np.array([-4000.0, -5000.0])
    kw = {"mode": "fixed", "slope_fe": np.array([10.0, 12.0])}
    avg = Compensation(-20.0, 45.0, 13, sun_slope=slope, sun_fit="average", **kw)
    deck = Compensation(-20.0, 45.0, 13, sun_slope=slope, sun_min_bf=0.0, sun_fit="deck", **kw)
    plain = Compensation(-20.0, 45.0, 13, **kw)
    rows, s = sun_rows(avg, 300, 4)
    sigma = np.array([4.0e4, 5.0e4])  # N per sample: the sun's few kN barely shown (w near a half)
    rows.y += np.random.default_rng(5).normal(0.0, 1.0, rows.y.shape) * sigma / np.sqrt(rows.m)
    sums = FitSums(avg.q, avg.width)
    sums.add(rows)
    kappa = avg.slope_weight(sigma**2)
    lam = np.array([50.0, 50.0])
    fit = avg.fit(sums, lam=lam, kappa=kappa)
    full = deck.fit(sums, lam=lam, kappa=kappa)
    g, scale = Compensation.averaged_sun(fit.sun_evidence)
    assert 0.05 < g < full.sun_evidence[2] and 0.0 < scale  # partly in: the evidence is not decisive
    np.testing.assert_allclose(fit.beta[:, -1], slope * g, rtol=1e-12)
    ref_rows, _ = sun_rows(plain, 300, 4)
    ref_rows.y[:] = rows.y - np.outer(s, slope * g)
    ref_sums = FitSums(plain.q, plain.width)
    ref_sums.add(ref_rows)
    ref = plain.fit(ref_sums, lam=lam, kappa=kappa)
    np.testing.assert_allclose(fit.beta[:, :-1], ref.beta, rtol=1e-8, atol=1e-9 * np.abs(ref.beta).max())
    np.testing.assert_allclose(fit.level, ref.level, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(fit.minv[:, -1, -1], scale**2 * full.minv[:, -1, -1], rtol=1e-10)
    np.testing.assert_allclose(fit.minv[:, :-1, -1], scale * full.minv[:, :-1, -1], rtol=1e-10, atol=1e-300)
    np.testing.assert_allclose(fit.minv[:, :-1, :-1], full.minv[:, :-1, :-1], rtol=1e-10)


def test_the_shipped_shadow_averages_the_sun_term() -> None:
    """The shipped parameters: the sun term on, averaged over its explanations."""
    cfg = load_config()
    assert cfg.sun_gradient is True and cfg.sun_gradient_fit == "average"  # shipped settings


def test_the_json_the_diagnostics_and_the_cli_say_the_averaged_term() -> None:
    """One ``g`` and one sd for both bearings, the deck's probability, in the JSON, diagnostics, CLI."""
    from bridge_shadow.commands.replay import _sun_text
    from bridge_shadow.estimate import Shadow
    from bridge_shadow.estimate.compensation.fit import deck_sun_weight
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.twin.simulate import simulate

    data, _ = simulate(2.0, 0.1, 4, {"vertical_gradient": 4.0})
    shadow = Shadow(load_config(), load_surrogate())
    shadow.run(data)
    ev = shadow.fit.sun_evidence
    g, scale = Compensation.averaged_sun(ev)
    w = deck_sun_weight(ev)
    assert 0.0 < w < 1.0
    info = shadow.spline_info()
    slope = shadow.compensation.sun_slope
    for c, ch in enumerate(("frc_01", "frc_02")):
        sp = info[ch]
        assert sp["sun_gradient_fit"] == "average" and sp["sun_gradient_weight"] == pytest.approx(w)
        assert sp["sun_gradient_k"] == pytest.approx(g, rel=1e-9)
        assert shadow.fit.beta[c, -1] == pytest.approx(slope[c] * g, rel=1e-9)
        assert sp["sun_gradient_sd_k"] == pytest.approx(scale * ev[3], rel=1e-9)  # the mixture's
        assert f"in with probability {w:.2f}" in _sun_text(sp)
    pytest.importorskip("diagnostic_msgs")
    from bridge_shadow.ros.diagnostics import statuses

    comp = statuses(shadow.diagnostics(), {"frc_01": 0.1, "frc_02": 0.1, "air_temperature": 0.1})[2]
    assert comp.values["frc_01 sun term probability"] == f"{w:.2f}"
