"""Load-test days: steps between records hours apart, on real records and in the twin (issue 19).

Two studies, each printed as rates:

- **real**: every stream the two public records of 2022-04-11 make (``twin.real_records``): the
  reference or the 10 mm record first, then either record placed 1.25 h, 3.5 h, 4 h (with the air
  temperature of 6.5 h) or 24 h (of 7.5 h) later with a step of 0, 10, 20, 30 or 10/20 mm added
  through the calibrated A; the new state as the last record, in the middle (the same record again
  1-1.5 h later), or after a record of the old state. 228 streams: the reference record 10 mm
  lower through A is the lowered state only in the model (the real lowered record differs from it
  by the model's error, 5-7 kN per bearing with the model average), so the lowered record followed
  by it has no settlement truth and is left out. Per stream: one event at
  each record whose state changed, no window of a changed record rejected (and, apart, none but
  the recorded test car parked on the state the shadow then held: "none lost car-free",
  ``StreamScore.lost_car_free``), the final estimate within 10 % of the truth (or 1 mm), and its
  95 % interval holding it.
- **twin**: ``twin.loadtest.load_test_day`` over ``--seeds`` seeds, with the sun (a 4 K vertical
  difference at full clear sky) and without it: every step an event at its record, no car-free
  window of a new state rejected, the final estimate within 10 %, the 95 % interval holding it.
  ``--only schedule``: the same on ``twin.loadtest.scheduled_day``, the day as 2022-04-11's
  loggers ran (the step inside each lowering record, three-hour ambient records between).

The shadow cuts the test car itself (its traffic screen, ``traffic_hold_s``); ``--hold 0`` runs
it without the screen (the previous stop's numbers). ``--car cut`` is the what-if that preceded
the screen: before the shadow sees a stream, the samples that ``calibrate``'s test-car detector
(``calibrate.car.detect_car``, 1 s bins of each 12-minute record) flags are dropped.
``--u0 as_built`` replaces the calibrated surrogate's ``u0`` (the reference record's car-free level,
``zero: before`` in ``config/calibration.yaml``) by the as-built FE's dead-load reactions (the
previous stops' ``u0``).

The shipped shadow has its sun term (``sun_gradient: true``, one ``g`` of the deck averaged over
its explanations by evidence: ``sun_gradient_fit: average``); ``--sun-off`` runs it without,
``--sun-term`` with (for the other fits), ``--sun-prior MEAN SD`` with another prior of its ``g``
(K; the shipped one is 0 and 6.75), ``--sun-fit deck`` with one ``g`` of the deck, in where its
Bayes factor reaches 3, ``per_bearing`` with a ``g`` of each bearing's own; ``--monitor-days N``
gives the twin's load-test day N days of continuous monitoring (no car, no step) before it.
``--only continuous`` is a third study, not run by default: three sunny days of continuous twin
monitoring (0.1 Hz, a 0.7 mm offset, 4 K at full sun), the sun term off and on: days without a
false event, the final error and interval, and the ``g`` the term learns. ``--only minutes`` is a
fourth: the two real records minutes apart (one record for the traffic hold, a step inside the
warm-up), cut to their first or last 6 minutes, small, raised and one-sided steps, and the day's
four states, each in 30 s, 1 min and 2 min windows (``window_s``), scored as the real study.
``--creep FACTOR`` lets the twin's new states creep as the real one does (``with_creep``,
FACTOR times its rate). ``--only creep`` is a fifth: the new state's reactions creeping after a
lowering (``with_creep``: the 10 mm record's own rise of 0.05 / 0.1 kN a minute, added again up to
three times) in the pair, the pair after a second quiet record of the old state, and the day's
four records (every new state creeping more, or only the two after the 10 mm record).
``--only pauses`` is a sixth: the later record's logger silent for 1 to 8 minutes while the test
car stands (``pause_streams``), then the reference record paused too, or the later record twice
(``more_pause_streams``), and one load cell silent for minutes of the later record
(``with_silence``). ``--only sweep`` is a seventh: ``--seeds`` random streams of the two records
(``twin.real_records.random_streams``: either order, the later record 0.9-72 h on with the air of
its own or another hour, no change or a common change of 5-40 mm, raised or lowered, with a
difference between the bearings of up to 10 mm, as the last record, in the middle or after the old
state; ``--cut-share`` of them cut to their first minutes or to begin at minute 3-7, under the
parked test car; ``--stream-seed`` draws another set), scored as the real study. ``--only
inside`` is an eighth: ``--seeds`` random
streams with one or two settlements of 3-20 mm inside the later record
(``twin.real_records.random_inside_streams``; ``--stream-seed`` too). ``--only ramps`` is a
ninth: the real pair, then the 10 mm record at 14:36 lowered 20 mm more over 4 to 30 minutes from
its minute 0, 3 or 6 (``twin.real_records.lowered_over``: the record copied in a row as long as
the lowering needs), the test car as recorded and cut (``without_recorded_car``). ``--only
stages`` is a tenth: the same record lowered 20 mm in 2 to 10 equal steps one to three minutes
apart, from its minute 1, 3 or 6 (``lowered_over``'s ``stages``), scored as the ramps. ``--only
long`` is an eleventh: one recording longer than the traffic hold, so unscreened, either record
three or four times back to back from the data's start or 1.25, 4 or 24 h after the same record,
10 mm lower at its first seam, its second or each (``long_streams``, 48), as they are and with a
20 kN vehicle parked in the recording's minutes 1-7 (``twin.real_records.with_vehicle``).

Usage::

    .venv/bin/python benchmarks/loadtest_days.py [--seeds 200]
        [--only real|twin|continuous|minutes|creep|pauses|sweep|inside|ramps|stages|long]
        [--workers N] [--car recorded|cut] [--hold S] [--u0 model|as_built] [--sun-term|--sun-off]
        [--sun-prior MEAN SD] [--sun-fit average|deck|per_bearing] [--monitor-days N] [--creep FACTOR]

Streams and seeds run as tasks on Dask (``bridge_shadow.engine``: a local cluster of ``--workers``
processes, default one per core).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from bridge_shadow.calibrate.car import bin_record, detect_car
from bridge_shadow.engine import client_mapper, dask_client
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.paths import config_file, shared_data_dir
from bridge_shadow.series import ForceSeries, MonitoringData
from bridge_shadow.twin.loadtest import LoadTestDay, creeping, load_test_day, scheduled_day
from bridge_shadow.twin.loadtest_score import car_excursions, score_day, score_stream
from bridge_shadow.twin.real_records import (
    Piece,
    build,
    lowered_over,
    random_inside_streams,
    random_streams,
    with_creep,
    with_silence,
    with_vehicle,
    without_recorded_car,
)

W = 60 * 10**9
#: Length of one public record (12 minutes) and a margin, ns.
RECORD_NS = 13 * W
PLACES = {"1.25 h": (1.25, None), "3.5 h": (3.5, None), "4 h": (4.0, 6.5), "24 h": (24.0, 7.5)}
#: The placements of the defect studies (pauses, a silent or creeping cell): an hour on, and hours.
NEAR_AND_FAR = {name: PLACES[name] for name in ("1.25 h", "4 h")}
STEPS = {
    "0": (0.0, 0.0),
    "10": (-0.01, -0.01),
    "20": (-0.02, -0.02),
    "30": (-0.03, -0.03),
    "10/20": (-0.01, -0.02),
}


def real_streams():
    """Yield (name, pieces) for every real-record stream of the study."""
    for first in ("ref", "lowered"):
        for later in ("ref", "lowered"):
            for place, (at, temp_at) in PLACES.items():
                for step_name, step in STEPS.items():
                    if first == "lowered" and later == "ref" and step_name == "10":
                        continue  # the same state only through the model (module docstring)
                    new = Piece(later, at, step, temp_at)
                    again = Piece(later, at + 1.5 if at < 8 else at + 1.0, step, 6.0)
                    base = f"{first} > {later} -{step_name} mm at {place}"
                    yield f"{base}, last", [Piece(first, 0.0), new]
                    yield f"{base}, middle", [Piece(first, 0.0), new, again]
                    yield f"{base}, old between", [Piece(first, 0.0), Piece(first, 0.45), new]


def minutes_streams():
    """Yield (name, pieces) of the records minutes apart or cut short (the ``minutes`` study)."""
    low = (-0.01, -0.01)
    yield "ref, lowered at its own time (44 min)", [Piece("ref", 0.0), Piece("lowered", 0.73)]
    yield "lowered, ref at 44 min (raised)", [Piece("lowered", 0.0), Piece("ref", 0.73)]
    yield "ref, lowered 2 min after its end", [Piece("ref", 0.0), Piece("lowered", 0.25)]
    yield "ref, ref -10 mm 1 min after its end", [Piece("ref", 0.0), Piece("ref", 0.22, low)]
    yield "ref, ref -3 mm at 1.25 h", [Piece("ref", 0.0), Piece("ref", 1.25, (-0.003, -0.003))]
    yield "ref, ref +10 mm at 1.25 h", [Piece("ref", 0.0), Piece("ref", 1.25, (0.01, 0.01))]
    yield "ref, ref south -10 mm at 1.25 h", [Piece("ref", 0.0), Piece("ref", 1.25, (-0.01, 0.0))]
    yield (
        "the day: ref, lowered, -20 at 5.7 h, -30 at 6.9 h",
        [
            Piece("ref", 0.0),
            Piece("lowered", 0.73),
            Piece("lowered", 5.7, low),
            Piece("lowered", 6.9, (-0.02, -0.02)),
        ],
    )
    yield (
        "ref, lowered, first 6 min of each",
        [
            Piece("ref", 0.0, cut_min=(0, 6)),
            Piece("lowered", 0.73, cut_min=(0, 6)),
        ],
    )
    yield (
        "ref, lowered, last 6 min of each",
        [
            Piece("ref", 0.0, cut_min=(6, 13)),
            Piece("lowered", 0.73, cut_min=(6, 13)),
        ],
    )


def _between(s: ForceSeries, keep: np.ndarray) -> ForceSeries:
    return ForceSeries(s.stamp_ns[keep], s.force_n[keep], s.frame_id[keep])


def without_car(data: MonitoringData, starts_ns: list[int]) -> MonitoringData:
    """Drop the force samples ``detect_car`` flags in each record (records start at ``starts_ns``)."""
    cut = []
    for t0 in starts_ns:
        inside = {ch: (s.stamp_ns >= t0) & (s.stamp_ns < t0 + RECORD_NS) for ch, s in data.forces.items()}
        record = {ch: _between(s, inside[ch]) for ch, s in data.forces.items()}
        binned = bin_record(MonitoringData(record, data.temperature), 1.0)
        for a, b in detect_car(binned).intervals_s:
            cut.append((binned.start_ns + round(a * 1e9), binned.start_ns + round(b * 1e9)))
    forces = {}
    for ch, s in data.forces.items():
        keep = np.ones(len(s.stamp_ns), bool)
        for a, b in cut:
            keep &= (s.stamp_ns < a) | (s.stamp_ns >= b)
        forces[ch] = _between(s, keep)
    return MonitoringData(forces, data.temperature)


AS_BUILT = config_file("surrogate_fe.yaml")


def real_stream(item: tuple[Any, ...]) -> tuple[str, list[bool], str, list[float]]:
    """Score one stream (a task): events right, nothing lost (car-free), within 10 % (or 1 mm), covered.

    ``item``: name, pieces, car, parameter overrides, u0, and optionally a dict of defects:
    ``creep`` (factor, first piece): ``with_creep`` on every record from that piece on whose state
    changed; ``silent`` (channel, from, to minutes): that load cell silent over those minutes of
    the last record; ``vehicle`` (N, from, to minutes, piece): ``with_vehicle`` over those minutes
    of that piece.
    """
    name, pieces, car, over, u0, *rest = item
    defects = rest[0] if rest else {}
    sur = load_surrogate()
    sc = build(shared_data_dir() / "Settlements", sur.A, pieces)
    if "creep" in defects:
        factor, first = defects["creep"]
        changed = [i for i in sc.changes() if i >= first]
        sc.data = with_creep(sc.data, sc.starts_ns, changed, factor)
    if "silent" in defects:
        sc.data = with_silence(sc.data, sc.starts_ns[-1], *defects["silent"])
    if "vehicle" in defects:
        load, a, b, first = defects["vehicle"]
        sc.data = with_vehicle(sc.data, sc.starts_ns[first], load, a, b)
    if car == "cut":
        sc.data = without_car(sc.data, sc.starts_ns)
    if u0 == "as_built":
        sur = dataclasses.replace(sur, u0=load_surrogate(AS_BUILT).u0)
    res = Shadow(_config(over), sur).run(sc.data)
    s = score_stream(sc, res, float(over.get("window_s", 60.0)))
    lost, err, sd = s.lost_windows, s.error_m, s.sigma_m
    probs = [round(c.change_probability, 3) for c in res.changes if c.kind == "gap"]
    line = (
        f"  {name:45s} events {len(res.events)}/{len(sc.changes())} lost {lost} "
        + (f"({s.lost_under_car} under the test car) " if s.lost_under_car else "")
        + f"error {np.round(1e3 * err, 2)} mm, 95 % +-{np.round(1.96e3 * sd, 1)} mm"
        + (f", unconfirmed p {probs}" if probs else "")
    )
    verdicts = [s.events_right, lost == 0, s.lost_car_free == 0, s.within, s.covered]
    return name, verdicts, line, (1.96e3 * sd).tolist()


def _config(over: dict[str, Any]) -> Any:
    """Return the shipped parameters with ``over`` replaced (``traffic_hold_s``, ``sun_gradient``)."""
    return load_config().replace(**over)


def print_streams(results: list[Any], title: str, t0: float, verbose: bool = True) -> None:
    """Print ``real_stream`` results (each line, or only the failed ones) and the five rates."""
    for _, r, line, _ in results:
        if verbose or not all(r):
            print(line)
    counts = np.sum([r for _, r, _, _ in results], axis=0)
    n = len(results)
    print(f"{title}: {n} streams in {time.perf_counter() - t0:.0f} s")
    labels = ("events right", "no window lost", "none lost car-free", "within 10 % (or 1 mm)", "95 % holds")
    for label, c in zip(labels, counts, strict=True):
        print(f"  {label:24s} {c}/{n} = {c / n:.3f}")


def real_study(
    mapper: Callable[..., list[Any]],
    verbose: bool,
    car: str = "recorded",
    over: dict[str, Any] | None = None,
    u0: str = "model",
    groups: dict[str, list[tuple[str, list[Piece]]]] | None = None,
) -> None:
    """Score the grid of real-record streams, or the streams of ``groups`` (title -> streams) apart."""
    t0 = time.perf_counter()
    over = over or {}
    if groups is None:
        results = mapper(real_stream, [(name, pieces, car, over, u0) for name, pieces in real_streams()])
        print_streams(results, f"real records, test car {car}, u0 {u0}, {over}", t0, verbose)
        widths = np.array([w for _, _, _, w in results])
        print(f"  final 95 % half-width, median {np.round(np.median(widths, axis=0), 2)} mm")
        return
    items = [
        (title, (name, pieces, car, over, u0))
        for title, streams in groups.items()
        for name, pieces in streams
    ]
    results = mapper(real_stream, [item for _, item in items])
    for title in groups:
        part = [r for r, (t, _) in zip(results, items, strict=True) if t == title]
        if part:
            print_streams(part, f"{title}, {over}", t0, verbose)


def sweep_groups(n: int, cut_share: float, seed: int = 0) -> dict[str, list[tuple[str, list[Piece]]]]:
    """``random_streams`` by how the later record is cut (whole, its first minutes, from minute 3-7)."""
    sur = load_surrogate()
    groups: dict[str, list[tuple[str, list[Piece]]]] = {
        "random streams of the two records, the later record whole": [],
        "random streams of the two records, cut to its first minutes (ending under the test car)": [],
        "random streams of the two records, cut to begin at minute 3-7 (under the test car)": [],
    }
    titles = list(groups)
    for name, pieces in random_streams(n, sur.A, sur.u0, seed=seed, cut_share=cut_share):
        cut = next((p.cut_min for p in pieces if p.cut_min), None)
        groups[titles[0 if cut is None else 1 if cut[0] == 0 else 2]].append((name, pieces))
    return groups


def minutes_study(mapper: Callable[..., list[Any]], over: dict[str, Any]) -> None:
    """Score records minutes apart (one record for the hold) and cut records, 30 s to 2 min windows."""
    t0 = time.perf_counter()
    items = [
        (f"{name} [{w:g} s]", pieces, "recorded", {**over, "window_s": w}, "model")
        for name, pieces in minutes_streams()
        for w in (30.0, 60.0, 120.0)
    ]
    print_streams(mapper(real_stream, items), f"records minutes apart or cut, {over}", t0)


def creep_streams() -> Iterator[tuple[str, list[Piece], int]]:
    """Yield (name, pieces, first creeping piece) of the creep study.

    The pair, the pair after a second quiet record, the day's four records, and the day with the
    10 mm record as it is and only the two later states creeping more.
    """
    yield "ref, lowered at its own time", [Piece("ref", 0.0), Piece("lowered", 0.73)], 1
    yield (
        "ref, ref 1.25 h on, lowered -10 mm at 2.5 h",
        [Piece("ref", 0.0), Piece("ref", 1.25), Piece("lowered", 2.5, (-0.01, -0.01))],
        1,
    )
    day = [
        Piece("ref", 0.0),
        Piece("lowered", 0.73),
        Piece("lowered", 5.07, (-0.01, -0.01), 5.5),
        Piece("lowered", 9.03, (-0.02, -0.02), 7.5),
    ]
    yield "the day: ref, lowered, -20 at 5.07 h, -30 at 9.03 h", day, 1
    yield "the day, only -20 and -30 creeping more", day, 2


def pause_streams() -> Iterator[tuple[str, list[Piece]]]:
    """Yield (name, pieces) of the pause study: a logger pause inside the later record.

    The reference or the 10 mm record 1.25 h or 4 h on (10 mm more through ``A``), silent for 1, 2,
    4 or 8 minutes from minute 2, 4 or 6 (the test car stands over about minutes 2-9): the same
    state on both sides of the pause, or the first part still the old state (the change in it).
    """
    for later, (place, (at, temp_at)), pause, start, in_pause in itertools.product(
        ("ref", "lowered"),
        NEAR_AND_FAR.items(),
        (1, 2, 4, 8),
        (2, 4, 6),
        (False, True),
    ):
        if start + pause > 11:
            continue
        low = (-0.01, -0.01)
        before = (0.0, 0.0) if in_pause else low
        name = f"ref, {later} at {place}, pause {start}-{start + pause} min" + (
            ", the step in it" if in_pause else ""
        )
        yield (
            name,
            [
                Piece("ref", 0.0),
                Piece(later, at, before, temp_at, cut_min=(0, start)),
                Piece(later, at, low, temp_at, cut_min=(start + pause, 13)),
            ],
        )


def more_pause_streams() -> Iterator[tuple[str, list[Piece]]]:
    """Yield the pause study's second set: the reference record paused, both paused, two pauses."""
    low = (-0.01, -0.01)
    for later, (place, (at, temp_at)), (p1, p2) in itertools.product(
        ("ref", "lowered"),
        NEAR_AND_FAR.items(),
        (((2, 4), (7, 9)), ((3, 5), (6, 8)), ((4, 6), (8, 10))),
    ):
        ref_paused = [Piece("ref", 0.0, cut_min=(0, p1[0])), Piece("ref", 0.0, cut_min=(p1[1], 13))]
        name = f"{later} at {place}, pauses {p1} / {p2}"
        yield f"ref paused, {name}", [*ref_paused, Piece(later, at, low, temp_at)]
        yield (
            f"both paused, {name}",
            [
                *ref_paused,
                Piece(later, at, low, temp_at, cut_min=(0, p2[0])),
                Piece(later, at, low, temp_at, cut_min=(p2[1], 13)),
            ],
        )
        yield (
            f"two pauses in the later record, {name}",
            [
                Piece("ref", 0.0),
                Piece(later, at, low, temp_at, cut_min=(0, p1[0])),
                Piece(later, at, low, temp_at, cut_min=(p1[1], p2[0])),
                Piece(later, at, low, temp_at, cut_min=(p2[1], 13)),
            ],
        )


