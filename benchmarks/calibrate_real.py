"""Calibration on the real 2022-04-11 pair: wall time, FE solves, how the answer moves with the assumptions.

Runs ``config/calibration.yaml`` (default mesh, every explanation) and prints its wall and CPU time,
the number of FE solves, and the time as a multiple of one FE solve of the bridge measured in the
same run (the issue's budget: under 2 minutes on 2 cores). Then the same calibration under the
assumptions the answer depends on: the jacks' accuracy (0.5 mm in the file, 0.2 mm here) and the
baseline change between the records (an uncertainty in the file, a modelled linear drift here),
each with the evidence table's leading rows and what they imply for the south-north split.

Run: ``.venv/bin/python benchmarks/calibrate_real.py [--quick]`` (``--quick``: the timed run only).
"""

from __future__ import annotations

import copy
import sys
import time

import numpy as np

from bridge_shadow.calibrate.run import calibrate, default_spec_path
from bridge_shadow.calibrate.spec import load_spec
from bridge_shadow.model.config import load_bridge_config
from bridge_shadow.model.solution import solve_bridge


def _table(result, rows: int = 6) -> None:
    print(
        f"  {'explanation':<20} {'dlogZ':>6} {'P':>5} {'k_common S/N kN/mm':>19} {'k_diff':>7} "
        f"{'x S/N mm':>14} {'ref +-x mm':>10}"
    )
    for r in result.table()[:rows]:
        kc = np.array(r["common_stiffness_n_per_m"]) / 1e6
        x = np.array(r["in_sample"][0]["x_m"]) * 1e3
        ref = r.get("reference", {}).get("half_difference_m", float("nan")) * 1e3
        print(
            f"  {r['name']:<20} {r['delta_log_evidence']:6.2f} {r['probability']:5.2f} "
            f"{kc[0]:9.2f}/{kc[1]:<9.2f}"
            f" {r['differential_stiffness_n_per_m'] / 1e6:7.2f} {x[0]:6.2f}/{x[1]:<7.2f} {ref:10.2f}"
        )


def main(quick: bool) -> None:
    """Print the timed run and the variants."""
    cfg = load_bridge_config()
    spec = load_spec(default_spec_path())
    t0 = time.perf_counter()
    solve_bridge(cfg, spec.mesh)
    one_solve = time.perf_counter() - t0
    c0, t0 = time.process_time(), time.perf_counter()
    result = calibrate(spec, cfg)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(
        f"calibration ({spec.mesh} mesh, {len(spec.explanations)} explanations): {wall:.1f} s wall, "
        f"{cpu:.1f} s CPU, {result.store.solves} FE solves; one FE solve {one_solve:.2f} s -> "
        f"{wall / one_solve:.0f} solve-times"
    )
    print(f"chosen: {result.chosen}")
    _table(result)
    if quick:
        return
    variants = {
        "jacks 0.2 mm (sd per bearing)": lambda s: [
            setattr(p, "imposed_sd_m", np.array([2e-4, 2e-4])) for p in s.pairs
        ],
        "baseline change: linear drift": lambda s: setattr(s, "baseline_change", "linear"),
    }
    for label, change in variants.items():
        s = copy.deepcopy(spec)
        change(s)
        r = calibrate(s, cfg)
        d = r.pairs[0].change
        print(
            f"\n{label}: dR = {d.dR_n[0] / 1e3:+.2f} +- {d.sd_n[0] / 1e3:.2f} / {d.dR_n[1] / 1e3:+.2f} +- "
            f"{d.sd_n[1] / 1e3:.2f} kN; chosen {r.chosen}"
        )
        _table(r)


if __name__ == "__main__":
    main("--quick" in sys.argv[1:])
