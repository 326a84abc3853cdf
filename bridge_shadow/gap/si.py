"""The gap tool's machine output in SI: the effect vocabulary's per-day and hour units converted.

The vocabulary (``bridge_shadow.effects``) keeps the units people set and read a drift or a lag
in (``synth --effect settlement_drift=2e-4`` is 0.2 mm a day); the fit keeps them too (its
columns are scaled by them). What leaves the tool as JSON is SI (the contract): a fitted
``v_south [m/day]`` becomes ``v_south [m/s]``, a lag ``tau [h]`` becomes ``tau [s]``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["TO_SI", "si_params", "si_unit_value"]

#: A unit of the vocabulary that is not SI -> its SI unit and the factor into it.
TO_SI: dict[str, tuple[str, float]] = {
    "m/day": ("m/s", 1.0 / 86400.0),
    "N/day": ("N/s", 1.0 / 86400.0),
    "h": ("s", 3600.0),
}


def si_unit_value(unit: str, value: Any) -> tuple[str, Any]:
    """Return ``(unit, value)`` in SI (a number, a list of numbers or None converted; others as they are)."""
    si, factor = TO_SI.get(unit, (unit, 1.0))
    if factor == 1.0:
        return unit, value
    return si, _scaled(value, factor)


def _scaled(value: Any, factor: float) -> Any:
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, (int, float)):
        return float(value) * factor
    if isinstance(value, (list, tuple)):
        return [_scaled(v, factor) for v in value]
    return value


def si_params(params: dict[str, Any]) -> dict[str, Any]:
    """Return fitted parameters keyed ``name [unit]`` with every non-SI unit converted (key and value)."""
    out: dict[str, Any] = {}
    for key, value in params.items():
        name, bracket, rest = key.partition(" [")
        unit = rest[:-1] if bracket and rest.endswith("]") else ""
        if unit in TO_SI:
            si, converted = si_unit_value(unit, value)
            out[f"{name} [{si}]"] = converted
        else:
            out[key] = value
    return out
