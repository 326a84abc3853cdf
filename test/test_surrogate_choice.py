"""`replay --surrogate` picks the surrogate (default: the calibrated config/surrogate.yaml)."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np

from bridge_shadow.cli import main
from bridge_shadow.model.surrogate_file import load_surrogate


def _replay(argv: list[str]) -> dict:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(argv) == 0
    return json.loads(out.getvalue())


def test_replay_uses_the_calibrated_surrogate_unless_told_otherwise(root) -> None:
    bag = str(root / "bags" / "baseline_1d")
    fe = root / "config" / "surrogate_fe.yaml"
    default = _replay(["replay", bag, "--json"])
    chosen = _replay(["replay", bag, "--json", "--surrogate", str(fe)])
    np.testing.assert_allclose(default["surrogate"]["A"], load_surrogate().A, rtol=1e-12)
    np.testing.assert_allclose(chosen["surrogate"]["A"], load_surrogate(fe).A, rtol=1e-12)
    assert not np.allclose(default["posterior"]["mean_m"], chosen["posterior"]["mean_m"], rtol=1e-3)
