"""The committed ``config/surrogate.yaml`` is current: regenerate it when bridge.yaml changes.

Fix a failure with ``bridge-shadow surrogate`` (default mesh, no overrides) and commit the file.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import yaml

from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.surrogate import SENSITIVITY_PARAMETERS, load_sensitivities, solve_bridge
from bridge_shadow.model.surrogate_file import THERMAL_CASES, load_surrogate


@pytest.fixture(scope="module")
def committed(root):
    path = root / "config" / "surrogate.yaml"
    assert path.is_file(), "config/surrogate.yaml missing: run `bridge-shadow surrogate`"
    return path


def test_surrogate_was_generated_from_the_current_bridge_yaml(committed, root):
    prov = yaml.safe_load(committed.read_text())["provenance"]
    sha = hashlib.sha256((root / "config" / "bridge.yaml").read_bytes()).hexdigest()
    assert prov["model_sha256"] == sha, (
        "config/bridge.yaml changed but config/surrogate.yaml was not regenerated: "
        "run `bridge-shadow surrogate` and commit config/surrogate.yaml"
    )
    assert prov["mesh"] == "default"
    assert prov["overrides"] == {}


def test_committed_surrogate_is_complete(committed):
    s = load_surrogate(committed)
    assert s.provenance["solver"].startswith("bridge_shadow.fe")  # not the closed-form placeholder
    assert set(s.thermal) == set(THERMAL_CASES)
    assert s.provenance["schur_check"]["max_rel_diff"] < 1e-8
    for key in (
        "model_sha256",
        "overrides",
        "mesh",
        "dofs",
        "elements",
        "solver",
        "seconds",
        "package_version",
    ):
        assert key in s.provenance
    sens = load_sensitivities(committed)
    assert set(SENSITIVITY_PARAMETERS) <= set(sens)
    assert load_surrogate().provenance == s.provenance  # the default location is this file


@pytest.mark.slow
def test_committed_numbers_reproduce_with_the_current_code(committed):
    s = load_surrogate(committed)
    sol = solve_bridge(load_bridge_config(), "default")
    np.testing.assert_allclose(sol.A, s.A, rtol=1e-6)
    np.testing.assert_allclose(sol.u0, s.u0, rtol=1e-6)
    for case in THERMAL_CASES:
        np.testing.assert_allclose(sol.thermal[case], s.thermal[case], rtol=1e-6, atol=1e-3)
