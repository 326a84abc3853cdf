"""``BAG/truth.yaml``: the ground truth of a synthetic bag, for scoring only.

Nothing that estimates or diagnoses may read this file; ``read_truth`` exists for tests and
benchmarks that score the shadow and the gap diagnosis against the twin.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.errors import InputError
from bridge_shadow.fileio import load_yaml

__all__ = ["TRUTH_FILE", "read_truth", "truth_path", "truth_text", "write_truth"]

#: File name of the truth next to the bag's storage files.
TRUTH_FILE = "truth.yaml"

_HEADER = (
    "# Ground truth of a synthetic bag written by `bridge-shadow synth` (bridge_shadow.twin).\n"
    "# For scoring only: nothing that estimates or diagnoses may read this file.\n"
    "# Units: SI (m, N, s, C, K) where a key names none; `days`, the twin settings whose names end in _h,\n"
    "# _per_day or _per_hour, and the effects (their units in `effect_units`, the vocabulary of\n"
    "# `synth --effect`) are in the units their names give. Settlements positive upward [south, north].\n"
)


def _plain(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def truth_path(bag: str | Path) -> Path:
    """Path of the truth file of a bag directory."""
    return Path(bag) / TRUTH_FILE


def truth_text(truth: dict[str, Any]) -> str:
    """Return the text of ``truth.yaml`` for ``truth`` (without its ``series`` arrays)."""
    data = _plain({k: v for k, v in truth.items() if k != "series"})
    return _HEADER + yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=100)


def write_truth(bag: str | Path, truth: dict[str, Any]) -> Path:
    """Write ``truth`` (without its ``series`` arrays) to ``BAG/truth.yaml``; return the path."""
    from bridge_shadow.fileio import atomic_write_text

    return atomic_write_text(truth_path(bag), truth_text(truth), "truth file")


def read_truth(bag: str | Path) -> dict[str, Any]:
    """Read ``BAG/truth.yaml`` (scoring only; never from estimation or diagnosis code)."""
    file = truth_path(bag)
    if not file.is_file():
        raise InputError(f"{file}: no truth file (is this a bag written by `bridge-shadow synth`?)")
    try:
        data = load_yaml(file.read_text())
    except yaml.YAMLError as err:
        raise InputError(f"{file}: not valid YAML ({err})") from err
    if not isinstance(data, dict):
        raise InputError(f"{file}: not a truth file")
    return data
