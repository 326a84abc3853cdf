"""Model averaging over the explanations, the discrepancy beyond the calibrated settlements, prior sets."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.calibrate.change import MeasuredChange
from bridge_shadow.calibrate.explain import fit_explanation
from bridge_shadow.calibrate.forward import SolutionStore
from bridge_shadow.calibrate.problem import PairData
from bridge_shadow.calibrate.run import (
    evidence_weights,
    model_average,
    prior_sensitivity,
    prior_set_fits,
    prior_set_members,
)
from bridge_shadow.calibrate.spec import spec_from_dict
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.parameters import PRIOR_SETS, prior_table
from bridge_shadow.model.surrogate_file import Discrepancy, Surrogate, load_surrogate, save_surrogate


@dataclass
class _Post:
    log_evidence: float


@dataclass
class _Fake:
    """What model_average reads of an explanation: its evidence, MAP vector and covariance."""

    post: _Post
    vec: np.ndarray
    cov: np.ndarray

    def model_vector(self) -> np.ndarray:
        return self.vec

    def model_cov(self) -> np.ndarray:
        return self.cov


def test_model_average_is_the_mixture_of_the_explanations() -> None:
    """Mean and covariance of the evidence-weighted mixture, against sampling the mixture."""
    rng = np.random.default_rng(3)
    fakes = {}
    for k, logz in enumerate((-24.0, -24.7, -26.1)):
        root = rng.normal(size=(12, 12)) * 0.1
        fakes[f"e{k}"] = _Fake(_Post(logz), rng.normal(size=12) * (k + 1), root @ root.T)
    w = evidence_weights(fakes)  # type: ignore[arg-type]
    np.testing.assert_allclose(sum(w.values()), 1.0, rtol=1e-12)
    assert w["e0"] / w["e1"] == pytest.approx(np.exp(0.7), rel=1e-12)
    mean, cov = model_average(fakes)  # type: ignore[arg-type]
    n = 200_000
    pick = rng.choice(3, size=n, p=[w[f"e{k}"] for k in range(3)])
    draws = np.empty((n, 12))
    for k in range(3):
        sel = pick == k
        draws[sel] = rng.multivariate_normal(fakes[f"e{k}"].vec, fakes[f"e{k}"].cov, size=int(sel.sum()))
    np.testing.assert_allclose(mean, draws.mean(axis=0), atol=0.03)
    np.testing.assert_allclose(cov, np.cov(draws.T), atol=0.06)
    # about another point: the second moment (what the single chosen explanation's file carried)
    about = fakes["e0"].vec
    _, second = model_average(fakes, about=about)  # type: ignore[arg-type]
    d = mean - about
    np.testing.assert_allclose(second, cov + np.outer(d, d), rtol=1e-9, atol=1e-12)


def test_discrepancy_is_zero_where_calibrated_and_grows_beyond() -> None:
    d = Discrepancy.from_steps(np.array([[-0.010, -0.010]]))
    assert d.low_m == (-0.010, -0.010) and d.high_m == (0.0, 0.0)
    for x in ([0.0, 0.0], [-0.005, -0.010], [-0.010, -0.002]):
        assert np.all(d.covariance(np.array(x)) == 0.0)  # inside: the calibration pinned the secant
    # a 30 mm lowering lies 20 mm beyond: sd 10 % of 20 mm per support, correlation 0.5
    cov = d.covariance(np.array([-0.030, -0.030]))
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), [0.002, 0.002], rtol=1e-12)
    assert cov[0, 1] / cov[0, 0] == pytest.approx(0.5)
    # against sampling the relative error of the extrapolated part
    rng = np.random.default_rng(0)
    x = np.array([-0.040, -0.025])
    rho = rng.multivariate_normal(np.zeros(2), 0.01 * np.array([[1, 0.5], [0.5, 1]]), size=100_000)
    reading_error = rho * d.beyond(x)
    np.testing.assert_allclose(d.covariance(x), np.cov(reading_error.T), rtol=0.03)
    with pytest.raises(Exception, match="low_m <= high_m"):
        Discrepancy((0.0, 0.0), (-1.0, 0.0))


def test_surrogate_carries_the_full_model_uncertainty_and_the_discrepancy(tmp_path: Path) -> None:
    a = np.array([[3.9e6, -1.5e6], [-1.5e6, 5.8e6]])
    rng = np.random.default_rng(2)
    root = rng.normal(size=(12, 12)) * np.r_[np.full(4, 1e5), np.full(2, 1e3), np.full(6, 1e2)][:, None]
    cov = root @ root.T
    thermal = {
        "uniform": [10.0, 12.0],
        "vertical_gradient": [-3e3, -5e3],
        "transverse_gradient": [500.0, -700.0],
    }
    s = Surrogate(a, [2.39e5, 2.39e5], thermal, {}, cov, Discrepancy.from_steps(np.array([[-0.01, -0.01]])))
    back = load_surrogate(save_surrogate(s, tmp_path / "s.yaml"))
    np.testing.assert_allclose(back.model_cov, s.model_cov, rtol=1e-12)
    assert back.discrepancy == s.discrepancy
    np.testing.assert_allclose(back.thermal_covariance("vertical_gradient"), cov[8:10, 8:10], rtol=1e-12)
    # the settlement covariance: A and u0 (the first six) plus the discrepancy beyond -10 mm
    x = np.array([-0.030, -0.025])
    six = Surrogate(a, s.u0, thermal, {}, cov[:6, :6]).model_covariance(x)
    np.testing.assert_allclose(s.model_covariance(x), six + s.discrepancy.covariance(x), rtol=1e-12)
    # a surrogate with only a discrepancy still reports it (the shadow adds model_covariance when
    # model_cov is set)
    only = Surrogate(a, s.u0, thermal, {}, None, s.discrepancy)
    np.testing.assert_allclose(only.model_covariance(x), s.discrepancy.covariance(x), rtol=1e-12)


@pytest.fixture(scope="module")
def spring_pair() -> tuple[list[PairData], dict]:
    """A pair whose change support springs (south 2e7, north 6e7 N/m) made on the coarse FE model."""
    from bridge_shadow.calibrate.forward import ForwardModel

    cfg = load_bridge_config()
    store = SolutionStore()
    names = ("support_spring_south", "support_spring_north")
    truth = ForwardModel(cfg, "coarse", names, store).evaluate(dict(zip(names, (2e7, 6e7), strict=True)))
    imposed = np.array([-0.010, -0.010])
    change = MeasuredChange(truth.A @ imposed, np.diag([200.0, 200.0]) ** 2)
    pairs = [PairData("twin", imposed, [1e-4, 1e-4], change)]
    fitted = {
        "as_built": fit_explanation("as_built", (), cfg, "coarse", pairs, store),
        "support_springs": fit_explanation("support_springs", names, cfg, "coarse", pairs, store),
    }
    return pairs, {"cfg": cfg, "store": store, "fitted": fitted}


def _spring_spec():
    """The calibration file of ``spring_pair``: the model as built and the two support springs."""
    pair = {"before": "x", "after": "y", "imposed_m": [-0.01, -0.01], "imposed_sd_m": [1e-4, 1e-4]}
    springs = ["support_spring_south", "support_spring_north"]
    return spec_from_dict(
        {"mesh": "coarse", "pairs": [pair], "explanations": {"as_built": [], "support_springs": springs}}
    )


def test_prior_sensitivity_refits_what_a_prior_set_changes(spring_pair) -> None:
    pairs, ctx = spring_pair
    spec = _spring_spec()
    fits = prior_set_fits(spec, ctx["cfg"], pairs, ctx["fitted"], ctx["store"])
    rows = prior_sensitivity(spec, pairs, fits)
    assert [r["prior_set"] for r in rows] == list(PRIOR_SETS)
    by = {r["prior_set"]: {e["name"]: e for e in r["explanations"]} for r in rows}
    springs = ctx["fitted"]["support_springs"]
    for name, r in by.items():
        assert r["as_built"]["log_evidence"] == ctx["fitted"]["as_built"].post.log_evidence or name == "wide"
        assert rows[list(PRIOR_SETS).index(name)]["winner"] == "support_springs"
    # the data fix both springs (posterior sd ~ 1e-2 of the prior's): doubling the prior's sd costs
    # the Occam factor ln 2 per spring and shrinks the prior penalty u^2 / 2 by 3/4 (Laplace)
    u = springs.lm.x[:2]
    predicted = springs.post.log_evidence - 2 * np.log(2.0) + 0.5 * np.sum(u**2) * 0.75
    assert by["wide"]["support_springs"]["log_evidence"] == pytest.approx(predicted, abs=0.05)
    # under the first-written prior (centre 2e8) the same springs sit further below the centre
    first = prior_table("first_written")["support_spring_south"]
    assert first.to_whitened(2e7) < prior_table("sources")["support_spring_south"].to_whitened(2e7)


def test_the_prior_sets_average_runs_over_the_sets_not_chosen_after_the_data(spring_pair) -> None:
    """``prior_set_members``: each explanation under each defensible set, weighed by its evidence.

    The set chosen after seeing the real pair (``after_fit``) is never a member; a fit two sets
    share is a member under each; a fit outside the plausible range under another set than the
    one in use is left out, with why; the average's mean is the members' evidence-weighted mean.
    """
    pairs, ctx = spring_pair
    spec = _spring_spec()
    fits = prior_set_fits(spec, ctx["cfg"], pairs, ctx["fitted"], ctx["store"])
    members, left_out = prior_set_members(fits, "sources")
    sets = [k for k, s in PRIOR_SETS.items() if not s.after_data]
    assert "after_fit" not in sets and len(sets) >= 3
    names = ("as_built", "support_springs")
    assert set(members) | set(left_out) == {f"{e} ({s})" for s in sets for e in names}
    assert members["as_built (first_written)"] is members["as_built (sources)"]  # untouched: shared
    log_z = np.array([m.post.log_evidence for m in members.values()])
    w = np.exp(log_z - log_z.max()) / np.exp(log_z - log_z.max()).sum()
    mean, _ = model_average(members)
    by_hand = sum(wi * m.model_vector() for wi, m in zip(w, members.values(), strict=True))
    np.testing.assert_allclose(mean, by_hand, rtol=1e-10)
    # a fit outside the plausible range under another set is left out, never the one in use's
    far = dict(fits)
    far["wide"] = {**fits["wide"], "support_springs": _Outside(fits["wide"]["support_springs"])}
    members, left_out = prior_set_members(far, "sources")
    assert "support_springs (wide)" in left_out and "plausible range" in left_out["support_springs (wide)"]
    members, left_out = prior_set_members(far, "wide")
    assert "support_springs (wide)" in members


class _Outside:
    """An explanation whose MAP lies outside the plausible range (the rest as ``e``'s)."""

    def __init__(self, e) -> None:
        self._e = e

    def values(self) -> dict[str, float]:
        return {"support_spring_south": 1e3, "support_spring_north": 1e3}

    def __getattr__(self, name: str):
        return getattr(self._e, name)
