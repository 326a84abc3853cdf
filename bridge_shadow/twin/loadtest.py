"""Load-test days: short records hours apart, the central support lowered between them.

A load-test day of the real bridge (DESIGN section 3): four 12-minute records (08:36, 09:20 and
two in the afternoon), the central support lowered by 10 mm in every gap, each record with the
same test-car pattern (car-free minutes at both ends, the car parked at three positions for about
two minutes each in between, crossings on the way), and the air temperature of the whole day.
Ways to make one:

- ``synthetic_day``: the truth twin (``twin.simulate``) over the whole day, cut to the records,
  with the parked test car added; the reality may differ from the estimator's model (a
  ``Reality`` surrogate, e.g. with support springs) and may be *nonlinear*: support springs that
  seat like a contact, tangent stiffness ``k(R) = k0 (R / R0)^n`` (``SeatingSupports``), so that
  a model calibrated on the first step is extrapolated on the later ones.
- ``load_test_day``: ``synthetic_day`` as a monitor receives such a day under the sun: the
  air warms from about 2 C in the morning to 12-14 C in the afternoon and the sun heats the deck
  from above (``vertical_gradient``, a linear temperature difference through the deck), and the
  car parks at two or three random places per record (+3 to +9 kN per bearing) (``LoadTestDay``).
- ``scheduled_day``: the day as its loggers actually ran (``SCHEDULE_2022_04_11``, read off the
  day's ten air-temperature files): four load records with the car, lowering records in which the
  support moves (a step at the record's middle), and two three-hour ambient records between, the
  later records starting minutes after the earlier ones stopped. The withheld records of that day
  have this shape; the four-record day above has nothing between its records.
- ``day_from_records``: the two real records of 2022-04-11 (reference 08:36, after 10 mm 09:20),
  cut and shifted to the afternoon, with the further steps added through a given ``A``
  (``A dx``) and the real air temperature of the hours they are placed at. Only the first step is
  real; the later ones are the given model's (a check of the tools, not of the model).

Both return ``MonitoringData`` and a truth dictionary (scoring only: nothing that estimates reads
it). No ROS import.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS, FORCE_FRAMES
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import ForceSeries, MonitoringData
from bridge_shadow.twin.config import LOCAL_TZ, TwinConfig
from bridge_shadow.twin.real_records import with_creep
from bridge_shadow.twin.response import two_span_mid_influence

__all__ = [
    "DAY",
    "RECORD_S",
    "RECORD_TIMES",
    "SCHEDULE_2022_04_11",
    "LoadTestDay",
    "SeatingSupports",
    "day_from_records",
    "load_test_day",
    "parked_car",
    "scheduled_day",
    "synthetic_day",
]

NS = 1_000_000_000
#: The day of the real lowering records.
DAY = dt.date(2022, 4, 11)
#: Local start times of the four records (h): the two real ones (08:36, 09:20) and two in the
#: afternoon (DESIGN section 3 says "two in the afternoon"; 13:10 and 15:30 are our placement).
RECORD_TIMES: tuple[float, ...] = (8.6, 9 + 20 / 60, 13 + 10 / 60, 15.5)
#: Length of one record, s (12 minutes, as the real ones).
RECORD_S = 720.0
#: The test car: weight (N) and its parked plateaus (start s into the record, length s, position
#: along the bridge as a share of the 30 m, south share of the weight). The real records show
#: plateaus summing to about 10, 20 and 10 kN (README, Calibration): a ~20 kN car at a third of a
#: span from the ends (influence 0.5) and over the central support (influence 1).
CAR_WEIGHT_N = 20.4e3
CAR_PLATEAUS: tuple[tuple[float, float, float, float], ...] = (
    (150.0, 120.0, 0.17, 0.45),
    (300.0, 120.0, 0.50, 0.50),
    (450.0, 120.0, 0.83, 0.55),
)
#: Time the car takes to drive to or between positions, s (a ramp between plateaus).
CAR_MOVE_S = 10.0


def _local_ns(day: dt.date, hours: float) -> int:
    midnight = dt.datetime(day.year, day.month, day.day, tzinfo=LOCAL_TZ)
    return round((midnight.timestamp() + hours * 3600.0) * NS)


Plateau = tuple[float, float, float, float]


def parked_car(
    t_ns: np.ndarray,
    start_ns: int,
    weight_n: float = CAR_WEIGHT_N,
    span_m: float = 15.0,
    plateaus: Sequence[Plateau] = CAR_PLATEAUS,
) -> np.ndarray:
    """(n, 2) N, the test car parked at ``plateaus`` in a record starting at ``start_ns``.

    ``plateaus``: (start s into the record, length s, position as a share of the bridge's length,
    south share of the weight), ``CAR_PLATEAUS`` by default. Each plateau ramps up and down over
    ``CAR_MOVE_S``; the load on each bearing is the weight times the two-span influence line of
    the central reaction times the girder's share.
    """
    t = (np.asarray(t_ns, np.int64) - start_ns) / NS
    out = np.zeros((len(t), 2))
    for begin, length, pos, south in plateaus:
        up = np.clip((t - begin) / CAR_MOVE_S, 0.0, 1.0)
        down = np.clip((begin + length - t) / CAR_MOVE_S, 0.0, 1.0)
        shape = np.minimum(up, down)
        load = weight_n * float(two_span_mid_influence(np.array([pos * 2 * span_m]), span_m)[0])
        out[:, 0] += shape * load * south
        out[:, 1] += shape * load * (1.0 - south)
    return out


@dataclass(frozen=True)
class SeatingSupports:
    """Support springs that stiffen with load like a seating contact (a nonlinear reality).

    Per bearing, the tangent stiffness is ``k(R) = k0 (R / R0)^n`` with ``R0`` the dead-load
    reaction: ``n = 0`` is a linear spring, ``n = 1/3`` a Hertzian contact (Johnson 1985). The
    spring's shortening from the dead-load state is
    ``S(R) = R0^n (R^(1 - n) - R0^(1 - n)) / (k0 (1 - n))`` and the reactions solve
    ``R = u0 + A_s (x - S(R))`` (the supports levelled under the dead load) with ``A_s`` the
    structure on rigid supports.

    Attributes:
        k0_n_per_m: (2,) tangent stiffness at the dead load [south, north], N/m.
        exponent: ``n``.

    """

    k0_n_per_m: tuple[float, float]
    exponent: float = 1.0 / 3.0

    def shortening(self, r_n: np.ndarray, r0_n: np.ndarray) -> np.ndarray:
        """(2,) m, ``S(R)`` per bearing."""
        n, k0 = self.exponent, np.asarray(self.k0_n_per_m, float)
        r = np.maximum(np.asarray(r_n, float), 1.0)
        if n == 1.0:
            return r0_n * np.log(r / r0_n) / k0
        return r0_n**n * (r ** (1 - n) - r0_n ** (1 - n)) / (k0 * (1 - n))

    def reactions(self, structure: Surrogate, x_m: np.ndarray) -> np.ndarray:
        """(2,) N, the reactions at settlement ``x_m`` (Newton on ``R = u0 + A_s (x - S(R))``)."""
        r0 = structure.u0
        r = structure.u0 + structure.A @ np.asarray(x_m, float)
        k0 = np.asarray(self.k0_n_per_m, float)
        for _ in range(50):
            g = r - r0 - structure.A @ (x_m - self.shortening(r, r0))
            c = (r0 / np.maximum(r, 1.0)) ** self.exponent / k0  # dS/dR
            jac = np.eye(2) + structure.A @ np.diag(c)
            step = np.linalg.solve(jac, g)
            r = r - step
            if np.max(np.abs(step)) < 1e-6:
                break
        return r


def _cut(data: MonitoringData, spans: Sequence[tuple[int, int]]) -> MonitoringData:
    """Keep the force samples inside ``spans``; the temperature of the whole day stays."""
    forces = {}
    for ch in CHANNELS:
        s = data.forces[ch]
        keep = np.zeros(len(s), bool)
        for a, b in spans:
            keep |= (s.stamp_ns >= a) & (s.stamp_ns < b)
        forces[ch] = ForceSeries(s.stamp_ns[keep], s.force_n[keep], s.frame_id[keep])
    return MonitoringData(forces, data.temperature)


def _car_force(
    stamp_ns: np.ndarray,
    spans: Sequence[tuple[int, int]],
    plateaus: Sequence[Sequence[Plateau]],
    weight_n: float,
    span_m: float,
) -> np.ndarray:
    """(n, 2) N: the parked test car's reactions at ``stamp_ns``, one plateau list per record span."""
    out = np.zeros((len(stamp_ns), 2))
    for (a, b), ps in zip(spans, plateaus, strict=True):
        m = (stamp_ns >= a) & (stamp_ns < b)
        out[m] += parked_car(stamp_ns[m], a, weight_n, span_m, ps)
    return out


