"""The twin's reality: a structure that may differ from the model the estimator uses.

By default the twin's reactions come from ``config/surrogate.yaml`` (the model the shadow uses too:
every check is then the model agreeing with itself). A reality of its own comes either

- from FE parameters (``synth --reality-set name=value``): one FE solve of ``config/bridge.yaml``
  with those overrides at synth time (``--reality-mesh coarse|default|fine``), with its stiffness
  sensitivities (adjoint, no extra solve); or
- from a surrogate file (``synth --reality-surrogate PATH``), e.g. ``config/surrogate_fe.yaml``.

The estimator keeps its own surrogate. The reality is recorded in ``truth.yaml`` (``reality``),
which is for scoring only.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bridge_shadow.errors import InputError
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = ["Reality", "reality_from_file", "reality_from_parameters"]


class Reality:
    """A surrogate, its sensitivities block and where they come from (``info``, for truth.yaml)."""

    def __init__(self, surrogate: Surrogate, block: dict[str, Any] | None, info: dict[str, Any]) -> None:
        self.surrogate = surrogate
        self.block = block
        self.info = info


def reality_from_parameters(
    overrides: Mapping[str, float],
    mesh: str = "default",
    model: str | Path | None = None,
    option: str = "--reality-set",
) -> Reality:
    """FE reality: ``bridge.yaml`` (or ``model``) with ``overrides`` solved at ``mesh`` (one solve).

    ``option``: the command-line option that gave ``overrides``, named in a range error.
    """
    from bridge_shadow.model.config import load_bridge_config
    from bridge_shadow.model.surrogate import compute_surrogate

    cfg = load_bridge_config(model, dict(overrides), option)
    cfg.mesh(mesh)
    run = compute_surrogate(cfg, mesh)
    info = {
        "source": "fe",
        "overrides": {k: float(v) for k, v in overrides.items()},
        "mesh": mesh,
        "model_sha256": cfg.sha256,
    }
    return Reality(run.surrogate, run.sensitivities, info)


def reality_from_file(path: str | Path) -> Reality:
    """Reality from a surrogate file (its ``sensitivities`` block too, when it has one)."""
    from bridge_shadow.twin.response import load_twin_surrogate

    file = Path(path)
    if not file.is_file():
        raise InputError(f"{file}: reality surrogate not found")
    surrogate, block = load_twin_surrogate(file)
    return Reality(surrogate, block, {"source": "file", "path": str(file)})
