"""Detection rates of the gap diagnosis over several twin seeds, at realistic and edge magnitudes.

A slow check and the measurement behind the detection table: run with ``-s`` to see the table,
``GAP_DETECTION_SEEDS=10`` for more seeds. An effect counts as found when ``best`` is the
injected effect or a reported indistinguishable group contains it; the clean record counts as
right when ``best`` is ``none``.
"""

from __future__ import annotations

import os
from collections import Counter

import numpy as np
import pytest

from bridge_shadow.effects import EFFECT_NAMES, EFFECTS
from bridge_shadow.gap.diagnose import diagnose

twin = pytest.importorskip("bridge_shadow.twin.simulate")

SEEDS = range(200, 200 + int(os.environ.get("GAP_DETECTION_SEEDS", "3")))
RATE_HZ = float(os.environ.get("GAP_DETECTION_RATE_HZ", "0.1"))


def _rates(level: str) -> dict[str, tuple[float, float, Counter]]:
    out = {}
    for name in ("none", *EFFECT_NAMES):
        found, reductions, bests = 0, [], Counter()
        for seed in SEEDS:
            eff = {} if name == "none" else {name: getattr(EFFECTS[name], level)}
            data, _ = twin.simulate(3.0, RATE_HZ, seed, eff)
            s = diagnose(data).summary
            group = [s["best"], *s["indistinguishable_from"]]
            found += (s["best"] == "none") if name == "none" else (name in group)
            bests[s["best"] if len(group) == 1 else "+".join(sorted(group))] += 1
            if name != "none":
                reductions.append(
                    next(c for c in s["candidates"] if c["effect"] == name)["heldout_reduction"]["total"]
                )
        out[name] = (found / len(SEEDS), float(np.median(reductions)) if reductions else float("nan"), bests)
    return out


@pytest.mark.slow
def test_detection_rates():
    table = {level: _rates(level) for level in ("realistic", "edge")}
    print(f"\nseeds {list(SEEDS)}, 3 days, forces at {RATE_HZ:g} Hz")
    print(f"{'effect':<21}{'realistic':>10}{'red.':>6}{'edge':>7}{'red.':>6}  answers at edge")
    for name in ("none", *EFFECT_NAMES):
        r, e = table["realistic"][name], table["edge"][name]
        print(f"{name:<21}{r[0]:>10.2f}{r[1]:>6.2f}{e[0]:>7.2f}{e[1]:>6.2f}  {dict(e[2])}")
    realistic = table["realistic"]
    assert realistic["none"][0] == 1.0
    for name in EFFECT_NAMES:
        assert realistic[name][0] >= 2 / 3, (name, realistic[name])