def _car_stops(
    spans: Sequence[tuple[int, int]], plateaus: Sequence[Sequence[Plateau]], span_m: float
) -> list[tuple[int, int, float, float]]:
    """Return the car's plateaus as truth: (from ns, to ns, position m, south share) per stop."""
    return [
        (a + round(p[0] * NS), a + round((p[0] + p[1]) * NS), p[2] * 2 * span_m, p[3])
        for (a, _), ps in zip(spans, plateaus, strict=True)
        for p in ps
    ]


def synthetic_day(
    seed: int,
    reality: Surrogate | None = None,
    *,
    steps_m: Sequence[tuple[float, float]] = ((-0.010, -0.010),) * 3,
    record_times_h: Sequence[float] = RECORD_TIMES,
    rate_hz: float = 1.0,
    seating: SeatingSupports | None = None,
    structure: Surrogate | None = None,
    effects: dict[str, Any] | None = None,
    car: bool = True,
    car_plateaus: Sequence[Sequence[Plateau]] | None = None,
    car_weight_n: float = CAR_WEIGHT_N,
    config: TwinConfig | None = None,
    day: dt.date = DAY,
    monitor_days: float = 0.0,
) -> tuple[MonitoringData, dict[str, Any]]:
    """Simulate a load-test day with the truth twin: records at ``record_times_h``, a step per gap.

    Args:
        seed: the twin's seed (weather, noise, dropouts).
        reality: the twin's linear reality (``Surrogate``), e.g. the FE model with support springs;
            with ``seating``, its tangent at the dead load. Default ``config/surrogate.yaml``.
        steps_m: the step [south, north] (m, positive up) in each gap, ``len(record_times_h) - 1``.
        rate_hz: force rate, Hz (1 Hz: the car-free levels need 10 s windows).
        seating: a nonlinear support (``SeatingSupports``) acting on ``structure`` (the structure
            on rigid supports); the settlement response is then ``R(x) - u0`` instead of ``A x``.
        effects: further twin effects (``twin.simulate``).
        car: add the parked test car to every record.
        car_plateaus: the car's plateaus per record (``parked_car``); default ``CAR_PLATEAUS`` in each.
        car_weight_n: the test car's weight, N.
        config: the twin's world (weather, noise; ``TwinConfig()`` by default).
        monitor_days: days of continuous monitoring (no car, no step) before the load-test day,
            ending at its midnight: what a monitored bridge's shadow has seen before a test.

    Returns:
        ``(data, truth)``; ``truth["settlement_m"]``: (records, 2) the true settlement of each
        record; ``truth["reactions_n"]``: its settlement response; ``record_start_ns`` and
        ``record_end_ns``; ``stops``: the car's plateaus as (from ns, to ns, position m, south share).

    """
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.twin.simulate import simulate

    reality = reality if reality is not None else load_surrogate()
    plateaus = [CAR_PLATEAUS] * len(record_times_h) if car_plateaus is None else list(car_plateaus)
    if len(plateaus) != len(record_times_h):
        raise ValueError("one list of car plateaus per record")
    if len(steps_m) != len(record_times_h) - 1:
        raise ValueError("one step per gap between records")
    t0 = _local_ns(day, 0.0)
    begin = t0 - round(monitor_days * 86400 * NS)
    starts = [_local_ns(day, h) for h in record_times_h]
    gaps = [(starts[i] + round(RECORD_S * NS) + starts[i + 1]) / 2 for i in range(len(steps_m))]
    twin_steps = [((g - begin) / (86400 * NS), dx[0], dx[1]) for g, dx in zip(gaps, steps_m, strict=True)]
    data, truth = simulate(
        1.0 + monitor_days,
        rate_hz,
        seed,
        effects or {},
        start=begin,
        steps=twin_steps,
        surrogate=reality,
        temp_rate_hz=1 / 60,
        config=config,
    )
    span_m = (config or TwinConfig()).span_m
    spans = [(s, s + round(RECORD_S * NS)) for s in starts]
    x_rec = np.cumsum(np.vstack([np.zeros((1, 2)), np.asarray(steps_m, float)]), axis=0)
    response = x_rec @ reality.A.T
    if seating is not None:
        base = structure if structure is not None else reality
        response = np.array([seating.reactions(base, x) - base.u0 for x in x_rec])
    forces = {}
    for i, ch in enumerate(CHANNELS):
        s = data.forces[ch]
        f = s.force_n.copy()
        for k, (a, b) in enumerate(spans):
            m = (s.stamp_ns >= a) & (s.stamp_ns < b)
            f[m] += response[k, i] - (x_rec[k] @ reality.A.T)[i]  # the nonlinear response, if any
        if car:
            f += _car_force(s.stamp_ns, spans, plateaus, car_weight_n, span_m)[:, i]
        forces[ch] = ForceSeries(s.stamp_ns, f, FORCE_FRAMES[ch])
    monitored = [(begin, t0)] if monitor_days > 0 else []
    day_data = _cut(MonitoringData(forces, data.temperature), monitored + spans)
    out = {
        "seed": seed,
        "record_start_ns": starts,
        "record_end_ns": [b for _, b in spans],
        "stops": _car_stops(spans, plateaus, span_m) if car else [],
        "steps_m": [list(map(float, s)) for s in steps_m],
        "settlement_m": x_rec.tolist(),
        "reactions_n": response.tolist(),
        "seating": None
        if seating is None
        else {"k0_n_per_m": list(seating.k0_n_per_m), "exponent": seating.exponent},
        "twin": {k: truth[k] for k in ("effects", "t_ref_c", "reality") if k in truth},
    }
    return day_data, out


