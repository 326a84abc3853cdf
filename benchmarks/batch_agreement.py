"""The online shadow against the paper's batch method: equal at the end of a record, close during it.

For ``--seeds`` truth-twin records without a settlement event (forces every 5 s, the committed
surrogate), every ``--every`` hours:

- the *online* value: the posterior the shadow published for the window at that time, in a run
  over the whole record (curve, lambda and noise model as refitted on their schedule so far);
- the *batch* value: the paper's batch method (``estimate.settlement.batch.paper_batch``, dense and direct) on
  the windows up to that time, with the same lambda and slope prior as a shadow that stops there.

Printed: the largest and the median ``|online - batch| / sigma_batch`` per support over all
checkpoints, the ratio of the online to the batch sigma, and at the end of the records the
largest difference in sigmas (rounding). Usage::

    .venv/bin/python benchmarks/batch_agreement.py [--seeds 10] [--days 3] [--every 6]
"""

from __future__ import annotations

import argparse

import numpy as np

from bridge_shadow.estimate import Shadow, ShadowConfig
from bridge_shadow.estimate.settlement.batch import paper_batch_of_run
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries
from bridge_shadow.twin.simulate import simulate


def prefix(data: MonitoringData, end_ns: int) -> MonitoringData:
    """Return the messages stamped before ``end_ns``."""
    forces = {}
    for ch, f in data.forces.items():
        m = f.stamp_ns < end_ns
        forces[ch] = ForceSeries(f.stamp_ns[m], f.force_n[m], f.frame_id[m], f.log_ns[m])
    t = data.temperature
    m = t.stamp_ns < end_ns
    return MonitoringData(forces, TemperatureSeries(t.stamp_ns[m], t.temp_c[m], t.variance[m], t.frame_id[m]))


def batch_of(shadow: Shadow, res) -> tuple[np.ndarray, np.ndarray]:
    """Return the paper's batch posterior on the windows ``res`` used (the shadow's lambda, prior)."""
    b = paper_batch_of_run(shadow, res)
    return b.mean_m, b.covariance_m2


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--days", type=float, default=3.0)
    parser.add_argument("--every", type=float, default=6.0, help="hours between checkpoints")
    args = parser.parse_args()
    sur = load_surrogate()
    dev, ratio, final = [], [], []
    for seed in range(args.seeds):
        data, truth = simulate(days=args.days, rate_hz=0.2, seed=500 + seed, surrogate=sur)
        whole = Shadow(ShadowConfig(), sur)
        res = whole.run(data)
        if res.events:
            continue
        h = res.history()
        mean, cov = batch_of(whole, res)
        final.append((np.abs(res.mean_m - mean) / np.sqrt(np.diag(cov))).max())
        for hours in np.arange(args.every, 24 * args.days, args.every):
            end = truth["start_ns"] + int(hours * 3600e9)
            part = Shadow(ShadowConfig(), sur)
            part_res = part.run(prefix(data, end))
            b_mean, b_cov = batch_of(part, part_res)
            i = np.searchsorted(h["end_ns"], part_res.outputs[-1].end_ns)
            sd = np.sqrt(np.diag(b_cov))
            dev.append(np.abs(h["mean_m"][i] - b_mean) / sd)
            ratio.append(np.sqrt(np.diag(h["covariance_m2"][i])) / sd)
    dev, ratio = np.array(dev), np.array(ratio)
    print(f"{len(final)} records of {args.days:g} days, checkpoints every {args.every:g} h ({len(dev)})")
    print(
        f"online - batch during the record, in batch sigmas [south, north]: median "
        f"{np.median(dev, axis=0).round(2)}, 95th percentile {np.percentile(dev, 95, axis=0).round(2)}, "
        f"max {dev.max(axis=0).round(2)}"
    )
    print(
        f"online sigma / batch sigma: median {np.median(ratio, axis=0).round(3)}, "
        f"range {ratio.min(axis=0).round(3)} .. {ratio.max(axis=0).round(3)}"
    )
    print(f"at the end (after flush): largest |online - batch| / sigma {max(final):.1e}")


if __name__ == "__main__":
    main()
