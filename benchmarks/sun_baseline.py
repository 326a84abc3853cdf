"""The baseline's change between records hours apart: the drift extrapolated, or the deck's sun.

On the twin's four load records at 2022-04-11's times (08:36, 09:20, 13:40, 17:38; a 10 mm step
in each gap; the sun's vertical temperature difference at full clear sky of 0, 4 and 8 K), read
through the shipped surrogate (the twin's own model) with ``baseline_change`` ``uncertainty``
(the default: the drifts seen within the records over the hours between) and ``sun`` (the deck's
vertical difference under the clear-sky sun and the day's clearness, with the sun term's prior;
``calibrate.change``):

- ``calibrate --check``: each later record against the 08:36 reference (13:40: -20 mm, 17:38:
  -30 mm), common mode;
- ``gap``'s levels: each step between consecutive records (-10 mm each), the mean of the two
  supports' errors and half-widths.

Printed per case: the error's mean (sd) over seeds, the median 95 % half-width, and how often
every interval holds the truth.

Usage::

    .venv/bin/python benchmarks/sun_baseline.py [--seeds 30] [--suns 0 4 8] [--workers N]

Seeds run as tasks on Dask (``bridge_shadow.engine``: a local cluster of ``--workers`` processes,
default one per core).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bridge_shadow.calibrate.change import SunBaseline, measured_change, record_level
from bridge_shadow.calibrate.check import check_pair
from bridge_shadow.engine import client_mapper, dask_client
from bridge_shadow.gap.levels import free_steps, level_pairs
from bridge_shadow.gap.records import Record
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.twin.loadtest import LoadTestDay, _cut, load_test_day

NS = 1_000_000_000
RECORD_S = 720
HOURS = (8 + 36 / 60, 9 + 20 / 60, 13 + 40 / 60, 17 + 38 / 60)
TREATMENTS = ("uncertainty", "sun")


def one_day(item: tuple[int, float]) -> list[tuple[float, float, bool]]:
    """One seed: (error m, 95 % half-width m, held) per case of ``case_names()``."""
    seed, sun_k = item
    sur = load_surrogate()
    sun = SunBaseline(sur.thermal["vertical_gradient"])
    spec = LoadTestDay(record_h=HOURS, vertical_gradient_k=sun_k, rate_hz=10.0)
    data, truth = load_test_day(seed, spec, sur)
    starts = [int(s) for s in truth["record_start_ns"]]
    x = np.asarray(truth["record_x_m"], float)
    out = []
    levels = [record_level(_cut(data, [(s, s + RECORD_S * NS)])) for s in starts]
    for i in (2, 3):
        for how in TREATMENTS:
            c = check_pair(
                how, measured_change(levels[0], levels[i], how, sun), sur, x[i] - x[0], np.zeros(2)
            )
            out.append((c.common_m - float(np.mean(x[i] - x[0])), 1.96 * c.common_sd_m, all(c.held())))
    records = [Record(i, 0, 0, s, s + RECORD_S * NS) for i, s in enumerate(starts)]
    steps = {
        how: free_steps(level_pairs(data, records, [], baseline_change=how, sun=sun)[0], sur)
        for how in TREATMENTS
    }
    for k in (1, 2, 3):
        for how in TREATMENTS:
            st = steps[how][k - 1]
            err = np.asarray(st["x_m"]) - (x[k] - x[k - 1])
            half = 1.96 * np.asarray(st["sigma_m"])
            out.append((float(np.mean(err)), float(np.mean(half)), bool(np.all(np.abs(err) <= half))))
    return out


def case_names() -> list[str]:
    """Return the names of the cases ``one_day`` returns, in order."""
    names = [f"check 08:36 -> {t} ({how})" for t in ("13:40", "17:38") for how in TREATMENTS]
    names += [
        f"gap step {a} -> {b} ({how})"
        for a, b in zip(("08:36", "09:20", "13:40"), ("09:20", "13:40", "17:38"), strict=True)
        for how in TREATMENTS
    ]
    return names


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--suns", type=float, nargs="+", default=[0.0, 4.0, 8.0], metavar="K")
    ap.add_argument("--workers", type=int, default=None, help="Dask workers (default: one per core)")
    args = ap.parse_args()
    with dask_client(workers=args.workers) as client:
        mapper = client_mapper(client)
        for sun_k in args.suns:
            t0 = time.perf_counter()
            r = np.array(mapper(one_day, [(seed, sun_k) for seed in range(args.seeds)]))
            took = time.perf_counter() - t0
            print(f"twin sun {sun_k:g} K at full clear sky, {args.seeds} seeds in {took:.0f} s")
            for j, name in enumerate(case_names()):
                err, half, held = r[:, j, 0], r[:, j, 1], r[:, j, 2]
                print(
                    f"  {name:36s} error {1e3 * err.mean():+.2f} (sd {1e3 * err.std():.2f}) mm, "
                    f"95 % +-{1e3 * np.median(half):.2f} mm, holds {held.mean():.2f}"
                )


if __name__ == "__main__":
    main()