@dataclass(frozen=True)
class LoadTestDay:
    """A load-test day under the sun, with the test car parked at random places (SI; local hours).

    Attributes:
        record_h: start of each record, local hours (2022-04-11: 08:36, 09:20, and two afternoon
            records).
        steps_m: the settlement change [south, north] in m in each gap between records (one fewer
            than the records); happens at the middle of the gap.
        car_weight_n: the test car's weight, N (its crossings raised the real reaction sum by
            about 20 kN at the peak, over the central support).
        parked: how many places per record the car stops at (drawn uniformly, inclusive).
        stop_min: minutes per stop (drawn uniformly).
        car_free_min: car-free minutes at the start and the end of a record.
        vertical_gradient_k: the sun-driven linear temperature difference through the deck at full
            clear sky, K (the twin's ``vertical_gradient`` effect; 4 K is its realistic value, well
            inside EN 1991-1-5's 15 K for composite decks in summer).
        rate_hz: force messages per second per channel.
        twin: the rest of the world (weather, noise; traffic crossings stay off).
        monitor_days: days of continuous monitoring before the test day (``synthetic_day``).

    """

    record_h: tuple[float, ...] = (8.6, 9.33, 13.5, 15.0)
    steps_m: tuple[tuple[float, float], ...] = ((-0.01, -0.01), (-0.01, -0.01), (-0.01, -0.01))
    car_weight_n: float = 20e3
    parked: tuple[int, int] = (2, 3)
    stop_min: tuple[float, float] = (1.5, 3.0)
    car_free_min: float = 2.5
    vertical_gradient_k: float = 4.0
    rate_hz: float = 0.2
    twin: TwinConfig = field(default_factory=TwinConfig)
    monitor_days: float = 0.0

    def __post_init__(self) -> None:
        if len(self.steps_m) != len(self.record_h) - 1:
            raise ValueError("steps_m needs one step per gap between records")
        if any(b - a <= RECORD_S / 3600.0 for a, b in pairwise(self.record_h)):
            raise ValueError("records must follow each other with a gap")

    def car_plateaus(self, rng: np.random.Generator) -> list[tuple[Plateau, ...]]:
        """Random plateaus per record: car-free ends, then two or three stops between drives."""
        out = []
        for _ in self.record_h:
            n = int(rng.integers(self.parked[0], self.parked[1] + 1))
            free = self.car_free_min * 60
            at, stops = free, []
            for _ in range(n):
                end = min(at + rng.uniform(*self.stop_min) * 60, RECORD_S - free)
                if end <= at + CAR_MOVE_S:
                    break
                # a place where the central reactions rise by 3 to 9 kN per bearing (influence 0.3-0.9)
                xi = rng.uniform(0.2, 0.65)
                pos = xi / 2 if rng.random() < 0.5 else 1.0 - xi / 2
                stops.append((at, end - at, pos, float(0.5 + rng.normal(0.0, 0.05))))
                at = end + rng.uniform(0.3, 0.8) * 60  # driving to the next place
            out.append(tuple(stops))
        return out