def pause_study(mapper: Callable[..., list[Any]], over: dict[str, Any]) -> None:
    """Score the pause streams (``pause_streams``)."""
    t0 = time.perf_counter()
    items = [(name, pieces, "recorded", over, "model") for name, pieces in pause_streams()]
    print_streams(mapper(real_stream, items), f"a logger pause inside the later record, {over}", t0, False)
    t0 = time.perf_counter()
    items = [(name, pieces, "recorded", over, "model") for name, pieces in more_pause_streams()]
    print_streams(
        mapper(real_stream, items), f"the reference record paused too, or two pauses, {over}", t0, False
    )
    t0 = time.perf_counter()
    later_records = [
        (f"ref, {later} at {place}", [Piece("ref", 0.0), Piece(later, at, (-0.01, -0.01), temp_at)])
        for later in ("ref", "lowered")
        for place, (at, temp_at) in NEAR_AND_FAR.items()
    ]
    items = [
        (
            f"{name}, load cell {c + 1} silent over minutes {a}-{b}",
            pieces,
            "recorded",
            over,
            "model",
            {"silent": (c, a, b)},
        )
        for name, pieces in later_records
        for c in (0, 1)
        for a, b in ((0, 2), (1, 3), (3, 6), (6, 9), (10, 13))
    ]
    print_streams(mapper(real_stream, items), f"one load cell silent in the later record, {over}", t0, False)


