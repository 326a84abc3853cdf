"""A load-test day in the truth twin: short records hours apart, a parked test car, the sun.

The real load test of 2022-04-11 is the model: 12-minute records of the central reactions taken
hours apart (08:36 and 09:20, then two in the afternoon), the central support lowered between
them, and in every record the same pattern of the test car: car-free minutes at the start and the
end, the car parked on the deck for minutes in between at two or three places (+3 to +9 kN per
bearing). The air warms from about 2 C in the morning to 12-14 C in the afternoon and the sun heats
the deck from above, which moves the reactions by kilonewtons between records
(``vertical_gradient``, a linear temperature difference through the deck).

``load_test_day`` simulates the whole day with ``twin.simulate`` (weather, sun, load-cell noise,
dropouts; the steps between records; the vertical gradient), adds the parked car inside each
record and keeps only the records: the stream a monitor of such a day receives. The truth (for
scoring only) gives each record's settlement.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries
from bridge_shadow.twin.config import LOCAL_TZ, TwinConfig
from bridge_shadow.twin.response import two_span_mid_influence
from bridge_shadow.twin.simulate import simulate

__all__ = ["LoadTestDay", "load_test_day", "parked_car_reactions"]

NS = 1_000_000_000


@dataclass(frozen=True)
class LoadTestDay:
    """What the day holds (SI; times in local hours of the day).

    Attributes:
        date: the day (local).
        record_h: start of each record, local hours (2022-04-11: 08:36, 09:20, and two afternoon
            records).
        record_min: length of a record, minutes.
        steps_m: the settlement change [south, north] in m in each gap between records (one fewer
            than the records); happens at the middle of the gap.
        car_weight_n: the test car's weight, N (its crossings raised the real reaction sum by
            about 20 kN at the peak, over the central support).
        parked: places per record where the car stops, and minutes per stop (drawn uniformly).
        car_free_min: car-free minutes at the start and the end of a record.
        vertical_gradient_k: the sun-driven linear temperature difference through the deck at full
            clear sky, K (the twin's ``vertical_gradient`` effect; 4 K is its realistic value, well
            inside EN 1991-1-5's 15 K for composite decks in summer).
        rate_hz: force messages per second per channel.
        twin: the rest of the world (weather, noise; traffic crossings stay off).

    """

    date: dt.date = dt.date(2022, 4, 11)
    record_h: tuple[float, ...] = (8.6, 9.33, 13.5, 15.0)
    record_min: float = 12.0
    steps_m: tuple[tuple[float, float], ...] = ((-0.01, -0.01), (-0.01, -0.01), (-0.01, -0.01))
    car_weight_n: float = 20e3
    parked: tuple[int, int] = (2, 3)
    stop_min: tuple[float, float] = (1.5, 3.0)
    car_free_min: float = 2.5
    vertical_gradient_k: float = 4.0
    rate_hz: float = 0.2
    twin: TwinConfig = field(default_factory=TwinConfig)

    def __post_init__(self) -> None:
        if len(self.steps_m) != len(self.record_h) - 1:
            raise ValueError("steps_m needs one step per gap between records")
        if any(b - a <= self.record_min / 60.0 for a, b in pairwise(self.record_h)):
            raise ValueError("records must follow each other with a gap")


def parked_car_reactions(
    t_ns: np.ndarray, stops: list[tuple[int, int, float, float]], weight_n: float, span_m: float
) -> np.ndarray:
    """Central reactions (n, 2) N [south, north] of a car parked at ``stops``.

    ``stops``: (from_ns, to_ns, position along the bridge in m, south share of the weight).
    """
    out = np.zeros((len(t_ns), 2))
    for t0, t1, pos, share in stops:
        on = (t_ns >= t0) & (t_ns < t1)
        load = weight_n * float(two_span_mid_influence(np.array([pos]), span_m)[0])
        out[on] += [load * share, load * (1.0 - share)]
    return out


def _local_ns(day: dt.date, hour: float) -> int:
    t = dt.datetime.combine(day, dt.time(0, 0), tzinfo=LOCAL_TZ) + dt.timedelta(hours=hour)
    return round(t.timestamp() * NS)


def load_test_day(
    seed: int, spec: LoadTestDay | None = None, surrogate: Surrogate | None = None
) -> tuple[MonitoringData, dict[str, Any]]:
    """Simulate a load-test day; return the records as one stream and the truth (scoring only).

    ``surrogate`` is the twin's reality (default ``config/surrogate.yaml``). The truth holds
    ``record_start_ns``, ``record_end_ns`` and ``record_x_m`` ((n_records, 2) m: the settlement
    during each record), the car's stops and the simulation's own truth under ``twin``.
    """
    spec = spec or LoadTestDay()
    day0 = _local_ns(spec.date, 0.0)
    starts = [_local_ns(spec.date, h) for h in spec.record_h]
    ends = [s + round(spec.record_min * 60 * NS) for s in starts]
    step_days = [((ends[i] + starts[i + 1]) / 2 - day0) / (86_400 * NS) for i in range(len(spec.steps_m))]
    steps = [(t, dx[0], dx[1]) for t, dx in zip(step_days, spec.steps_m, strict=True)]
    data, truth = simulate(
        days=1.0,
        rate_hz=spec.rate_hz,
        seed=seed,
        effects={"vertical_gradient": spec.vertical_gradient_k} if spec.vertical_gradient_k else {},
        start=day0,
        steps=steps,
        config=spec.twin,
        surrogate=surrogate,
    )
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 7]))
    stops: list[tuple[int, int, float, float]] = []
    span = spec.twin.span_m
    for t0, t1 in zip(starts, ends, strict=True):
        n = int(rng.integers(spec.parked[0], spec.parked[1] + 1))
        free = spec.car_free_min * 60 * NS
        at = t0 + free
        for _ in range(n):
            dur = rng.uniform(*spec.stop_min) * 60 * NS
            stop_end = min(at + dur, t1 - free)
            if stop_end <= at:
                break
            # a place where the central reactions rise by 3 to 9 kN per bearing (influence 0.3-0.9)
            xi = rng.uniform(0.2, 0.65)
            pos = xi * span if rng.random() < 0.5 else (2.0 - xi) * span
            stops.append((int(at), int(stop_end), float(pos), float(0.5 + rng.normal(0.0, 0.05))))
            at = stop_end + rng.uniform(0.3, 0.8) * 60 * NS  # driving to the next place
    keep_forces = {}
    x = truth["series"]["x_m"]
    t_series = truth["series"]["stamp_ns"]
    mids = [(a + b) // 2 for a, b in zip(starts, ends, strict=True)]
    record_x = np.array([x[np.searchsorted(t_series, t)] for t in mids])
    for c, ch in enumerate(CHANNELS):
        s = data.forces[ch]
        mask = np.zeros(len(s), bool)
        for a, b in zip(starts, ends, strict=True):
            mask |= (s.stamp_ns >= a) & (s.stamp_ns < b)
        car = parked_car_reactions(s.stamp_ns[mask], stops, spec.car_weight_n, span)[:, c]
        keep_forces[ch] = ForceSeries(
            s.stamp_ns[mask], s.force_n[mask] + car, s.frame_id[mask], s.log_ns[mask]
        )
    temp = data.temperature
    tmask = np.zeros(len(temp), bool)
    for a, b in zip(starts, ends, strict=True):
        tmask |= (temp.stamp_ns >= a - 60 * NS) & (temp.stamp_ns < b + 60 * NS)
    keep_temp = TemperatureSeries(
        *(getattr(temp, f)[tmask] for f in ("stamp_ns", "temp_c", "variance", "frame_id", "log_ns"))
    )
    out_truth = {
        "record_start_ns": starts,
        "record_end_ns": ends,
        "record_x_m": record_x,
        "stops": stops,
        "spec": spec,
        "twin": truth,
    }
    return MonitoringData(keep_forces, keep_temp), out_truth