def load_test_day(
    seed: int, spec: LoadTestDay | None = None, surrogate: Surrogate | None = None
) -> tuple[MonitoringData, dict[str, Any]]:
    """Simulate ``spec`` (``synthetic_day`` under the sun, the car at random places); see there.

    ``surrogate`` is the twin's reality (default ``config/surrogate.yaml``). The truth adds
    ``record_x_m``: (records, 2) m, the settlement during each record.
    """
    spec = spec or LoadTestDay()
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
    data, truth = synthetic_day(
        seed,
        surrogate,
        steps_m=spec.steps_m,
        record_times_h=spec.record_h,
        rate_hz=spec.rate_hz,
        effects={"vertical_gradient": spec.vertical_gradient_k} if spec.vertical_gradient_k else {},
        car_plateaus=spec.car_plateaus(rng),
        car_weight_n=spec.car_weight_n,
        config=spec.twin,
        monitor_days=spec.monitor_days,
    )
    truth["record_x_m"] = np.asarray(truth["settlement_m"], float)
    return data, truth


#: 2022-04-11 as its loggers ran: (kind, local start, local end) of each recording, from the ten
#: air-temperature files of the day (``Settlements/TemperatureData2022-04-11.zip``, logged with the
#: forces). ``load``: 12 minutes with the test car; ``lowering``: the jacks lowered the central
#: support by 10 mm during it; ``quiet``: no car, no change (the first lowering's second file, and
#: the two ambient records of three hours). The records follow each other after silences of 1 to 4
#: minutes, except for the gaps before 09:44, 13:40 and 14:13.
SCHEDULE_2022_04_11: tuple[tuple[str, str, str], ...] = (
    ("load", "08:36:26", "08:48:24"),
    ("lowering", "08:49:35", "09:09:34"),
    ("quiet", "09:10:48", "09:18:39"),
    ("load", "09:20:06", "09:32:05"),
    ("quiet", "09:44:02", "12:44:01"),
    ("lowering", "12:47:10", "13:04:56"),
    ("load", "13:39:57", "13:51:56"),
    ("quiet", "14:13:14", "17:13:13"),
    ("lowering", "17:15:54", "17:34:25"),
    ("load", "17:37:51", "17:49:48"),
)


