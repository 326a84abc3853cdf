"""Calibration of the FE model on records with a known imposed settlement (no ROS import).

The paper updates the settlements given the model; this updates the model given a known settlement.
One idea per module:

- ``records``: read a record (bag, or munich-bridge-data CSV/zip files);
- ``car``: the test car (crossings and parked plateaus) in a short record;
- ``change``: the measured reaction change of a record pair and its covariance;
- ``forward``: named FE parameters -> surrogate and its derivatives (support springs in closed form);
- ``problem``: whitened residuals of the measured changes and the priors;
- ``lm``: projected Levenberg-Marquardt; ``posterior``: Laplace posterior and evidence at bounds;
- ``identifiability``: which parameter combinations the data fix;
- ``explain``: one candidate explanation (fit, evidence, what it implies);
- ``spec``: the calibration file; ``run``: the whole calibration; ``report``: text and figures.

``bridge-shadow calibrate`` (``commands/calibrate.py``) is the command line. Names are imported
lazily.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "CalibrationError",
    "CalibrationResult",
    "CalibrationSpec",
    "calibrate",
    "load_spec",
    "spec_from_dict",
]

_WHERE = {
    "CalibrationError": "errors",
    "CalibrationResult": "run",
    "calibrate": "run",
    "CalibrationSpec": "spec",
    "load_spec": "spec",
    "spec_from_dict": "spec",
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
