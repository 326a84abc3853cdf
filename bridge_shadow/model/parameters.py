"""Named FE parameters of the bridge model with their priors (no ROS import).

Every stiffness-like parameter of ``config/bridge.yaml`` (and the ones the real structure suggests,
which the FE model supports as overrides) has a prior taken from its source: a centre (the value
in ``bridge.yaml``, or the stated value for the added ones) and a plausible range. The prior is
normal in ``log(value)``: the range is its central 95 % interval, so

    sigma_log = log(high / low) / (2 * 1.96)

and the centre need not be the middle of the range (a prior median below or above the assumed
value is written as such). Fractions in (0, 1] (``kind == "fraction"``) have the same log-normal
prior, truncated at 1 (``upper`` bound): their centre is usually 1 ("as built") and the range says
how far below it the real structure may plausibly be.

Users: ``bridge-shadow calibrate`` (Bayesian updating), the gap diagnosis (bounds of the fitted
stiffness changes), and the truth twin (a reality that differs from the model).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from bridge_shadow.errors import ConfigError

__all__ = [
    "PARAMETERS",
    "Parameter",
    "log_bounds",
    "parameter",
]

#: z of the two-sided 95 % interval of a normal distribution.
_Z95 = 1.959963984540054


@dataclass(frozen=True)
class Parameter:
    """One named FE parameter and its prior.

    Attributes:
        name: the key under ``parameters`` in ``config/bridge.yaml`` (``--set name=value``).
        unit: SI unit of the value.
        centre: prior median (SI); usually the ``bridge.yaml`` value.
        low, high: plausible range (SI), the prior's central 95 % interval in log space.
        source: where the centre and the range come from (one sentence for people).
        kind: ``"stiffness"`` (any positive value) or ``"fraction"`` (in (0, 1], truncated at 1).
        upper: hard upper bound (SI) or None.

    """

    name: str
    unit: str
    centre: float
    low: float
    high: float
    source: str
    kind: str = "stiffness"
    upper: float | None = None

    def __post_init__(self) -> None:
        if not 0 < self.low < self.high:
            raise ConfigError(f"parameter {self.name}: need 0 < low < high")
        if not self.low <= self.centre <= self.high:
            raise ConfigError(f"parameter {self.name}: centre must lie in [low, high]")

    @property
    def log_centre(self) -> float:
        """Prior mean of ``log(value)``."""
        return math.log(self.centre)

    @property
    def log_sigma(self) -> float:
        """Prior standard deviation of ``log(value)`` (from the 95 % range)."""
        return math.log(self.high / self.low) / (2.0 * _Z95)

    def relative_bounds(self, value: float | None = None) -> tuple[float, float]:
        """Bounds of a relative change ``r`` (``k -> (1 + r) k``) around ``value`` (default centre).

        The plausible range ``[low, high]`` (clipped at ``upper``) expressed as ``r``; a fitted
        ``r`` outside it is implausible.
        """
        v = self.centre if value is None else float(value)
        hi = self.high if self.upper is None else min(self.high, self.upper)
        return self.low / v - 1.0, hi / v - 1.0

    def plausible(self, value: float) -> bool:
        """Whether ``value`` lies in the plausible range (and under the hard bound)."""
        hi = self.high if self.upper is None else min(self.high, self.upper)
        return self.low <= value <= hi


def _p(*args: object, **kw: object) -> Parameter:
    return Parameter(*args, **kw)  # type: ignore[arg-type]


#: The parameter table. Centres of the parameters in ``config/bridge.yaml`` are its values
#: (``test_model_parameters.py`` checks it), except the support springs: the as-built model has
#: none (``.inf``, a rigid support), and their prior centre here is the physically reasoned
#: stiffness of the real support system. ``slab_joint_opening`` is 1 in both (joints closed).
PARAMETERS: dict[str, Parameter] = {
    p.name: p
    for p in (
        _p(
            "bearing_stiffness", "N/m", 2.0e9, 3.0e8, 1.0e10,
            "500 kN-class load cell in series with steel plates and a spindle (bridge.yaml); "
            "range: an elastomeric pad (3e8) to a bare steel load cell (1e10)",
        ),
        _p(
            "support_spring_south", "N/m", 5.0e7, 5.0e6, 1.0e9,
            "support system under FRC-01 in series with the bearing (paper: 'a flexible central "
            "support system' for imposed settlements; no stiffness published): a jack's oil "
            "column ~2e8, a 1 m pad footing on medium soil ~1e8, timber/steel packing ~3e8, in "
            "series ~5e7; range: packing on soft soil (5e6) to a steel stack on concrete (1e9). "
            "Absent (rigid, .inf) in the as-built FE model",
        ),
        _p(
            "support_spring_north", "N/m", 5.0e7, 5.0e6, 1.0e9,
            "support system under FRC-02 in series with the bearing; as support_spring_south",
        ),
        _p(
            "end_bearing_stiffness", "N/m", 1.5e9, 2.0e8, 1.0e10,
            "elastomeric end bearing ~200 x 300 x 40 mm (bridge.yaml); range: soft pad to steel",
        ),
        _p(
            "fixed_bearing_stiffness", "N/m", 1.0e9, 1.0e8, 1.0e10,
            "horizontal restraint of a held bearing direction (bridge.yaml); one decade each way",
        ),
        _p(
            "connector_stiffness", "N/m/m", 1.6e9, 1.0e7, 1.0e10,
            "bolted girder-connector joint slip per metre, EN 1993-1-8 (bridge.yaml); range down "
            "to bolts slipping in oversized holes (1e7)",
        ),
        _p(
            "dowel_stiffness", "N/m/m", 5.0e9, 2.0e8, 2.0e10,
            "composite-dowel slip modulus per metre (bridge.yaml); range: damaged or cracked "
            "dowels (2e8) to stiff",
        ),
        _p(
            "composite_action", "1", 1.0, 0.05, 1.0,
            "degree of composite action (multiplies the longitudinal dowel stiffness); 1 = as "
            "built, range down to a slab nearly sliding on the girders",
            kind="fraction", upper=1.0,
        ),
        _p(
            "dowel_rotational_stiffness", "N m/rad/m", 1.0e8, 1.0e6, 1.0e10,
            "rotational embedding of the connector web in the slab (bridge.yaml); two decades each way",
        ),
        _p(
            "slab_joint_normal_stiffness", "N/m/m", 1.25e11, 1.0e8, 2.0e11,
            "mortar-filled joint 20 mm wide, E 10 GPa, t 0.25 m (bridge.yaml); range down to an "
            "open, unbonded joint (1e8)",
        ),
        _p(
            "slab_joint_shear_stiffness", "N/m/m", 5.0e10, 1.0e8, 1.0e11,
            "G t / w of the mortar joint (bridge.yaml); range down to a joint held by friction",
        ),
        _p(
            "slab_joint_rotational_stiffness", "N m/rad/m", 6.5e8, 1.0e5, 1.0e9,
            "E t^3 / (12 w) of the mortar joint (bridge.yaml); range down to an open joint",
        ),
        _p(
            "slab_joint_opening", "1", 1.0, 1.0e-4, 1.0,
            "fraction of the slab-joint normal and rotational stiffness kept by the joints over "
            "the hogging zone near the central support (tension opens mortar joints of precast "
            "segments); 1 = closed as built",
            kind="fraction", upper=1.0,
        ),
        _p(
            "E_concrete", "Pa", 3.4e10, 2.0e10, 4.5e10,
            "C35/45 short-term modulus, EN 1992-1-1 Table 3.1 (bridge.yaml); range C20/25 to C60/75",
        ),
    )
}


def parameter(name: str) -> Parameter:
    """Return the named parameter; ConfigError listing the known names otherwise."""
    try:
        return PARAMETERS[name]
    except KeyError:
        raise ConfigError(f"unknown model parameter {name!r}; known: {', '.join(PARAMETERS)}") from None


def log_bounds(names: Iterable[str]) -> tuple[list[float], list[float]]:
    """Lower and upper bounds of ``log(value)`` for ``names`` (hard bounds only: ``upper``)."""
    lo, hi = [], []
    for name in names:
        p = parameter(name)
        lo.append(-math.inf)
        hi.append(math.log(p.upper) if p.upper is not None else math.inf)
    return lo, hi