def long_streams() -> Iterator[tuple[str, list[Piece], int]]:
    """Yield (name, pieces, first piece of the recording) of one recording longer than the hold.

    Either record three or four times back to back (one 36-48 minute recording, unscreened), from
    the data's start or after the same record 1.25, 4 or 24 h before (the air of 6 h and 7 h for
    the last two), 10 mm lower through ``A`` at the first seam, the second, or each.
    """
    temps = {None: None, 1.25: None, 4.0: 6.0, 24.0: 7.0}
    for rec in ("ref", "lowered"):
        for n in (3, 4):
            for start, temp in temps.items():
                for steps in ("first", "second", "each"):
                    pieces = [] if start is None else [Piece(rec, 0.0)]
                    at0 = 0.0 if start is None else start
                    for i in range(n):
                        dx = -0.01 * {"first": min(i, 1), "second": int(i >= 2), "each": i}[steps]
                        t = None if temp is None else temp + 0.2 * i
                        pieces.append(Piece(rec, at0 + 0.2 * i, (dx, dx), temp_at_h=t))
                    where = "from the start" if start is None else f"after {start:g} h"
                    yield f"{rec} x{n} {where}, -10 mm at {steps}", pieces, len(pieces) - n


def long_study(mapper: Callable[..., list[Any]], over: dict[str, Any]) -> None:
    """Score ``long_streams``, as they are and with a 20 kN vehicle in the recording's minutes 1-7."""
    for load in (0.0, 20e3):
        t0 = time.perf_counter()
        items = [
            (name, pieces, "recorded", over, "model", {"vehicle": (load, 1.0, 7.0, first)} if load else {})
            for name, pieces, first in long_streams()
        ]
        title = f"one recording longer than the hold, vehicle {load / 1e3:g} kN in minutes 1-7, {over}"
        print_streams(mapper(real_stream, items), title, t0, False)


