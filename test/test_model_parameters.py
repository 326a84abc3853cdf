"""The parameter priors agree with config/bridge.yaml and say where they come from."""

from __future__ import annotations

import numpy as np

from bridge_shadow.model.config import MAY_BE_INFINITE, load_bridge_config
from bridge_shadow.model.parameters import PARAMETERS


def test_prior_centres_are_the_bridge_yaml_values() -> None:
    """Every named parameter is in bridge.yaml; its prior centre is the file's value.

    Except the support springs: as built they are absent (.inf, a rigid support) and their prior
    centre is the physically reasoned stiffness of the real support system (parameters.py).
    """
    params = load_bridge_config().params
    for name, p in PARAMETERS.items():
        assert name in params, name
        if name in MAY_BE_INFINITE:
            assert np.isinf(params[name]) and np.isfinite(p.centre)
        else:
            assert p.centre == params[name], name


def test_fractions_are_bounded_at_one_and_every_prior_has_a_source() -> None:
    for p in PARAMETERS.values():
        assert p.source and p.unit
        if p.kind == "fraction":
            assert p.upper == 1.0 and p.centre == 1.0 and p.high == 1.0
        assert p.low < p.centre <= p.high and p.plausible(p.centre)
