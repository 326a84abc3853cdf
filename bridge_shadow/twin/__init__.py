"""The synthetic truth twin: weather, sun, structure temperature, traffic, sensors, known effects.

``simulate`` returns ``MonitoringData`` (the three contract topics) and the truth; ``write_truth``
puts the truth next to a bag. ``clear_sky`` (re-exported from ``bridge_shadow.sun``) is the sun
covariate the gap diagnosis uses too. No ROS import. Names are imported lazily.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "DEFAULT_START",
    "DEFAULT_TEMP_RATE_HZ",
    "TRUTH_FILE",
    "TwinConfig",
    "clear_sky",
    "parse_effects",
    "read_truth",
    "simulate",
    "solar_elevation_deg",
    "validate_effects",
    "write_truth",
]

_WHERE = {
    "DEFAULT_START": "config",
    "TwinConfig": "config",
    "DEFAULT_TEMP_RATE_HZ": "simulate",
    "parse_effects": "simulate",
    "simulate": "simulate",
    "validate_effects": "simulate",
    "clear_sky": "bridge_shadow.sun",
    "solar_elevation_deg": "bridge_shadow.sun",
    "TRUTH_FILE": "truth",
    "read_truth": "truth",
    "write_truth": "truth",
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    where = _WHERE[name]
    module = where if "." in where else f"{__name__}.{where}"
    return getattr(importlib.import_module(module), name)