def creep_study(mapper: Callable[..., list[Any]], over: dict[str, Any]) -> None:
    """Score the creep streams with the new states' creep 1 to 4 times the 10 mm record's own."""
    t0 = time.perf_counter()
    items = [
        (f"{name} [creep x{1 + extra:g}]", pieces, "recorded", over, "model", {"creep": (extra, first)})
        for name, pieces, first in creep_streams()
        for extra in (0.0, 0.5, 1.0, 2.0, 3.0)
    ]
    print_streams(mapper(real_stream, items), f"new states creeping, {over}", t0)


#: The ramp study's later record: the 10 mm record copied to 14:36 (``lowered_over``; the day has
#: air readings for three copies in a row there), lowered over minutes from a minute of it.
RAMP_AT_H = 6.0
RAMP_MINUTES = (4, 8, 12, 16, 20, 24, 30)
RAMP_STARTS = (0, 3, 6)
#: The staged lowerings (``--only stages``): (steps, minutes between them), from minute 1, 3 or 6.
STAGES = ((2, 3.0), (4, 2.0), (5, 1.0), (5, 2.0), (10, 1.0))
STAGE_STARTS = (1, 3, 6)


def ramp_stream(
    item: tuple[str, float, float, str, dict[str, Any], int | None],
) -> tuple[str, list[bool], str, list[float]]:
    """Score one ramp stream (a task): the 10 mm event, the ramp reported, nothing lost, the final state.

    Right: the real 10 mm lowering an event at its record, the changes after it (events, or changes
    of probability above 0.99) adding up to the ramp's -20 mm within 2 mm, no window an outlier,
    the final estimate within 10 % of -30 mm and its 95 % interval holding it. Verdicts in
    ``print_streams``' order: "no window lost" counts every outlier, "none lost car-free" those
    that are not the recorded test car parked on the state the shadow then held
    (``twin.loadtest_score.car_excursions``, as the real study counts them).
    """
    name, start, minutes, car, over, stages = item
    sur = load_surrogate()
    pieces = lowered_over(RAMP_AT_H, start, minutes, stages=stages)
    sc = build(shared_data_dir() / "Settlements", sur.A, pieces)
    if car == "cut":
        sc.data = without_recorded_car(sc)
    res = Shadow(_config(over), sur).run(sc.data)
    k1, k2 = sc.starts_ns[1] // W, sc.starts_ns[2] // W
    first = [e for e in res.events if e.window == k1]
    later = [e.size_m for e in res.events if e.window >= k2]
    later += [c.size_m for c in res.changes if c.window >= k2 and c.change_probability > 0.99]
    moved = np.sum(later, axis=0) if later else np.zeros(2)
    truth = sc.truth_m
    err, sd = res.mean_m - truth, np.sqrt(np.diag(res.covariance_m2))
    outliers = [o.end_ns for o in res.outputs if o.reason == "outlier"]
    lost, under_car = len(outliers), car_excursions(sc, res, outliers, W)
    right = len(first) == 1 and bool(np.all(np.abs(moved + 0.02) <= 0.002))
    line = (
        f"  {name:45s} 10 mm event {len(first)}, later {np.round(1e3 * moved, 1)} mm, lost {lost} "
        + (f"({under_car} the test car on a state then held) " if under_car else "")
        + f"error {np.round(1e3 * err, 2)} mm, 95 % +-{np.round(1.96e3 * sd, 1)} mm"
    )
    within = bool(np.all(np.abs(err) <= 0.1 * np.abs(truth)))
    verdicts = [right, lost == 0, lost == under_car, within, bool(np.all(np.abs(err) <= 1.96 * sd))]
    return name, verdicts, line, (1.96e3 * sd).tolist()


