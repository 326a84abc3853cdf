"""Load-test days built from the two real records of 2022-04-11 (read from ../shared, never copied).

Scenarios for tests and benchmarks (``test/test_loadtest_days.py``,
``benchmarks/loadtest_days.py``); the twin's own load-test day is ``twin.loadtest``.

The public data hold two 12-minute records of the central-support forces: the reference state
(08:36 local) and the state after the whole central support was lowered by 10 mm (09:20), each with
the test car crossing and parked on the bridge, plus the day's air temperature (08:36-17:49). A
scenario places copies of them on a time line, cut or whole, hours apart, adds a further
settlement step through the calibrated surrogate (forces + A dx), and pairs each copy with the
real air temperature of the hour it is placed at (or of another hour, when it is placed beyond the
day). The car's pattern and the bridge's own wander stay as they were recorded: only reality
shows them.

Truth of a piece (for scoring only): the record's own state (0 for the reference, -10 mm at both
bearings for the lowered record) plus the added step; and where the test car stood in it
(``Scenario.car_ns``: ``calibrate``'s car detector on the record as recorded, placed with the piece).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from bridge_shadow.contract import CHANNELS
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = [
    "CREEP_N_PER_S",
    "RECORDS",
    "SWEEP_MIN_CHANGE_M",
    "SWEEP_MIN_LOAD_SHARE",
    "Piece",
    "Scenario",
    "build",
    "car_stretches_ns",
    "load_records",
    "lowered_from_start",
    "lowered_over",
    "random_inside_streams",
    "random_streams",
    "with_creep",
    "with_silence",
    "with_vehicle",
    "without_recorded_car",
]

NS = 1_000_000_000
HOUR_NS = 3600 * NS
#: The two public records (file names in ``Settlements/``) and their imposed state [south, north] m.
RECORDS = {
    "ref": ("UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip", (0.0, 0.0)),
    "lowered": ("UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip", (-0.01, -0.01)),
}
TEMPERATURE_ZIP = "TemperatureData2022-04-11.zip"


@dataclass(frozen=True)
class Piece:
    """One record placed in a scenario.

    Attributes:
        record: ``ref`` or ``lowered``.
        at_h: start of the copy, hours after the reference record's start (08:36 local).
        step_m: settlement added through the surrogate [south, north], m (on top of the record's).
        temp_at_h: take the air temperature of this hour (same reference) instead of the copy's own
            (None: its own; required when the copy lies beyond the day's temperature record).
        cut_min: keep only minutes ``[a, b)`` of the record (None: the whole record).

    """

    record: str
    at_h: float
    step_m: tuple[float, float] = (0.0, 0.0)
    temp_at_h: float | None = None
    cut_min: tuple[float, float] | None = None

    def truth_m(self) -> np.ndarray:
        """Return the true settlement of the copy [south, north], m."""
        return np.asarray(RECORDS[self.record][1], float) + np.asarray(self.step_m, float)


@dataclass
class Scenario:
    """A built scenario: the stream and what it should give (scoring only)."""

    data: MonitoringData
    pieces: tuple[Piece, ...]
    starts_ns: list[int]
    #: Stretches ``(from, to)`` stamp ns of the stream where the recorded test car stood.
    car_ns: tuple[tuple[int, int], ...] = ()

    #: Hours after the reference record's start with a continuous air-temperature record (the
    #: day's files leave gaps of minutes to half an hour between them).
    TEMPERATURE_HOURS = ((0.0, 0.9), (1.14, 4.1), (5.62, 8.6))

    @property
    def truth_m(self) -> np.ndarray:
        """True settlement at the end of the stream, m."""
        return self.pieces[-1].truth_m()

    def changes(self) -> list[int]:
        """Return the indices of the pieces whose state differs from the one before (events)."""
        return [
            i
            for i in range(1, len(self.pieces))
            if np.max(np.abs(self.pieces[i].truth_m() - self.pieces[i - 1].truth_m())) > 1e-9
        ]


@lru_cache(maxsize=2)
def load_records(folder: Path) -> tuple[dict[str, MonitoringData], TemperatureSeries]:
    """Import the two force records and the day's air temperature (cached per folder)."""
    from bridge_shadow.importers import import_csv

    recs = {name: import_csv([folder / fname])[0] for name, (fname, _) in RECORDS.items()}
    temp = import_csv([folder / TEMPERATURE_ZIP])[0].temperature
    return recs, temp


@lru_cache(maxsize=2)
def car_stretches_ns(folder: Path) -> dict[str, tuple[tuple[int, int], ...]]:
    """Return where the test car stood in each record, ``(from, to)`` stamp ns (scoring only).

    ``calibrate.car.detect_car`` on 1 s bins of the record as recorded: a piece's copy has the
    car at the same minutes, whatever step the piece adds through ``A``.
    """
    from bridge_shadow.calibrate.car import bin_record, detect_car

    recs, _ = load_records(Path(folder))
    out = {}
    for name, rec in recs.items():
        binned = bin_record(rec, 1.0)
        stretches = detect_car(binned).intervals_s
        t0 = binned.start_ns
        out[name] = tuple((t0 + round(a * NS), t0 + round(b * NS)) for a, b in stretches)
    return out


def build(
    folder: Path, A: np.ndarray, pieces: tuple[Piece, ...] | list[Piece], require_temperature: bool = True
) -> Scenario:
    """Build the stream of ``pieces`` (in the given order, which must be increasing in ``at_h``).

    ``A`` (2, 2) N/m maps each piece's added step to forces. ``require_temperature`` False lets a
    piece keep the air readings its own hour has, however few (the public file pauses for half an
    hour at a time): the stream then has stale temperature there, as a real one would.
    """
    recs, temp = load_records(Path(folder))
    cars = car_stretches_ns(Path(folder))
    t_ref = int(recs["ref"].forces[CHANNELS[0]].stamp_ns[0])
    forces: dict[str, list[ForceSeries]] = {ch: [] for ch in CHANNELS}
    t_parts: list[tuple[np.ndarray, np.ndarray]] = []
    starts = []
    car: list[tuple[int, int]] = []
    for p in pieces:
        rec = recs[p.record]
        t0 = int(rec.forces[CHANNELS[0]].stamp_ns[0])
        shift = t_ref + round(p.at_h * HOUR_NS) - t0
        d_force = np.asarray(A, float) @ np.asarray(p.step_m, float)
        lo, hi = (-np.inf, np.inf) if p.cut_min is None else (p.cut_min[0] * 60 * NS, p.cut_min[1] * 60 * NS)
        for c, ch in enumerate(CHANNELS):
            s = rec.forces[ch]
            keep = (s.stamp_ns - t0 >= lo) & (s.stamp_ns - t0 < hi)
            moved = ForceSeries(s.stamp_ns[keep] + shift, s.force_n[keep] + d_force[c], s.frame_id[keep])
            forces[ch].append(moved)
        first = int(forces[CHANNELS[0]][-1].stamp_ns[0])
        last = int(max(f[-1].stamp_ns[-1] for f in forces.values()))
        starts.append(first)
        car += [
            (max(a + shift, first), min(b + shift, last))
            for a, b in cars[p.record]
            if a + shift < last and b + shift > first
        ]
        # the air temperature over the copy (plus a minute either side): its own hour's, or another's
        src = 0 if p.temp_at_h is None else t_ref + round(p.temp_at_h * HOUR_NS) - first
        sel = (temp.stamp_ns >= first - 60 * NS + src) & (temp.stamp_ns <= last + 60 * NS + src)
        broken = not np.any(sel) or np.max(np.diff(temp.stamp_ns[sel]), initial=0) > 120 * NS
        if require_temperature and broken:
            raise ValueError(f"no continuous air temperature for {p}: give temp_at_h, an hour that has it")
        t_parts.append((temp.stamp_ns[sel] - src, temp.temp_c[sel]))
    merged = {ch: _concat(forces[ch]) for ch in CHANNELS}
    ts = np.concatenate([t for t, _ in t_parts])
    tv = np.concatenate([v for _, v in t_parts])
    order = np.argsort(ts, kind="stable")
    data = MonitoringData(merged, TemperatureSeries(ts[order], tv[order]))
    return Scenario(data, tuple(pieces), starts, tuple(car))


def _concat(parts: list[ForceSeries]) -> ForceSeries:
    return ForceSeries(
        np.concatenate([p.stamp_ns for p in parts]),
        np.concatenate([p.force_n for p in parts]),
        np.concatenate([p.frame_id for p in parts]),
    )


#: The 10 mm record's own creep over its minutes, south / north (N/s): its car-free windows rise
#: by about 0.05 / 0.1 kN a minute (0.6 / 1.2 kN over the record); the reference record's north
#: stays within 0.1 kN.
CREEP_N_PER_S = np.array([50.0, 100.0]) / 60.0


def with_creep(
    data: MonitoringData, starts_ns: list[int], changed: list[int], factor: float
) -> MonitoringData:
    """Add ``factor`` times ``CREEP_N_PER_S`` from the first sample of each changed record to its end.

    ``starts_ns`` are the records' first stamps (``Scenario.starts_ns``), ``changed`` the indices of
    the records that creep (a record after a change of the supports).
    """
    forces = {}
    for c, (ch, s) in enumerate(data.forces.items()):
        add = np.zeros(len(s.stamp_ns))
        for i in changed:
            end = starts_ns[i + 1] if i + 1 < len(starts_ns) else np.iinfo(np.int64).max
            inside = (s.stamp_ns >= starts_ns[i]) & (s.stamp_ns < end)
            add[inside] = factor * CREEP_N_PER_S[c] * (s.stamp_ns[inside] - starts_ns[i]) / 1e9
        forces[ch] = ForceSeries(s.stamp_ns, s.force_n + add, s.frame_id)
    return MonitoringData(forces, data.temperature)


def with_silence(
    data: MonitoringData, start_ns: int, channel: int, a_min: float, b_min: float
) -> MonitoringData:
    """Drop load cell ``channel``'s samples over minutes ``[a_min, b_min)`` after ``start_ns``."""
    forces = {}
    for c, (ch, s) in enumerate(data.forces.items()):
        t = s.stamp_ns
        gone = (c == channel) & (t >= start_ns + a_min * 60 * NS) & (t < start_ns + b_min * 60 * NS)
        forces[ch] = _kept(s, ~gone)
    return MonitoringData(forces, data.temperature)


def with_vehicle(
    data: MonitoringData, start_ns: int, load_n: float, a_min: float, b_min: float
) -> MonitoringData:
    """Add a vehicle of ``load_n`` N (half per bearing) over minutes ``[a_min, b_min)`` after ``start_ns``."""
    forces = {}
    for ch, s in data.forces.items():
        t = s.stamp_ns
        on = (t >= start_ns + a_min * 60 * NS) & (t < start_ns + b_min * 60 * NS)
        forces[ch] = ForceSeries(t, s.force_n + on * (0.5 * load_n), s.frame_id, s.log_ns)
    return MonitoringData(forces, data.temperature)


def lowered_over(
    at_h: float, start_min: float, minutes: float, size_m: float = -0.02, stages: int | None = None
) -> list[Piece]:
    """Return the real pair, then the 10 mm record at ``at_h`` lowered ``size_m`` more over ``minutes``.

    The jacks' lowering runs from minute ``start_min`` of the later record, in half-minute slices
    through ``A`` (each at the step its middle has reached), and the record is copied in a row (12
    minutes each, the test car's pattern in every copy) until three still minutes follow it.
    ``at_h`` must have the day's air readings for every copy (5.62-8.6 h holds three). With
    ``stages`` the lowering comes in that many equal steps instead, ``minutes / stages`` apart,
    the first at ``start_min`` (the jacks lowered by a few millimetres at a time, then held).
    """
    copies = int(np.ceil((start_min + minutes + 3.0) / 12.0))
    pieces = [Piece("ref", 0.0), Piece("lowered", 0.733)]
    return pieces + _lowering_slices("lowered", at_h, copies, start_min, minutes, size_m, stages)


def lowered_from_start(
    record: str, start_min: float, minutes: float, size_m: float, copies: int = 3
) -> list[Piece]:
    """Return ``record`` copied ``copies`` times in a row from the data's start, lowered over minutes.

    As ``lowered_over`` without the real pair before it: the copies 0.2 h apart (12 minutes each,
    one unbroken recording), the lowering of ``size_m`` from minute ``start_min`` over ``minutes``
    in half-minute slices through ``A``, while the shadow's noise model is young.
    """
    return _lowering_slices(record, 0.0, copies, start_min, minutes, size_m, None)


def _lowering_slices(
    record: str, at_h: float, copies: int, start_min: float, minutes: float, size_m: float, stages: int | None
) -> list[Piece]:
    """Half-minute slices of ``record`` copied in a row from ``at_h``, each at the step its middle reached."""
    pieces = []
    for u in np.arange(0.0, 12.0 * copies, 0.5):
        c = int(u // 12)
        f = float(np.clip((u + 0.25 - start_min) / minutes, 0.0, 1.0))
        if stages is not None:
            f = float(min(np.floor(f * stages) + 1.0, stages)) / stages if u + 0.25 >= start_min else 0.0
        cut = (float(u - 12 * c), float(u + 0.5 - 12 * c))
        pieces.append(Piece(record, at_h + c * 0.2, (size_m * f, size_m * f), cut_min=cut))
    return pieces


def without_recorded_car(sc: Scenario) -> MonitoringData:
    """Return ``sc.data`` without the force samples where the recorded test car stood (``car_ns``).

    The car as recorded, not as a detector reads it (one would take a ramp's minutes for a car).
    """
    forces = {}
    for ch, s in sc.data.forces.items():
        keep = np.ones(len(s.stamp_ns), bool)
        for a, b in sc.car_ns:
            keep &= (s.stamp_ns < a) | (s.stamp_ns >= b)
        forces[ch] = _kept(s, keep)
    return MonitoringData(forces, sc.data.temperature)


def _kept(s: ForceSeries, keep: np.ndarray) -> ForceSeries:
    """Return the samples of ``s`` where ``keep`` holds (stamps, forces, frames; the air elsewhere)."""
    return ForceSeries(s.stamp_ns[keep], s.force_n[keep], s.frame_id[keep])


#: Hours of the day's air-temperature record a 12-minute copy can take its temperature from.
_TEMP_WINDOWS = tuple((a, b - 0.25) for a, b in Scenario.TEMPERATURE_HOURS)
#: ``random_streams``' smallest change of state: a change the size of the model's own error
#: between the two real records (5-7 kN per bearing) has no settlement truth.
SWEEP_MIN_CHANGE_M = 0.005
#: ``random_streams`` stays where both bearings keep at least this share of their dead load
#: (``u0``): the two bearings of the support are stiff against each other (10 mm between them
#: moves 200 kN), and a state beyond lift-off is outside the linear model (the gate then rejects
#: the cell's negative readings and says so: ``out_of_range``, a warning naming a lifted bearing).
SWEEP_MIN_LOAD_SHARE = 0.25


def _near_lift_off(A: np.ndarray, u0: np.ndarray, settlement_m: np.ndarray) -> bool:
    """Whether a bearing keeps less than ``SWEEP_MIN_LOAD_SHARE`` of its dead load at this state."""
    return bool(np.any(u0 + A @ settlement_m < SWEEP_MIN_LOAD_SHARE * u0))


def random_streams(
    n: int, A: np.ndarray, u0: np.ndarray, seed: int = 0, cut_share: float = 0.0
) -> Iterator[tuple[str, list[Piece]]]:
    """Yield ``n`` random streams (name, pieces) of the two records: any order, spacing and step.

    Each draws the first and later record, the later one's start log-uniform in 0.9-72 h, the air
    temperature of its own hour (where the day's file has it) or of a random hour, and its change
    of state against the first: none (one in six, only when both are the same record), or a common
    settlement of 5-40 mm (one in five raised) with, one in three, a difference of up to 10 mm
    between the bearings, added through the calibrated A, as long as both bearings keep a quarter
    of their dead load (``SWEEP_MIN_LOAD_SHARE``); a share ``cut_share`` of the later records cut
    to their first 6-10 minutes or to begin at minute 3-7 (the 12-minute records' test car then on
    the bridge at the cut's end or start). The new state is the last record, in the middle (again
    1-1.5 h later), or after a record of the old state. ``A`` (2, 2) N/m and ``u0`` (2,) N are the
    surrogate's (the step's forces, the dead load).
    """
    rng = np.random.default_rng(seed)
    A, u0 = np.asarray(A, float), np.asarray(u0, float)
    i = 0
    while i < n:
        first, later = (str(x) for x in rng.choice(["ref", "lowered"], 2))
        at = float(np.exp(rng.uniform(np.log(0.9), np.log(72.0))))
        own = any(a <= at <= b for a, b in _TEMP_WINDOWS)
        if own and rng.random() < 0.5:
            temp_at = None
        else:
            a, b = _TEMP_WINDOWS[rng.integers(len(_TEMP_WINDOWS))]
            temp_at = float(rng.uniform(a, b))
        if first == later and rng.random() < 1 / 6:
            change = np.zeros(2)
        else:
            common = rng.uniform(SWEEP_MIN_CHANGE_M, 0.04) * (1 if rng.random() < 0.2 else -1)
            diff = rng.uniform(-0.01, 0.01) if rng.random() < 1 / 3 else 0.0
            change = common + np.array([diff / 2, -diff / 2])
            if np.max(np.abs(change)) < SWEEP_MIN_CHANGE_M:
                change *= SWEEP_MIN_CHANGE_M / np.max(np.abs(change))
        if _near_lift_off(A, u0, np.asarray(RECORDS[first][1]) + change):
            continue  # beyond lift-off (SWEEP_MIN_LOAD_SHARE): drawn again
        step = tuple(float(x) for x in np.subtract(RECORDS[first][1], RECORDS[later][1]) + change)
        cut = None
        if rng.random() < cut_share:  # its first 6-10 minutes, or from minute 3-7 on
            keep = float(rng.uniform(6.0, 10.0))
            cut = (0.0, keep) if rng.random() < 0.5 else (13.0 - keep, 13.0)
        new = Piece(later, at, step, temp_at, cut)
        layout = ("last", "middle", "old between")[rng.integers(3)]
        d = np.round(1e3 * change, 1)
        temp = "own" if temp_at is None else f"{temp_at:.2f} h"
        part = "" if cut is None else f" min {cut[0]:.1f}-{cut[1]:.1f}"
        name = f"#{i} {first} > {later}{part} {d} mm at {at:.2f} h (air {temp}), {layout}"
        if layout == "last":
            yield name, [Piece(first, 0.0), new]
        elif layout == "middle":
            again_at = at + float(rng.uniform(1.0, 1.5))
            a, b = _TEMP_WINDOWS[rng.integers(len(_TEMP_WINDOWS))]
            yield name, [Piece(first, 0.0), new, Piece(later, again_at, step, float(rng.uniform(a, b)))]
        else:
            yield name, [Piece(first, 0.0), Piece(first, 0.45), new]
        i += 1


def random_inside_streams(
    n: int, A: np.ndarray, u0: np.ndarray, seed: int = 0
) -> Iterator[tuple[str, list[Piece]]]:
    """Yield ``n`` random streams (name, pieces) with one or two settlements inside the later record.

    The first record whole; the same record again 1-72 h on, in the same state, with the air of a
    random hour (the other record there would differ from it by the model's error, not by a
    settlement: ``SWEEP_MIN_CHANGE_M``) and, from one or two random minutes (1-11, at least two
    apart), further changes of 3-20 mm each, lowered (four in five) or raised, a third with up to
    a third of it between the bearings, added through ``A`` to the rest of the record (the
    record's pieces share its placement: one recording, the step while it runs, the test car's
    minutes as they were). States beyond
    ``SWEEP_MIN_LOAD_SHARE`` of the dead load are drawn again.
    """
    rng = np.random.default_rng(seed)
    A, u0 = np.asarray(A, float), np.asarray(u0, float)
    i = 0
    while i < n:
        first = later = str(rng.choice(["ref", "lowered"]))
        at = float(np.exp(rng.uniform(np.log(1.0), np.log(72.0))))
        a, b = _TEMP_WINDOWS[rng.integers(len(_TEMP_WINDOWS))]
        temp_at = float(rng.uniform(a, b))
        n_steps = 1 + int(rng.random() < 0.5)
        minutes = np.sort(rng.choice(np.arange(1, 12), n_steps, replace=False)).tolist()
        if n_steps == 2 and minutes[1] - minutes[0] < 2:
            continue
        state = np.zeros(2)  # the later record begins in the first one's state
        steps, sizes = [state.copy()], []
        for _ in minutes:
            size = rng.uniform(0.003, 0.02) * (1 if rng.random() < 0.2 else -1)
            diff = rng.uniform(-abs(size), abs(size)) / 3 if rng.random() < 1 / 3 else 0.0
            change = size + np.array([diff / 2, -diff / 2])
            state = state + change
            steps.append(state.copy())
            sizes.append(np.round(1e3 * change, 1).tolist())
        truths = [np.asarray(RECORDS[later][1]) + st for st in steps]
        if any(_near_lift_off(A, u0, t) for t in truths):
            continue
        bounds = [0.0, *map(float, minutes), 13.0]
        pieces = [Piece(first, 0.0)]
        for k, st in enumerate(steps):
            pieces.append(Piece(later, at, tuple(map(float, st)), temp_at, (bounds[k], bounds[k + 1])))
        name = f"#{i} {first} again at {at:.2f} h (air {temp_at:.2f} h), {sizes} mm from minutes {minutes}"
        yield name, pieces
        i += 1
