"""The vocabulary of unmodelled effects (DESIGN section 6), shared by the truth twin and the gap.

The twin (``bridge_shadow.twin``) injects an effect with ``--effect NAME=MAGNITUDE`` using the
generative meaning below; the gap diagnosis (``bridge_shadow.gap``) must find it from the data with
candidate models of its own, never reading the twin's ground-truth file. Both read this table for the
names, the unit of the magnitude, and the magnitudes used in tests: ``realistic`` (a clear case) and
``edge`` (about the edge of detectability in three days of 60 s windows).

The *baseline model* against which a gap is measured is the FE model as built: central reactions
``u0 + A x`` with ``x = 0`` (the prior mean; or the known imposed settlement, ``gap --imposed``)
plus the FE ``uniform`` thermal sensitivity times the air temperature change. A clean twin bag (no
effect) is that baseline plus sensor noise (AR(1)), dropouts and NaNs, so its diagnosis must be
``none``.

Every fitted parameter of the diagnosis has a plausible range (``plausible_range``): for the
stiffness effects the plausible range of the FE parameter (``bridge_shadow.model.parameters``), for
the others the physically reasoned ``Effect.plausible`` below. A fit outside it is rejected as
implausible, never reported as present.

Model-form effects (``bearing_stiffness``, ``connector_stiffness``, ``support_spring``,
``slab_joint_opening``) change the surrogate itself, the settlement response ``A x`` as well as
``u0`` and the thermal and traffic responses; ``bridge_shadow.model.sensitivities.change_surrogate``
is the one implementation of that change, used by the twin and the diagnosis alike.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "EFFECTS",
    "EFFECT_NAMES",
    "MODEL_FORM_EFFECTS",
    "SETTLEMENT_EFFECTS",
    "Effect",
    "format_support_springs",
    "parse_support_springs",
    "plausible_range",
]


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
        plausible: plausible range of each fitted linear parameter of the diagnosis's candidate
            (its unit is in the candidate's parameter name), or None where the range comes from
            the FE parameter priors (the model-form effects, see ``plausible_range``).
        plausible_source: why that range (one sentence for people).

    """

    name: str
    unit: str
    realistic: float
    edge: float
    part: str
    meaning: str
    plausible: tuple[float, float] | None = None
    plausible_source: str = ""


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "settlement_offset",
            "m",
            7e-4,
            5e-5,
            "structural",
            "constant differential settlement x = [+v, -v] (south up, north down), as the paper "
            "found (+0.7 / -0.7 mm); reactions change by A x",
            (-0.05, 0.05),
            "+-50 mm per bearing: the central reactions vanish at about -42 mm (A^-1 u0, common mode) "
            "and double at +42 mm; the temporary bearings are adjusted over that order",
        ),
        Effect(
            "settlement_drift",
            "m/day",
            2e-4,
            1.5e-5,
            "structural",
            "the south central support sinks linearly, x_south(t) = -v t (t in days from the start), "
            "as under scour; reactions change by A x(t)",
            (-0.01, 0.01),
            "+-10 mm a day: scour and consolidation are orders of magnitude slower; faster movements "
            "are steps",
        ),
        Effect(
            "settlement_step",
            "m",
            -1e-3,
            -5e-5,
            "structural",
            "both central supports move by v (positive upward) at the middle of the record, as when the "
            "supports are lowered; reactions change by A [v, v] from then on (the diagnosis fits any "
            "step [v_s, v_n] at a record gap or a change point it finds)",
            (-0.05, 0.05),
            "+-50 mm per bearing, as settlement_offset",
        ),
        Effect(
            "uniform_temperature",
            "N/K",
            300.0,
            15.0,
            "thermal",
            "partially restrained longitudinal movement (bearing friction): both central reactions "
            "change by c (T_struct - T_ref), T_struct the uniform structure temperature (follows the "
            "air with the thermal lag, if on), T_ref the mean air temperature",
            (-5000.0, 5000.0),
            "+-5 kN/K: two thirds of the FE response to 1 K of vertical gradient (7.6 kN/K), which "
            "only a fully restrained longitudinal movement would reach; friction gives hundreds",
        ),
        Effect(
            "vertical_gradient",
            "K",
            4.0,
            0.3,
            "thermal",
            "sun-driven top-warmer gradient over the girder depth: dT_v(t) = g * sun(t) * clearness(day), "
            "sun the clear-sky irradiance at Neubiberg normalized to its peak (0..1); reactions change "
            "by thermal['vertical_gradient'] * dT_v",
            (-3.0, 13.5),
            "EN 1991-1-5 6.1.4.1, Table 6.1: linear temperature difference of a type 2 (composite) "
            "deck, top warmer 15 K (bottom warmer 18 K), times k_sur = 0.9 of Table 6.2 for an "
            "unsurfaced deck (the bare precast slab): 13.5 K in full sun; the sun drives only the "
            "top-warmer part, a top cooler in the sun only as noise (-3 K)",
        ),
        Effect(
            "transverse_gradient",
            "K",
            3.0,
            0.3,
            "thermal",
            "sun-driven south-north difference (south girder warmer): dT_t(t) = g * sun(t) * "
            "clearness(day); reactions change by thermal['transverse_gradient'] * dT_t",
            (-3.0, 15.0),
            "the southern girder takes the sun, the northern one lies in shade: up to about 15 K "
            "between them; a warmer north girder in sunshine only as noise (-3 K)",
        ),
        Effect(
            "thermal_lag",
            "h",
            3.0,
            0.5,
            "thermal",
            "the structure's bulk temperature lags the air (first order, time constant tau hours); the "
            "deck surface follows the air, so a vertical gradient dT_v = T_air - T_bulk appears and the "
            "reactions change by thermal['vertical_gradient'] * dT_v",
            (0.0, 3.0),
            "scale of the gradient T_air - T_lagged on the FE vertical-gradient case: 1 is the full "
            "difference over the depth (the twin's meaning), 0 none; up to 3 for a stiffer FE case; "
            "tau lies on the 0.25-8 h grid",
        ),
        Effect(
            "bearing_stiffness",
            "1",
            -0.5,
            -0.1,
            "structural",
            "relative change r of the central bearings' vertical stiffness (k -> (1 + r) k): changes A, "
            "u0 and the thermal and traffic responses by the FE sensitivities, first order in r "
            "(surrogate 'sensitivities' block, or the closed-form placeholder)",
            None,
            "plausible range of the FE parameter bearing_stiffness (model.parameters), as r",
        ),
        Effect(
            "connector_stiffness",
            "1",
            -0.5,
            -0.1,
            "structural",
            "relative change r of the girder-slab connector (composite action) stiffness: changes A, u0 "
            "and the thermal and traffic responses by the FE sensitivities, first order in r",
            None,
            "plausible range of the FE parameter connector_stiffness (model.parameters), as r",
        ),
        Effect(
            "support_spring",
            "N/m",
            2.0e7,
            1.0e9,
            "structural",
            "a support system (trestle, jack, foundation) of stiffness k in series with each central "
            "bearing (a number: both bearings; 'south:K' or 'north:K': one; 'KS,KN': each its own). "
            "Exact closed form: A' = (A^-1 + diag(1/k_s, 1/k_n))^-1, and u0, the thermal cases and "
            "the traffic reactions map through A' A^-1 (the dead load also compresses the spring). The "
            "diagnosis also tries a support levelled under the dead load (u0 kept, only changes map)",
            None,
            "plausible range of support_spring_south/north (model.parameters, the range calibrate "
            "uses too); stiffer than its upper end is indistinguishable from the rigid support of "
            "the as-built model",
        ),
        Effect(
            "slab_joint_opening",
            "1",
            0.1,
            0.7,
            "structural",
            "fraction f of the slab-joint stiffness kept over the hogging zone near the central support "
            "(1 = closed, as built): changes A, u0 and the thermal and traffic responses by the "
            "sensitivity per unit relative change (surrogate block, or the closed-form placeholder: "
            "bare steel girders over the hogging zone at f = 0), linear in r = f - 1",
            None,
            "plausible range of the FE parameter slab_joint_opening (model.parameters), as r = f - 1",
        ),
        Effect(
            "sensor_drift",
            "N/day",
            300.0,
            20.0,
            "sensor",
            "the north load cell (FRC-02) drifts linearly by d N per day from the start of the record; "
            "the south one does not",
            (-5000.0, 5000.0),
            "+-5 kN a day (2 % of the reading): a cell drifting faster has failed outright",
        ),
        Effect(
            "traffic",
            "N",
            2.5e4,
            3.0e3,
            "load",
            "test-car crossings of weight W (N) during daytime (about 6 per hour, 08-18 local time), "
            "each lasting about 10 s, loading both central bearings by the two-span influence line",
            (-0.5, 2.0),
            "share of the summed window excess of a crossing that one bearing takes: 0..1 (about "
            "0.5 each by the lane position), with a margin for noise",
        ),
    )
}