def lowering_study(mapper: Callable[..., list[Any]], over: dict[str, Any], stages: bool = False) -> None:
    """Score 20 mm lowerings inside a record hours after the last, the car kept or cut.

    Over 4 to 30 minutes (``--only ramps``), or with ``stages`` in 2 to 10 equal steps one to three
    minutes apart (``--only stages``).
    """
    t0 = time.perf_counter()
    for car in ("recorded", "cut"):
        if stages:
            title = "a lowering in steps"
            items = [
                (f"{n} steps {every:g} min apart from minute {a:g} [car {car}]", a, n * every, car, over, n)
                for (n, every), a in itertools.product(STAGES, STAGE_STARTS)
            ]
        else:
            title = "a lowering over minutes"
            items = [
                (f"from minute {a:g}, over {m:g} min [car {car}]", a, m, car, over, None)
                for a, m in itertools.product(RAMP_STARTS, RAMP_MINUTES)
            ]
        print_streams(mapper(ramp_stream, items), f"{title}, test car {car}, {over}", t0)


def twin_day(item: tuple[int, float, dict, float, float]) -> Any:
    """Score one twin load-test day (a task); ``creep``: the new states creeping (``with_creep``)."""
    seed, sun, over, monitor_days, creep = item
    sur = load_surrogate()
    data, truth = load_test_day(seed, LoadTestDay(vertical_gradient_k=sun, monitor_days=monitor_days), sur)
    if creep:
        data = creeping(data, truth, creep)
    return score_day(Shadow(_config(over), sur).run(data), truth)


