"""The paper's prior rule: 3 sigma = the settlement at which a central reaction vanishes."""

from __future__ import annotations

import numpy as np
import pytest

from bridge_shadow.errors import ConfigError
from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.estimate.settlement.prior import prior_sigma
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.paths import config_file


def test_rule_from_the_fe_surrogate_and_the_override() -> None:
    sur = load_surrogate(config_file("surrogate_fe.yaml"))  # the as-built FE model
    one, both = prior_sigma(sur.A, sur.u0, "one_bearing"), prior_sigma(sur.A, sur.u0, "both")
    # the reaction of a support vanishes at 3 sigma: alone, or with both supports settling together
    np.testing.assert_allclose(sur.u0 - np.diag(sur.A) * 3 * one, 0.0, atol=1e-6)
    np.testing.assert_allclose(sur.u0 - sur.A.sum(axis=1) * 3 * both, 0.0, atol=1e-6)
    assert np.all(both > one)
    if sur.provenance.get("solver", "").startswith("bridge_shadow.fe"):  # the uncalibrated FE model
        np.testing.assert_allclose(one, 4.54e-3, rtol=0.01)
        np.testing.assert_allclose(both, 14.1e-3, rtol=0.01)
    np.testing.assert_allclose(Shadow(ShadowConfig(), sur).prior_sigma_m, one, rtol=1e-12)
    paper = Shadow(ShadowConfig(prior_sigma_m=[3e-4, 3e-4]), sur)
    assert (  # exact: the configured values passed through
        np.array_equal(paper.prior_sigma_m, [3e-4, 3e-4]) and paper.prior_info()["source"] == "prior_sigma_m"
    )
    with pytest.raises(ConfigError):
        ShadowConfig(prior_rule="half")
    with pytest.raises(ConfigError):
        prior_sigma(-sur.A, sur.u0)
