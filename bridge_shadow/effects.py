"""The vocabulary of unmodelled effects (DESIGN section 6), shared by the truth twin and the gap.

The twin (``bridge_shadow.twin``) injects an effect with ``--effect NAME=MAGNITUDE`` using the
generative meaning below; the gap diagnosis (``bridge_shadow.gap``) must find it from the data with
candidate models of its own, never reading the twin's ground-truth file. Both read this table for the
names, the unit of the magnitude, and the magnitudes used in tests: ``realistic`` (a clear case) and
``edge`` (about the edge of detectability in three days of 60 s windows).

The *baseline model* against which a gap is measured is the FE model as built: central reactions
``u0 + A x`` with ``x = 0`` (the prior mean) plus the FE ``uniform`` thermal sensitivity times the
air temperature change. A clean twin bag (no effect) is that baseline plus sensor noise (AR(1)),
dropouts and NaNs, so its diagnosis must be ``none``.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["EFFECTS", "EFFECT_NAMES", "Effect"]


@dataclass(frozen=True)
class Effect:
    """One named unmodelled effect.

    Attributes:
        name: the vocabulary name (DESIGN section 6).
        unit: unit of the magnitude given as ``--effect name=value`` (SI).
        realistic: a clearly present magnitude for tests and demos.
        edge: a magnitude near the edge of detectability (3 days, 60 s windows).
        part: model part it belongs to: ``structural``, ``thermal``, ``sensor`` or ``load``.
        meaning: what the twin does with the magnitude (its generative definition).

    """

    name: str
    unit: str
    realistic: float
    edge: float
    part: str
    meaning: str


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "settlement_offset", "m", 7e-4, 5e-5, "structural",
            "constant differential settlement x = [+v, -v] (south up, north down), as the paper "
            "found (+0.7 / -0.7 mm); reactions change by A x",
        ),
        Effect(
            "settlement_drift", "m/day", 2e-4, 1.5e-5, "structural",
            "the south central support sinks linearly, x_south(t) = -v t (t in days from the start), "
            "as under scour; reactions change by A x(t)",
        ),
        Effect(
            "uniform_temperature", "N/K", 300.0, 15.0, "thermal",
            "partially restrained longitudinal movement (bearing friction): both central reactions "
            "change by c (T_struct - T_ref), T_struct the uniform structure temperature (follows the "
            "air with the thermal lag, if on), T_ref the mean air temperature",
        ),
        Effect(
            "vertical_gradient", "K", 4.0, 0.3, "thermal",
            "sun-driven top-warmer gradient over the girder depth: dT_v(t) = g * sun(t) * clearness(day), "
            "sun the clear-sky irradiance at Neubiberg normalized to its peak (0..1); reactions change "
            "by thermal['vertical_gradient'] * dT_v",
        ),
        Effect(
            "transverse_gradient", "K", 3.0, 0.3, "thermal",
            "sun-driven south-north difference (south girder warmer): dT_t(t) = g * sun(t) * "
            "clearness(day); reactions change by thermal['transverse_gradient'] * dT_t",
        ),
        Effect(
            "thermal_lag", "h", 3.0, 0.5, "thermal",
            "the structure's bulk temperature lags the air (first order, time constant tau hours); the "
            "deck surface follows the air, so a vertical gradient dT_v = T_air - T_bulk appears and the "
            "reactions change by thermal['vertical_gradient'] * dT_v",
        ),
        Effect(
            "bearing_stiffness", "1", -0.5, -0.1, "structural",
            "relative change r of the central bearings' vertical stiffness (k -> (1 + r) k): changes A, "
            "u0 and the thermal and traffic responses by the FE sensitivities (surrogate "
            "'sensitivities' block, or the closed-form placeholder)",
        ),
        Effect(
            "connector_stiffness", "1", -0.5, -0.1, "structural",
            "relative change r of the girder-slab connector (composite action) stiffness: changes A, u0 "
            "and the thermal and traffic responses by the FE sensitivities",
        ),
        Effect(
            "sensor_drift", "N/day", 300.0, 20.0, "sensor",
            "the north load cell (FRC-02) drifts linearly by d N per day from the start of the record; "
            "the south one does not",
        ),
        Effect(
            "traffic", "N", 2.5e4, 3.0e3, "load",
            "test-car crossings of weight W (N) during daytime (about 6 per hour, 08-18 local time), "
            "each lasting about 10 s, loading both central bearings by the two-span influence line",
        ),
    )
}

#: Names in vocabulary order.
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)