def scheduled_twin_day(item: tuple[int, float, dict, float]) -> Any:
    """Score one twin day on 2022-04-11's own schedule (``scheduled_day``; a task; ``rate``: Hz)."""
    seed, sun, over, rate = item
    sur = load_surrogate()
    data, truth = scheduled_day(seed, LoadTestDay(vertical_gradient_k=sun, rate_hz=rate), sur)
    return score_day(Shadow(_config(over), sur).run(data), truth)


def twin_study(
    mapper: Callable[..., list[Any]],
    seeds: int,
    verbose: bool,
    over: dict[str, Any] | None = None,
    monitor_days: float = 0.0,
    creep: float = 0.0,
    schedule: float = 0.0,
) -> None:
    """Score the twin's days with and without the sun; ``schedule``: on 2022-04-11's, at this rate (Hz)."""
    over = over or {}
    for sun in (4.0, 0.0):
        t0 = time.perf_counter()
        if schedule:
            scores = mapper(scheduled_twin_day, [(seed, sun, over, schedule) for seed in range(seeds)])
        else:
            scores = mapper(twin_day, [(seed, sun, over, monitor_days, creep) for seed in range(seeds)])
        for seed, s in enumerate(scores):
            if verbose or not s.passed:
                err = np.round(1e3 * s.error_m, 2)
                print(f"  seed {seed}: events {s.events_right} lost {s.lost_windows} error {err} mm")
        rates = {
            "events right": np.mean([s.events_right for s in scores]),
            "no window lost": np.mean([not s.lost_windows for s in scores]),
            "within 10 %": np.mean([s.within_10pct for s in scores]),
            "95 % holds": np.mean([s.covered for s in scores]),
        }
        err = np.array([s.error_m for s in scores]) * 1e3
        day = f"twin day on 2022-04-11's schedule at {schedule:g} Hz" if schedule else "twin load-test day"
        head = f"{day}, sun {sun:g} K, {monitor_days:g} days monitored before, {over}"
        head += f", new states creeping {creep:g} x the 10 mm record's rate" if creep else ""
        print(f"{head}: {seeds} seeds in {time.perf_counter() - t0:.0f} s")
        for label, r in rates.items():
            print(f"  {label:16s} {r:.3f}")
        print(f"  final error mean {np.round(err.mean(axis=0), 2)} mm, sd {np.round(err.std(axis=0), 2)} mm")
        half = 1.96e3 * np.array([s.sigma_m for s in scores])
        print(f"  final 95 % half-width, median {np.round(np.median(half, axis=0), 2)} mm")


