"""Detection rates of the gap diagnosis over twin seeds, at realistic and edge magnitudes.

The measurement behind the detection table (moved out of the test suite, which keeps a short
check in ``test/test_gap_detection.py``). An effect counts as found when ``best`` is the injected
effect or a reported indistinguishable group contains it; the clean record counts as right when
``best`` is ``none``. Usage::

    .venv/bin/python benchmarks/gap_detection.py [--seeds 10] [--rate 0.1]
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np

from bridge_shadow.effects import EFFECT_NAMES, EFFECTS
from bridge_shadow.gap.diagnose import diagnose
from bridge_shadow.twin.simulate import simulate


def rates(level: str, seeds: range, rate_hz: float) -> dict[str, tuple[float, float, Counter]]:
    """Per effect: share found, median held-out reduction, and the answers given."""
    out = {}
    for name in ("none", *EFFECT_NAMES):
        found, reductions, bests = 0, [], Counter()
        for seed in seeds:
            eff = {} if name == "none" else {name: getattr(EFFECTS[name], level)}
            data, _ = simulate(3.0, rate_hz, seed, eff)
            s = diagnose(data).summary
            group = [s["best"], *s["indistinguishable_from"]]
            found += (s["best"] == "none") if name == "none" else (name in group)
            bests[s["best"] if len(group) == 1 else "+".join(sorted(group))] += 1
            if name != "none":
                reductions.append(
                    next(c for c in s["candidates"] if c["effect"] == name)["heldout_reduction"]["total"]
                )
        out[name] = (found / len(seeds), float(np.median(reductions)) if reductions else float("nan"), bests)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="seeds from 200 on (default 3)")
    parser.add_argument("--rate", type=float, default=0.1, help="force rate, Hz (default 0.1)")
    args = parser.parse_args()
    seeds = range(200, 200 + args.seeds)
    t0 = time.perf_counter()
    table = {level: rates(level, seeds, args.rate) for level in ("realistic", "edge")}
    print(f"seeds {list(seeds)}, 3 days, forces at {args.rate:g} Hz ({time.perf_counter() - t0:.0f} s)")
    print(f"{'effect':<21}{'realistic':>10}{'red.':>6}{'edge':>7}{'red.':>6}  answers at edge")
    for name in ("none", *EFFECT_NAMES):
        r, e = table["realistic"][name], table["edge"][name]
        print(f"{name:<21}{r[0]:>10.2f}{r[1]:>6.2f}{e[0]:>7.2f}{e[1]:>6.2f}  {dict(e[2])}")


if __name__ == "__main__":
    main()
