"""What the withheld records should show: each lowered state of 2022-04-11, read under a sun.

The public records of 2022-04-11 are both from the morning (08:36 and 09:20 local); the records
after 20 mm and 30 mm (13:39 and 17:37) are withheld. A sunny afternoon warms the deck's top: a
linear vertical temperature difference loads the two bearings exactly as a lowering of both does
(the surrogate's ``thermal.vertical_gradient`` and ``A [1, 1]`` in the same ratio), so a shadow
without its sun term reads it as settlement. This prints, before those records are read, how far:

- the common mode's reading per kelvin of vertical difference, ``A^-1 vertical_gradient`` (mm/K);
- on the twin's day as its loggers ran (``twin.loadtest.scheduled_day``: a 10 mm step inside each
  lowering record, three-hour ambient records between) with the sun's vertical difference at full
  clear sky of 0 to 8 K (the twin's ``vertical_gradient``; 4 K is its default): at the end of each
  load record after a lowering, the common mode's error (mean and sd over seeds), that error in
  kelvin of vertical difference, the 95 % half-width of the common mode, and how often the interval
  holds the truth;
- ``--day records``: the same on the four load records alone at their real times (08:36, 09:20,
  13:39, 17:37; ``twin.loadtest.load_test_day``, nothing between them): the stream a user has who
  was given the load records and not the ambient hours between them;
- ``--sun off|average|deck|per_bearing``: read without the shadow's sun term, or with the fit
  named (``sun_gradient_fit``), instead of the shipped defaults (the term on, ``average``).

Usage::

    .venv/bin/python benchmarks/withheld_states.py [--seeds 50] [--suns 0 2 4 6 8] [--workers N]
        [--day schedule|records] [--sun off|average|deck|per_bearing]

Seeds run as tasks on Dask (``bridge_shadow.engine``: a local cluster of ``--workers`` processes,
default one per core).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bridge_shadow.engine import client_mapper, dask_client
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.loadtest import (
    SCHEDULE_2022_04_11,
    LoadTestDay,
    load_test_day,
    scheduled_day,
)

W_NS = 60 * 10**9
#: The load records after a lowering (indices into the schedule): the states the records show.
STATE_RECORDS = [
    i
    for i, (kind, _, _) in enumerate(SCHEDULE_2022_04_11)
    if kind == "load" and any(k == "lowering" for k, _, _ in SCHEDULE_2022_04_11[:i])
]
LOAD_RECORDS = [i for i, (kind, _, _) in enumerate(SCHEDULE_2022_04_11) if kind == "load"]
#: The load records' local start hours: the four-record stream (``--day records``).
RECORD_H = tuple(
    sum(float(x) / 60**j for j, x in enumerate(SCHEDULE_2022_04_11[i][1].split(":"))) for i in LOAD_RECORDS
)
ONES = np.ones(2) / 2.0  # the common mode: the mean of the two supports


def read_states(item: tuple[int, float, str, str | None]) -> np.ndarray:
    """One seed: (records, 3) common-mode error (m), its 95 % half-width (m), the truth (m).

    ``item``: seed, the twin's sun (K), the day, the sun term's fit (``off``: none; None: shipped).
    """
    seed, sun, day, fit = item
    sur = load_surrogate()
    if day == "records":
        data, truth = load_test_day(seed, LoadTestDay(record_h=RECORD_H, vertical_gradient_k=sun), sur)
        records = [1, 2, 3]
    else:
        data, truth = scheduled_day(seed, LoadTestDay(vertical_gradient_k=sun, rate_hz=0.2), sur)
        records = STATE_RECORDS
    config = load_config()
    if fit == "off":
        config = config.replace(sun_gradient=False)
    elif fit is not None:
        config = config.replace(sun_gradient=True, sun_gradient_fit=fit)
    res = Shadow(config, sur).run(data)
    out = []
    for i in records:
        end = truth["record_end_ns"][i]
        last = [o for o in res.outputs if o.updated and o.end_ns <= end + W_NS][-1]
        x = float(ONES @ np.asarray(truth["record_x_m"][i], float))
        half = 1.96 * float(np.sqrt(ONES @ last.covariance_m2 @ ONES))
        out.append((float(ONES @ last.mean_m) - x, half, x))
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--suns", type=float, nargs="+", default=[0.0, 2.0, 4.0, 6.0, 8.0], metavar="K")
    ap.add_argument("--workers", type=int, default=None, help="Dask workers (default: one per core)")
    ap.add_argument(
        "--day",
        choices=("schedule", "records"),
        default="schedule",
        help="the day as its loggers ran (default), or its four load records alone",
    )
    ap.add_argument(
        "--sun",
        choices=("off", "average", "deck", "per_bearing"),
        default=None,
        help="the shadow's sun term: off, or its fit (sun_gradient_fit; default: shipped, average)",
    )
    args = ap.parse_args()
    sur = load_surrogate()
    per_k = np.linalg.solve(sur.A, np.asarray(sur.thermal["vertical_gradient"], float))
    print(
        f"common mode read per K of vertical difference (top warmer): {1e3 * float(ONES @ per_k):+.3f} mm "
        f"(south {1e3 * per_k[0]:+.3f}, north {1e3 * per_k[1]:+.3f}; shipped surrogate)"
    )
    names = [SCHEDULE_2022_04_11[i][1][:5] for i in STATE_RECORDS]
    with dask_client(workers=args.workers) as client:
        mapper = client_mapper(client)
        for sun in args.suns:
            t0 = time.perf_counter()
            items = [(seed, sun, args.day, args.sun) for seed in range(args.seeds)]
            r = np.array(mapper(read_states, items))
            took = time.perf_counter() - t0
            what = "the day as its loggers ran" if args.day == "schedule" else "the four load records alone"
            term = f", sun term {args.sun}" if args.sun else ", shipped"
            print(f"twin sun {sun:g} K at full clear sky, {what}{term}, {args.seeds} seeds in {took:.0f} s")
            for j, name in enumerate(names):
                err, half, x = r[:, j, 0], r[:, j, 1], r[:, j, 2]
                kelvin = err.mean() / float(ONES @ per_k)
                print(
                    f"  {name} record, {1e3 * x.mean():+.0f} mm: error {1e3 * err.mean():+.2f} mm "
                    f"(sd {1e3 * err.std():.2f}; {kelvin:+.1f} K of vertical difference), 95 % "
                    f"+-{1e3 * np.median(half):.2f} mm, holds the truth in {np.mean(np.abs(err) <= half):.2f}"
                )


if __name__ == "__main__":
    main()