def continuous_day(item: tuple[int, bool, str]) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """Three days of monitoring under the sun (4 K), a 0.7 mm offset: error, sd, events, fitted g (a task).

    ``item``: seed, the sun term on, its fit (``sun_gradient_fit``).
    """
    from bridge_shadow.twin.simulate import simulate

    seed, term, fit = item
    sur = load_surrogate()
    data, truth = simulate(3.0, 0.1, seed, {"settlement_offset": 7e-4, "vertical_gradient": 4.0})
    shadow = Shadow(load_config().replace(sun_gradient=term, sun_gradient_fit=fit), sur)
    res = shadow.run(data)
    err = res.mean_m - np.array(truth["settlement"]["end_m"])
    g = shadow.fit.beta[:, -1] / sur.thermal["vertical_gradient"] if term else np.full(2, np.nan)
    return err, np.sqrt(np.diag(res.covariance_m2)), len(res.events), g


def continuous_study(mapper: Callable[..., list[Any]], seeds: int, fit: str = "per_bearing") -> None:
    """Run the twin's three sunny days of continuous monitoring, the sun term off and on (``fit``)."""
    for term in (False, True):
        t0 = time.perf_counter()
        out = mapper(continuous_day, [(seed, term, fit) for seed in range(seeds)])
        err = 1e3 * np.array([o[0] for o in out])
        sd = 1e3 * np.array([o[1] for o in out])
        print(
            f"three sunny days monitored, sun term {f'on ({fit})' if term else 'off'}: {seeds} seeds in "
            f"{time.perf_counter() - t0:.0f} s"
        )
        print(f"  days without a false event {np.mean([o[2] == 0 for o in out]):.3f}")
        print(f"  95 % holds                 {np.mean(np.all(np.abs(err) <= 1.96 * sd, axis=1)):.3f}")
        worst = np.round(np.abs(err).max(axis=0), 3)
        print(f"  final error mean {np.round(err.mean(axis=0), 3)} mm, largest {worst} mm")
        print(f"  final 95 % half-width, median {np.round(np.median(1.96 * sd, axis=0), 2)} mm")
        if term:
            g = np.array([o[3] for o in out])
            spread = np.round(g.std(axis=0), 2)
            print(f"  sun term g {np.round(g.mean(axis=0), 2)} K (sd over seeds {spread}), twin 4 K")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument(
        "--only",
        choices=(
            "real",
            "twin",
            "schedule",
            "continuous",
            "minutes",
            "creep",
            "pauses",
            "sweep",
            "inside",
            "ramps",
            "stages",
            "long",
        ),
        help="one study (continuous: three sunny days of monitoring, sun term off and on; minutes: the "
        "two records minutes apart or cut short, in 30 s, 1 min and 2 min windows; creep: the new "
        "states' reactions creeping after the lowering, 1 to 4 times the 10 mm record's own; pauses: a "
        "logger pause of minutes inside the later record; schedule: the twin's day cut to 2022-04-11's "
        "own recordings, with its lowering and three-hour ambient records; sweep: --seeds random streams "
        "of the two records, any order, spacing and step; inside: --seeds random streams with one or two "
        "settlements inside the later record; ramps: a 20 mm lowering over 4 to 30 minutes of a record "
        "hours after the last; stages: the same in 2 to 10 equal steps; long: one recording longer than "
        "the traffic hold, steps at its seams, with and without a vehicle over the warm-up; none of "
        "these by default)",
    )
    ap.add_argument("--workers", type=int, default=None, help="Dask workers (default: one per core)")
    ap.add_argument(
        "--car",
        choices=("recorded", "cut"),
        default="recorded",
        help="real study: the records as recorded, or with the test car's samples cut (a what-if)",
    )
    ap.add_argument(
        "--hold", type=float, default=None, help="traffic_hold_s (default: shipped; 0: no screen)"
    )
    ap.add_argument(
        "--u0",
        choices=("model", "as_built"),
        default="model",
        help="real study: the surrogate's u0 (the reference record's car-free level) or the as-built FE's",
    )
    sun = ap.add_mutually_exclusive_group()
    sun.add_argument(
        "--sun-term", action="store_true", help="the shadow with its sun term (sun_gradient: true, shipped)"
    )
    sun.add_argument(
        "--sun-off", action="store_true", help="the shadow without its sun term (sun_gradient: false)"
    )
    ap.add_argument(
        "--sun-prior",
        nargs=2,
        type=float,
        metavar=("MEAN", "SD"),
        help="the prior of the sun term's g in K (default: shipped, 0 and 6.75)",
    )
    ap.add_argument(
        "--sun-fit",
        choices=("average", "deck", "per_bearing"),
        help="the sun term's fit, sun_gradient_fit (default: shipped, average: one g of the deck, "
        "averaged over no term, the deck's g and a g of each bearing's own by their evidence; deck: "
        "one g of the deck where its Bayes factor reaches sun_gradient_min_bayes_factor; per_bearing: "
        "a g of each bearing's own, always in)",
    )
    ap.add_argument(
        "--monitor-days",
        type=float,
        default=0.0,
        help="twin study: days of continuous monitoring before the load-test day (default 0)",
    )
    ap.add_argument(
        "--creep",
        type=float,
        default=0.0,
        help="twin study: each new state's reactions rise through its record at this many times the "
        "real 10 mm record's own 0.05 / 0.1 kN a minute (with_creep; default 0: none)",
    )
    ap.add_argument(
        "--rate",
        type=float,
        default=0.2,
        help="schedule study: force samples per second per channel (default 0.2; the real 100)",
    )
    ap.add_argument(
        "--cut-share",
        type=float,
        default=0.25,
        help="sweep study: share of the later records cut to their first 6-10 minutes or to begin at "
        "minute 3-7 (default 0.25; the rates are printed for whole and cut records apart)",
    )
    ap.add_argument(
        "--stream-seed",
        type=int,
        default=0,
        help="sweep and inside studies: the random streams' seed (default 0, the streams the rules were "
        "read on; another draws streams none of them was written on)",
    )
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args()
    over: dict[str, Any] = {}
    if args.hold is not None:
        over["traffic_hold_s"] = args.hold
    if args.sun_term or args.sun_off:
        over["sun_gradient"] = bool(args.sun_term)
    if args.sun_off and (args.sun_prior or args.sun_fit):
        ap.error("--sun-prior and --sun-fit set the sun term, which --sun-off leaves out")
    if args.sun_prior:
        over["sun_gradient_prior_mean_k"], over["sun_gradient_prior_sd_k"] = args.sun_prior
    if args.sun_fit:
        over["sun_gradient_fit"] = args.sun_fit
    with dask_client(workers=args.workers) as client:
        mapper = client_mapper(client)
        if args.only in (None, "real"):
            real_study(mapper, args.verbose, args.car, over, args.u0)
        if args.only in (None, "twin"):
            twin_study(mapper, args.seeds, args.verbose, over, args.monitor_days, args.creep)
        if args.only == "schedule":
            twin_study(mapper, args.seeds, args.verbose, over, schedule=args.rate)
        if args.only == "continuous":
            continuous_study(mapper, args.seeds, args.sun_fit or load_config().sun_gradient_fit)
        if args.only == "minutes":
            minutes_study(mapper, over)
        if args.only == "creep":
            creep_study(mapper, over)
        if args.only == "pauses":
            pause_study(mapper, over)
        if args.only == "long":
            long_study(mapper, over)
        if args.only in ("ramps", "stages"):
            lowering_study(mapper, over, stages=args.only == "stages")
        if args.only == "inside":
            sur = load_surrogate()
            streams = random_inside_streams(args.seeds, sur.A, sur.u0, args.stream_seed)
            inside = {"settlements inside a record": list(streams)}
            real_study(mapper, args.verbose, args.car, over, args.u0, inside)
        if args.only == "sweep":
            real_study(
                mapper,
                args.verbose,
                args.car,
                over,
                args.u0,
                sweep_groups(args.seeds, args.cut_share, args.stream_seed),
            )


if __name__ == "__main__":
    main()