def _hours(clock: str) -> float:
    h, m, s = (float(x) for x in clock.split(":"))
    return h + m / 60.0 + s / 3600.0


def scheduled_day(
    seed: int,
    spec: LoadTestDay | None = None,
    surrogate: Surrogate | None = None,
    *,
    schedule: Sequence[tuple[str, str, str]] = SCHEDULE_2022_04_11,
    step_m: tuple[float, float] = (-0.010, -0.010),
) -> tuple[MonitoringData, dict[str, Any]]:
    """Simulate a load-test day on ``schedule``: the twin's day cut to its recordings (SI).

    ``spec`` gives the sun (``vertical_gradient_k``), the force rate, the car and the twin's world
    (its ``record_h`` and ``steps_m`` are not used); ``step_m`` happens at the middle of every
    ``lowering`` record (the jacks' minutes as one step). The truth is ``load_test_day``'s:
    ``record_x_m`` is each recording's settlement at its end (a lowering record's new state, whose
    event belongs inside it), ``stops`` the car's plateaus.
    """
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.twin.simulate import simulate

    spec = spec or LoadTestDay()
    reality = surrogate if surrogate is not None else load_surrogate()
    day_ns = 86400 * NS
    t0 = _local_ns(DAY, 0.0)
    spans = [(_local_ns(DAY, _hours(a)), _local_ns(DAY, _hours(b))) for _, a, b in schedule]
    kinds = [k for k, _, _ in schedule]
    at = [(a + b) // 2 for (a, b), k in zip(spans, kinds, strict=True) if k == "lowering"]
    data, twin = simulate(
        1.0,
        spec.rate_hz,
        seed,
        {"vertical_gradient": spec.vertical_gradient_k} if spec.vertical_gradient_k else {},
        start=t0,
        steps=[((t - t0) / day_ns, step_m[0], step_m[1]) for t in at],
        surrogate=reality,
        temp_rate_hz=1 / 60,
        config=spec.twin,
    )
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
    loads = [span for span, k in zip(spans, kinds, strict=True) if k == "load"]
    plateaus: list[tuple[Plateau, ...]] = []
    while len(plateaus) < len(loads):
        plateaus += spec.car_plateaus(rng)
    plateaus = plateaus[: len(loads)]
    forces = {}
    for i, ch in enumerate(CHANNELS):
        s = data.forces[ch]
        car = _car_force(s.stamp_ns, loads, plateaus, spec.car_weight_n, spec.twin.span_m)[:, i]
        forces[ch] = ForceSeries(s.stamp_ns, s.force_n + car, FORCE_FRAMES[ch])
    x_end = np.array([sum(t < b for t in at) for _, b in spans], float)[:, None] * np.asarray(step_m, float)
    truth = {
        "seed": seed,
        "record_start_ns": [a for a, _ in spans],
        "record_end_ns": [b for _, b in spans],
        "record_kind": kinds,
        "record_x_m": x_end,
        "settlement_m": x_end.tolist(),
        "step_ns": at,
        "stops": _car_stops(loads, plateaus, spec.twin.span_m),
        "twin": {k: twin[k] for k in ("effects", "t_ref_c", "reality") if k in twin},
    }
    return _cut(MonitoringData(forces, data.temperature), spans), truth


def creeping(data: MonitoringData, truth: dict[str, Any], factor: float) -> MonitoringData:
    """Return ``load_test_day``'s ``data`` with every record after a step creeping (``with_creep``).

    ``factor`` times the real 10 mm record's own rise (``real_records.CREEP_N_PER_S``) from each
    such record's first sample: the twin has no creep of its own.
    """
    steps = [np.asarray(dx, float) for dx in truth["steps_m"]]
    changed = [i + 1 for i, dx in enumerate(steps) if np.any(dx != 0.0)]
    return with_creep(data, [int(t) for t in truth["record_start_ns"]], changed, factor)


def day_from_records(
    reference: MonitoringData,
    after: MonitoringData,
    temperature: MonitoringData,
    a_model: np.ndarray,
    *,
    steps_m: Sequence[tuple[float, float]] = ((-0.010, -0.010), (-0.010, -0.010)),
    later_times_h: Sequence[float] = RECORD_TIMES[2:],
    day: dt.date = DAY,
) -> tuple[MonitoringData, dict[str, Any]]:
    """Build a four-record day from the two real records of 2022-04-11 (see the module docstring).

    Args:
        reference, after: the real records (``import_csv`` of each force zip), 08:36 and 09:20.
        temperature: the day's air temperature (``import_csv`` of the temperature zip).
        a_model: (2, 2) N/m, the model through which the later steps are added.
        steps_m: the steps after the real 10 mm one, [south, north] each (m).
        later_times_h: local start of the later records (the ``after`` record shifted there).

    Returns:
        ``(data, truth)``: the day, and per record the settlement the construction imposes
        (the first step the real 10 mm, the others through ``a_model``).

    """
    forces: dict[str, list] = {ch: [] for ch in CHANNELS}
    for rec in (reference, after):
        for ch in CHANNELS:
            forces[ch].append((rec.forces[ch].stamp_ns, rec.forces[ch].force_n))
    start_after = min(int(after.forces[ch].stamp_ns.min()) for ch in CHANNELS)
    total = np.zeros(2)
    starts = [min(int(reference.forces[ch].stamp_ns.min()) for ch in CHANNELS), start_after]
    settlement = [[0.0, 0.0], [-0.010, -0.010]]
    for h, dx in zip(later_times_h, steps_m, strict=True):
        total = total + np.asarray(dx, float)
        shift = _local_ns(day, h) - start_after
        add = np.asarray(a_model, float) @ total
        for i, ch in enumerate(CHANNELS):
            s = after.forces[ch]
            forces[ch].append((s.stamp_ns + shift, s.force_n + add[i]))
        starts.append(start_after + shift)
        settlement.append((np.array([-0.010, -0.010]) + total).tolist())
    series = {}
    for ch in CHANNELS:
        stamps = np.concatenate([s for s, _ in forces[ch]])
        values = np.concatenate([v for _, v in forces[ch]])
        order = np.argsort(stamps, kind="stable")
        series[ch] = ForceSeries(stamps[order], values[order], FORCE_FRAMES[ch])
    truth = {"record_start_ns": starts, "settlement_m": settlement, "a_model": np.asarray(a_model).tolist()}
    return MonitoringData(series, temperature.temperature), truth
