"""The candidate library: a spatial signature on the two reactions times a temporal driver.

Each candidate maps its linear parameters to a reaction change ``(n, 2)`` N through a design
array ``X: (n, 2, p)`` (the change per unit of each parameter), optionally for each value of one
nonlinear parameter on a grid (the thermal lag, the drifting channel). Signatures come from the
surrogate: the columns of ``A`` (settlements), the thermal load cases, and the model-form changes
of :mod:`bridge_shadow.model.sensitivities`.

Model-form candidates change the whole response of the baseline model
``B(t) = u0 + A x_k(t) + thermal_uniform dT(t)``, where ``x_k`` is the settlement known
independently of the reactions (an imposed one, ``gap --imposed``; zero otherwise):

- ``bearing_stiffness``, ``connector_stiffness``, ``slab_joint_opening``: linear in the relative
  change ``r``: with the surrogate file's parameter sweeps (``model.sweeps``) the *secant* from the
  built value to each solved value ``v_g`` (``r_g = v_g / v_0 - 1``) is one grid alternative,
  ``(dA x_k + du0 + dthermal_uniform dT) / r_g`` with ``dA``, ``du0``, ``dthermal`` the exact FE
  changes, so a fit near ``r_g`` is the FE's own response however far from the built value;
  without sweeps the tangent (FE sensitivities of the file, else the closed-form placeholder),
  which holds near the built value only;
- ``support_spring``: exact, ``(M(C) - I) B(t)`` with ``M = (I + A C)^-1`` and
  ``C = diag(1/k_s, 1/k_n)``, a discrete choice of the bearing (south, north or both) and of the
  support's dead-load state (``loaded``: the spring carries the dead load from the nominal level,
  so ``u0`` maps through ``M`` too, as the twin injects it; ``levelled``: the support was set to
  the design level under the dead load, so ``u0`` stays and only changes map, ``(M - I)(B - u0)``),
  and the compliances fitted by bounded nonlinear least squares (:mod:`bridge_shadow.gap.spring`).
  Its ``design`` gives the linearization at ``C = 0``, used for the chance level.

``settlement_step`` is a step of the settlements at one of a few times found from the data
(``step_times``: the gaps between records and the strongest change points of the residual).

Why not the shadow's own settlement for ``x_k``: the shadow computes ``x`` from the same two
reactions through the as-built ``A``, so for any stiffness change ``A'`` the settlement
``A'^-1 A x`` reproduces the reactions exactly; ``dA x`` with that ``x`` only rescales the
settlement and cannot be told from it. A stiffness change shows where the settlement is known
(an imposed lowering) or through ``u0`` and the thermal response.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.effects import EFFECTS, plausible_range
from bridge_shadow.errors import ConfigError
from bridge_shadow.gap.drivers import Drivers
from bridge_shadow.model.parameters import PARAMETERS
from bridge_shadow.model.sensitivities import StiffnessSensitivity, read_sensitivities_block
from bridge_shadow.model.sensitivities import stiffness_sensitivities as _stiffness_sensitivities
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = [
    "CANDIDATES",
    "SPRING_CHOICES",
    "Candidate",
    "Context",
    "Sensitivity",
    "spring_bearings",
    "spring_load",
    "step_times",
    "stiffness_sensitivities",
]

#: Thermal-lag grid in hours (0.25 h to 8 h, about geometric). Longer lags are left out on purpose:
#: ``T - lag(T)`` with a lag of days becomes ``T - mean(T)``, the uniform-temperature driver.
LAG_GRID_H: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)
#: Which central bearing stands on a support spring, and whether the spring carries the dead load
#: from the nominal level (loaded) or was levelled under it (the discrete choice of ``support_spring``).
SPRING_CHOICES: tuple[str, ...] = (
    "south",
    "north",
    "both",
    "south levelled",
    "north levelled",
    "both levelled",
)
#: Change points of the residual tried as step times, besides the gaps between records.
STEP_CHANGE_POINTS = 3
#: A gap of more windows than this between two windows with data is a gap between records.
STEP_GAP_WINDOWS = 5
#: Step times closer than this many windows, or than ``STEP_MIN_SHARE`` of the record, to another
#: or to the ends are not tried (a step near an end is an offset).
STEP_MIN_WINDOWS = 10
STEP_MIN_SHARE = 0.05


#: Largest relative change the first-order tangent of a stiffness candidate may take beside the
#: sweep's secants: at |r| = 0.5 the tangents of bearing, connector and slab joint differ from the
#: FE sweeps by up to about a third (a 2e9 N/m bearing halved: A changes by 1.79 kN/mm, its tangent
#: says 1.42); beyond, the secants carry the fit.
FIRST_ORDER_MAX_R = 0.5
#: How far along its own line a secant of the sweep is used, as a multiple of its ``r_g``: up to
#: twice the solved change (the next solved value lies within a factor of about 7 in the
#: parameter, so twice the change stays inside the interval the secant spans or just beyond it).
SECANT_REACH = 2.0

#: The stiffness sensitivity type (one implementation in :mod:`bridge_shadow.model.sensitivities`).
Sensitivity = StiffnessSensitivity


def stiffness_sensitivities(s: Surrogate, path: str | Path | None = None) -> dict[str, Sensitivity]:
    """First-order sensitivities from the surrogate's ``sensitivities`` block, else the placeholder.

    The block (written by ``bridge-shadow surrogate``, see :mod:`bridge_shadow.model.sensitivities`)
    is read from the ``Surrogate`` attribute ``sensitivities`` when present, or else from the YAML
    file ``path`` (default ``config/surrogate.yaml``); an unreadable file counts as no block.
    """
    block: Any = getattr(s, "sensitivities", None)
    if block is None:
        try:
            block = read_sensitivities_block(path)
        except ConfigError:
            block = None
    return _stiffness_sensitivities(s, block if isinstance(block, dict) else None)


@dataclass
class Context:
    """What a candidate's design needs.

    Attributes:
        drivers: the temporal drivers (n windows).
        surrogate: the model as built.
        sensitivities: first-order sensitivities by parameter name.
        x_known: (n, 2) m, settlement known independently of the reactions (imposed), else 0.
        baseline: (n, 2) N, ``u0 + A x_known + thermal_uniform dT``.
        t_ns: (n,) window centres, ns.
        width_s: window length, s.
        step_times: window-boundary times (ns) tried by ``settlement_step``.
        sweeps: parameter -> its sweep (``model.sweeps``; empty: first-order designs only).

    """

    drivers: Drivers
    surrogate: Surrogate
    sensitivities: dict[str, Sensitivity]
    x_known: np.ndarray
    baseline: np.ndarray
    t_ns: np.ndarray | None = None
    width_s: float = 60.0
    step_times: tuple[int, ...] = ()
    sweeps: dict[str, Any] = field(default_factory=dict)

    def secant_grid(self, name: str) -> tuple[Any, ...]:
        """Return the tangent (None) and the relative change ``r_g`` of each solved value of the sweep."""
        sw = self.sweeps.get(name)
        if sw is None:
            return (None,)
        r = sw.values / sw.built - 1.0
        return (None, *(float(v) for v in r if abs(v) > 1e-9))

    @classmethod
    def build(
        cls,
        drivers: Drivers,
        surrogate: Surrogate,
        sensitivities: dict[str, Sensitivity],
        x_known: np.ndarray | None = None,
        t_ns: np.ndarray | None = None,
        width_s: float = 60.0,
    ) -> Context:
        """Context with the baseline computed from the surrogate and ``x_known`` (default 0)."""
        n = len(drivers)
        x = np.zeros((n, 2)) if x_known is None else np.asarray(x_known, float).reshape(n, 2)
        uniform = surrogate.thermal.get("uniform", np.zeros(2))
        baseline = surrogate.u0[None, :] + x @ surrogate.A.T + drivers.dtemp_k[:, None] * uniform[None, :]
        return cls(drivers, surrogate, sensitivities, x, baseline, t_ns, width_s)

    def step_share(self, when_ns: int) -> np.ndarray:
        """(n,) share of each window after a step at ``when_ns`` (0 before, 1 after)."""
        if self.t_ns is None:
            raise ValueError("the context has no window times")
        half = 0.5 * self.width_s * 1e9
        return np.clip((self.t_ns + half - when_ns) / (2.0 * half), 0.0, 1.0)


Design = Callable[[Context, Any], np.ndarray]
Bounds = Callable[[Context], list[tuple[float, float]]]


@dataclass(frozen=True)
class Candidate:
    """One candidate effect of the vocabulary.

    Attributes:
        name: vocabulary name (``bridge_shadow.effects``).
        params: names of the linear parameters, with their SI unit in brackets.
        design: ``(ctx, g) -> X (n, 2, p)``, the reaction change in N per unit of each parameter
            (for ``nonlinear`` candidates: its linearization at no change).
        grid: values of the nonlinear parameter (``(None,)`` when there is none).
        grid_name: name of the nonlinear parameter.
        magnitude: ``(params, g) -> float``, the fitted value in the vocabulary's magnitude unit
            (or ``magnitude_unit``).
        magnitude_unit: the magnitude's unit where it is not the vocabulary's (the twin's
            ``traffic`` is a vehicle's weight in N; the candidate fits the bearings' shares).
        discrete: the grid is a discrete choice (penalized by ``2 log K``).
        bounds: ``ctx -> [(low, high)]`` per linear parameter: its plausible range.
        nonlinear: fitted by :mod:`bridge_shadow.gap.spring` instead of linear least squares.
        data_grid: the grid comes from the record (``ctx.step_times``), not ``grid``.
        secant_grid: the grid is the relative change of each solved value of the parameter's
            sweep (``ctx.secant_grid``), when the surrogate has one.

    """

    name: str
    params: tuple[str, ...]
    design: Design
    grid: tuple[Any, ...] = (None,)
    grid_name: str | None = None
    magnitude: Callable[[np.ndarray, Any], float] | None = None
    magnitude_unit: str | None = None
    discrete: bool = False
    bounds: Bounds | None = None
    nonlinear: bool = False
    data_grid: bool = False
    secant_grid: bool = False

    def grid_of(self, ctx: Context) -> tuple[Any, ...]:
        """Return the grid of the nonlinear parameter for this record."""
        if self.data_grid:
            return ctx.step_times or (None,)
        if self.secant_grid:
            return ctx.secant_grid(self.name)
        return self.grid

    @property
    def part(self) -> str:
        """Model part: structural, thermal, sensor or load."""
        return EFFECTS[self.name].part

    @property
    def n_params(self) -> int:
        """Number of fitted parameters (linear ones plus the grid parameter)."""
        return len(self.params) + (self.grid_name is not None)

    def penalty(self, n_eff: float, n_grid: int | None = None) -> float:
        """BIC penalty in ``-2 log L`` units.

        ``log n_eff`` per continuous parameter, ``2 log K`` for a choice among ``K`` discrete
        alternatives (the drifting channel, the bearing on a spring, the step time).
        """
        pen = len(self.params) * np.log(n_eff)
        if self.secant_grid and (n_grid or 1) > 1:  # which secant: a discrete choice
            return float(pen + 2.0 * np.log(n_grid or 1))
        if self.grid_name is not None:
            k = len(self.grid) if n_grid is None else n_grid
            pen += 2.0 * np.log(max(k, 1)) if self.discrete else np.log(n_eff)
        return float(pen)

    def alternative_caps(self, ctx: Context) -> list[tuple[float, float] | None] | None:
        """Per grid alternative the range of ``r`` it describes: where its design is the FE's response.

        The tangent (None) holds near the built value, ``|r| <= FIRST_ORDER_MAX_R``; the secant to
        ``r_g`` between the built value and ``r_g`` and as far again (``SECANT_REACH``), so that a
        secant near the built value does not act as a tangent stretched over decades.
        """
        if not self.secant_grid or len(self.grid_of(ctx)) < 2:
            return None
        caps: list[tuple[float, float] | None] = []
        for g in self.grid_of(ctx):
            if g is None:
                caps.append((-FIRST_ORDER_MAX_R, FIRST_ORDER_MAX_R))
            else:
                caps.append((min(0.0, SECANT_REACH * g), max(0.0, SECANT_REACH * g)))
        return caps

    def plausible_bounds(self, ctx: Context) -> list[tuple[float, float]]:
        """Plausible range per linear parameter (SI); unbounded when the candidate states none."""
        if self.bounds is not None:
            return self.bounds(ctx)
        return [(-np.inf, np.inf)] * len(self.params)


def _const(ctx: Context, vec: np.ndarray, driver: np.ndarray) -> np.ndarray:
    return driver[:, None, None] * np.asarray(vec, float)[None, :, None]


def _settle_offset(ctx: Context, _: Any) -> np.ndarray:
    n = len(ctx.drivers)
    return np.broadcast_to(ctx.surrogate.A[None, :, :], (n, 2, 2)).copy()


def _settle_step(ctx: Context, when_ns: Any) -> np.ndarray:
    if when_ns is None:
        return np.zeros((len(ctx.drivers), 2, 2))
    return ctx.step_share(int(when_ns))[:, None, None] * ctx.surrogate.A[None, :, :]


def step_times(t_ns: np.ndarray, resid: np.ndarray, valid: np.ndarray, width_s: float) -> tuple[int, ...]:
    """Window-boundary times (ns) where a settlement step is tried.

    The start of the first window after every gap of more than ``STEP_GAP_WINDOWS`` windows
    without data (a gap between records), and the ``STEP_CHANGE_POINTS`` strongest change points
    of the residual: the splits into two constant levels, both channels together, that remove the
    most squared residual (``n1 n2 / n (mean1 - mean2)^2`` summed over the channels), at least
    ``STEP_MIN_WINDOWS`` windows from each other and from the ends. The change points are chosen
    on the whole record (the held-out check then fits the step on the training days only).
    """
    half = round(0.5 * width_s * 1e9)
    have = np.flatnonzero(valid.all(axis=1))
    n = len(have)
    sep = max(STEP_MIN_WINDOWS, int(STEP_MIN_SHARE * n))
    if n < 2 * sep:
        return ()
    # split after position i of the windows with data (i = 0 .. n - 2)
    gaps = [int(j) for j in np.flatnonzero(np.diff(have) > STEP_GAP_WINDOWS + 1)]
    r = resid[have]
    k = np.arange(1, n)
    c = np.cumsum(r, axis=0)[:-1]
    total = r.sum(axis=0)
    gain = np.sum((c - k[:, None] * total / n) ** 2, axis=1) * n / (k * (n - k))
    inside = (k >= sep) & (k <= n - sep)
    picked = [j for j in gaps if inside[j]]
    gain[~inside] = 0.0
    changes: list[int] = []
    for i in np.argsort(gain)[::-1]:
        if len(changes) == STEP_CHANGE_POINTS or gain[i] <= 0:
            break
        if all(abs(int(i) - j) >= sep for j in changes + picked):
            changes.append(int(i))
    return tuple(sorted({int(t_ns[have[i + 1]] - half) for i in picked + changes}))


def _settle_drift(ctx: Context, _: Any) -> np.ndarray:
    return ctx.drivers.t_day[:, None, None] * ctx.surrogate.A[None, :, :]


def _uniform(ctx: Context, _: Any) -> np.ndarray:
    return _const(ctx, np.ones(2), ctx.drivers.dtemp_k)


def _sun_case(case: str) -> Design:
    def design(ctx: Context, _: Any) -> np.ndarray:
        d = ctx.drivers
        return _const(ctx, ctx.surrogate.thermal[case], d.sun * d.clearness)

    return design


def _thermal_lag(ctx: Context, tau_h: float) -> np.ndarray:
    d = ctx.drivers
    return _const(ctx, ctx.surrogate.thermal["vertical_gradient"], d.temp_c - d.lagged_temp(tau_h))


def _stiffness(name: str) -> Design:
    """Whole-response change per unit ``r``: ``dA x_known + du0 + dthermal_uniform dT``.

    At a secant grid value ``r_g`` (the surrogate's sweep) the changes are the FE's from the built
    value to ``v_0 (1 + r_g)``, divided by ``r_g``; without one (``g`` None) the tangent.
    """

    def design(ctx: Context, r_g: Any) -> np.ndarray:
        if r_g is None:
            sens = ctx.sensitivities[name]
            da, du0 = sens.dA, sens.du0
            duni = sens.dthermal.get("uniform", np.zeros(2))
        else:
            sw = ctx.sweeps[name]
            change = sw.change(sw.built * (1.0 + float(r_g)))[0] / float(r_g)
            da, du0, duni = change[:4].reshape(2, 2), change[4:6], change[6:8]
        x = ctx.x_known @ da.T + du0[None, :] + ctx.drivers.dtemp_k[:, None] * duni[None, :]
        return x[:, :, None]

    return design


def _relative_bounds(name: str) -> Bounds:
    """Prior range of the FE parameter as ``r`` around the value the surrogate was built with."""

    def bounds(ctx: Context) -> list[tuple[float, float]]:
        sw = ctx.sweeps.get(name)
        value = sw.built if sw is not None else ctx.sensitivities[name].value
        if value is None:
            return [plausible_range(name)]
        return [PARAMETERS[name].relative_bounds(value)]

    return bounds


def _fixed_bounds(name: str, p: int) -> Bounds:
    def bounds(ctx: Context) -> list[tuple[float, float]]:
        return [plausible_range(name)] * p

    return bounds


def spring_load(ctx: Context, choice: str) -> np.ndarray:
    """(n, 2) N, the reactions a support spring maps: ``B`` (loaded) or ``B - u0`` (levelled)."""
    if choice.endswith("levelled"):
        return ctx.baseline - ctx.surrogate.u0[None, :]
    return ctx.baseline


def spring_bearings(choice: str) -> list[int]:
    """Return the indices of the bearings on a spring for a choice of ``SPRING_CHOICES``."""
    side = choice.split()[0]
    return [0] if side == "south" else [1] if side == "north" else [0, 1]


def _spring_linearized(ctx: Context, choice: str) -> np.ndarray:
    """Reaction change per unit compliance (m/N) at no spring: ``-A E_j L`` for each bearing ``j``."""
    a, b = ctx.surrogate.A, spring_load(ctx, choice)
    return np.stack([-b[:, j, None] * a[None, :, j] for j in spring_bearings(choice)], axis=2)


def _sensor_drift(ctx: Context, channel: str) -> np.ndarray:
    e = np.array([1.0, 0.0]) if channel == "south" else np.array([0.0, 1.0])
    return _const(ctx, e, ctx.drivers.t_day)


def _traffic(ctx: Context, _: Any) -> np.ndarray:
    tr = ctx.drivers.traffic
    x = np.zeros((len(tr), 2, 2))
    x[:, 0, 0] = tr
    x[:, 1, 1] = tr
    return x


def _spring_magnitude(p: np.ndarray, _: Any) -> float:
    """Stiffness of the softer spring, N/m (inf: no spring)."""
    c = float(np.max(p)) if len(p) else 0.0
    return 1.0 / c if c > 0 else float("inf")


CANDIDATES: tuple[Candidate, ...] = (
    Candidate(
        "settlement_offset",
        ("x_south [m]", "x_north [m]"),
        _settle_offset,
        magnitude=lambda p, g: float(0.5 * (p[0] - p[1])),
        bounds=_fixed_bounds("settlement_offset", 2),
    ),
    Candidate(
        "settlement_drift",
        ("v_south [m/day]", "v_north [m/day]"),
        _settle_drift,
        magnitude=lambda p, g: float(-p[0]),
        bounds=_fixed_bounds("settlement_drift", 2),
    ),
    Candidate(
        "settlement_step",
        ("dx_south [m]", "dx_north [m]"),
        _settle_step,
        grid_name="at [ns]",
        magnitude=lambda p, g: float(0.5 * (p[0] + p[1])),
        discrete=True,
        bounds=_fixed_bounds("settlement_step", 2),
        data_grid=True,
    ),
    Candidate(
        "uniform_temperature",
        ("c [N/K]",),
        _uniform,
        magnitude=lambda p, g: float(p[0]),
        bounds=_fixed_bounds("uniform_temperature", 1),
    ),
    Candidate(
        "vertical_gradient",
        ("g [K]",),
        _sun_case("vertical_gradient"),
        magnitude=lambda p, g: float(p[0]),
        bounds=_fixed_bounds("vertical_gradient", 1),
    ),
    Candidate(
        "transverse_gradient",
        ("g [K]",),
        _sun_case("transverse_gradient"),
        magnitude=lambda p, g: float(p[0]),
        bounds=_fixed_bounds("transverse_gradient", 1),
    ),
    Candidate(
        "thermal_lag",
        ("scale [1]",),
        _thermal_lag,
        LAG_GRID_H,
        "tau [h]",
        magnitude=lambda p, g: float(g),
        bounds=_fixed_bounds("thermal_lag", 1),
    ),
    Candidate(
        "bearing_stiffness",
        ("r [1]",),
        _stiffness("bearing_stiffness"),
        magnitude=lambda p, g: float(p[0]),
        bounds=_relative_bounds("bearing_stiffness"),
        secant_grid=True,
    ),
    Candidate(
        "connector_stiffness",
        ("r [1]",),
        _stiffness("connector_stiffness"),
        magnitude=lambda p, g: float(p[0]),
        bounds=_relative_bounds("connector_stiffness"),
        secant_grid=True,
    ),
    Candidate(
        "support_spring",
        ("c_south [m/N]", "c_north [m/N]"),
        _spring_linearized,
        SPRING_CHOICES,
        "bearing",
        magnitude=_spring_magnitude,
        discrete=True,
        nonlinear=True,
    ),
    Candidate(
        "slab_joint_opening",
        ("r [1]",),
        _stiffness("slab_joint_opening"),
        magnitude=lambda p, g: float(1.0 + p[0]),
        bounds=_relative_bounds("slab_joint_opening"),
        secant_grid=True,
    ),
    Candidate(
        "sensor_drift",
        ("d [N/day]",),
        _sensor_drift,
        ("south", "north"),
        "channel",
        magnitude=lambda p, g: float(p[0]),
        discrete=True,
        bounds=_fixed_bounds("sensor_drift", 1),
    ),
    Candidate(
        "traffic",
        ("b_south [1]", "b_north [1]"),
        _traffic,
        magnitude=lambda p, g: float(np.sum(p)),
        magnitude_unit="1",  # the two bearings' shares of a crossing's excess, summed
        bounds=_fixed_bounds("traffic", 2),
    ),
)
