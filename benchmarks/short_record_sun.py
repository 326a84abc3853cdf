"""A small lowering in a short record hours after the reference one, on the twin's sunny day.

The real-record streams that miss a 3 mm lowering in a short morning record ("Where it falls
short") copy the 08:36 reference record's forces to a later hour and give them that hour's air: the
sun the forces carry never changes while the sun covariate says it did, so they cannot tell an
honest reading of the sun from a wrong one. The twin's load-test day (``twin.loadtest.load_test_day``)
puts the sun's vertical temperature difference into the forces as the covariate reads it. This
prints, over seeds, for the reference record at 08:36 followed by one record at ``--hour``
(local) lowered by ``--step`` mm on both supports and cut to its first ``--minutes`` minutes
(2.58: car-free, before the test car parks):

- how often the final 95 % interval holds the truth (both supports);
- how often the final estimate is within 10 % of the step or 1 mm, whichever is larger;
- how often the lowering is one event;
- the mean error of the common mode, mm.

Usage::

    .venv/bin/python benchmarks/short_record_sun.py [--seeds 100] [--hour 9.85] [--step -3]
        [--minutes 2.58] [--sun-k 4] [--sun off] [--workers N]

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
from bridge_shadow.twin.loadtest import LoadTestDay, load_test_day

REFERENCE_H = 8.6  # 08:36 local, the reference record's start


def one_day(item: tuple[int, float, float, float, float, bool]) -> tuple[bool, bool, int, float]:
    """One seed: (interval holds the truth, within 10 % or 1 mm, events, common-mode error in m)."""
    seed, hour, step_m, minutes, sun_k, sun_off = item
    sur = load_surrogate()
    spec = LoadTestDay(
        record_h=(REFERENCE_H, hour), steps_m=((step_m, step_m),), vertical_gradient_k=sun_k, rate_hz=1.0
    )
    data, truth = load_test_day(seed, spec, sur)
    end = int(truth["record_start_ns"][1]) + round(minutes * 60e9)
    config = load_config()
    if sun_off:
        config = config.replace(sun_gradient=False)
    res = Shadow(config, sur).run(data.select(lambda t: t < end))
    x = np.asarray(truth["record_x_m"][1], float)
    err = res.mean_m - x
    sd = np.sqrt(np.diag(res.covariance_m2))
    covered = bool(np.all(np.abs(err) <= 1.96 * sd))
    within = bool(np.all(np.abs(err) <= max(0.1 * abs(step_m), 1e-3)))
    return covered, within, len(res.events), float(err.mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--hour", type=float, default=9.85, help="the later record's local start (default 09:51)")
    ap.add_argument("--step", type=float, default=-3.0, help="the lowering of both supports, mm")
    ap.add_argument("--minutes", type=float, default=2.58, help="the later record's length, min (12: whole)")
    ap.add_argument("--sun-k", type=float, default=4.0, help="the twin's vertical difference at full sun, K")
    ap.add_argument("--sun", choices=("on", "off"), default="on", help="the shadow's sun term (default on)")
    ap.add_argument("--workers", type=int, default=None, help="Dask workers (default: one per core)")
    args = ap.parse_args()
    items = [
        (seed, args.hour, args.step * 1e-3, args.minutes, args.sun_k, args.sun == "off")
        for seed in range(args.seeds)
    ]
    t0 = time.perf_counter()
    with dask_client(workers=args.workers) as client:
        r = client_mapper(client)(one_day, items)
    took = time.perf_counter() - t0
    covered, within, events, err = (np.array(c) for c in zip(*r, strict=True))
    print(
        f"reference 08:36, then {args.minutes:g} min at {args.hour:g} h lowered {args.step:g} mm, twin sun "
        f"{args.sun_k:g} K, sun term {args.sun}, {args.seeds} seeds in {took:.0f} s: interval holds the "
        f"truth {covered.sum()}, within 10 % or 1 mm {within.sum()}, one event {np.sum(events == 1)}, "
        f"common-mode error {1e3 * err.mean():+.2f} mm (sd {1e3 * err.std():.2f})"
    )


if __name__ == "__main__":
    main()
