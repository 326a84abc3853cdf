"""The gap tool's units: its JSON in SI (per-day and hour units converted), its text in mm and kN.

The vocabulary (``bridge_shadow.effects``) keeps the units people set and read a drift or a lag
in (``synth --effect settlement_drift=2e-4`` is 0.2 mm a day); the fit keeps them too (its
columns are scaled by them). What leaves the tool as JSON is SI (the contract): a fitted
``v_south [m/day]`` becomes ``v_south [m/s]``, a lag ``tau [h]`` becomes ``tau [s]``.
"""

from __future__ import annotations

from typing import Any

from bridge_shadow.timefmt import iso_utc

__all__ = ["PEOPLE_UNITS", "TO_SI", "param_text", "params_text", "si_params", "si_unit_value"]

#: A unit of the vocabulary that is not SI -> its SI unit and the factor into it.
TO_SI: dict[str, tuple[str, float]] = {
    "m/day": ("m/s", 1.0 / 86400.0),
    "N/day": ("N/s", 1.0 / 86400.0),
    "h": ("s", 3600.0),
}


def si_unit_value(unit: str, value: Any) -> tuple[str, Any]:
    """Return ``(unit, value)`` in SI (a number, a list of numbers or None converted; others as they are)."""
    if unit not in TO_SI:
        return unit, value
    si, factor = TO_SI[unit]
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


#: A fitted parameter's SI unit (its JSON key's ``[unit]``) -> the text's unit and factor.
PEOPLE_UNITS: dict[str, tuple[str, float]] = {
    "m": ("mm", 1e3),
    "m/s": ("mm/day", 86400e3),
    "N/s": ("kN/day", 86.4),
    "N/K": ("kN/K", 1e-3),
    "N/m": ("kN/mm", 1e-6),
    "N/m/m": ("kN/mm per m", 1e-6),
    "m/N": ("mm/kN", 1e6),
    "K": ("K", 1.0),
    "s": ("h", 1.0 / 3600.0),
}


def param_text(key: str, value: float) -> str:
    """``v_south -0.2002 mm/day``: a fitted value in the units the text uses (kN, mm); 1 bare."""
    name, _, unit = key.partition(" [")
    shown, factor = PEOPLE_UNITS.get(unit.rstrip("]"), ("", 1.0))
    return f"{name} {factor * value:.4g}" + (f" {shown}" if shown else "")


def params_text(params: dict[str, Any]) -> str:
    """Fitted parameters (SI keys) as text for people: ``x_south 0.7 mm, k_north rigid, at ...``."""
    parts = []
    for k, v in params.items():
        if k == "steps":
            if len(v) > 1:
                parts.append(f"{len(v)} steps (levels below)")
            continue
        if isinstance(v, float):
            parts.append(param_text(k, v))
        elif v is None:
            parts.append(f"{k.split(' ')[0]} rigid")
        elif k == "at [ns]":
            parts.append(f"at {iso_utc(int(v))}")
        else:
            parts.append(f"{k.split(' ')[0]} {v}")
    return ", ".join(parts)