#: The settlement effects: what the shadow itself estimates (never added to the model "after").
SETTLEMENT_EFFECTS: tuple[str, ...] = ("settlement_offset", "settlement_step", "settlement_drift")
#: Effects that change the surrogate (A, u0, thermal) rather than add a term to the reactions.
MODEL_FORM_EFFECTS: tuple[str, ...] = (
    "bearing_stiffness",
    "connector_stiffness",
    "support_spring",
    "slab_joint_opening",
)

#: Names in vocabulary order.
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)


def plausible_range(name: str) -> tuple[float, float]:
    """Plausible range of each fitted linear parameter of effect ``name`` (SI).

    ``bearing_stiffness`` and ``connector_stiffness``: the relative change ``r`` over the FE
    parameter's plausible range (``Parameter.relative_bounds``); ``slab_joint_opening``: ``r = f - 1``
    over the plausible range of the fraction ``f`` kept; ``support_spring``: the spring stiffness in
    N/m (``support_spring_south``'s plausible range; the north one has the same). These are the
    ranges of the one table ``bridge_shadow.model.parameters`` that ``calibrate`` keeps its fits
    in too. The others: ``Effect.plausible``.
    """
    from bridge_shadow.model.parameters import PARAMETERS

    if name in ("bearing_stiffness", "connector_stiffness", "slab_joint_opening"):
        return PARAMETERS[name].relative_bounds()
    if name == "support_spring":
        return PARAMETERS["support_spring_south"].bounds
    rng = EFFECTS[name].plausible
    if rng is None:  # pragma: no cover - every other effect states its range
        raise KeyError(name)
    return rng


def parse_support_springs(value: object) -> tuple[float, float]:
    """Spring stiffness [south, north] in N/m (``inf``: rigid) from an ``--effect support_spring`` value.

    Accepts a number (both bearings), ``"south:K"``, ``"north:K"`` or ``"KS,KN"``. Raises
    ValueError for anything else or a stiffness that is not positive.
    """
    text = str(value).strip()
    side, sep, rest = text.partition(":")
    if sep:
        k = float(rest)
        if side.strip() == "south":
            out = (k, float("inf"))
        elif side.strip() == "north":
            out = (float("inf"), k)
        else:
            raise ValueError(f"support_spring {text!r}: the side must be south or north")
    elif "," in text:
        ks, kn = (float(v) for v in text.split(","))
        out = (ks, kn)
    else:
        k = float(text)
        out = (k, k)
    if not all(k > 0 for k in out):
        raise ValueError(f"support_spring {text!r}: the stiffness must be positive (N/m)")
    return out


def format_support_springs(springs: tuple[float, float]) -> float | str:
    """Canonical ``--effect support_spring`` value: a float for both bearings alike, else a string."""
    ks, kn = (float(k) for k in springs)
    if ks == kn:
        return ks
    if kn == float("inf"):
        return f"south:{ks:g}"
    if ks == float("inf"):
        return f"north:{kn:g}"
    return f"{ks:g},{kn:g}"
