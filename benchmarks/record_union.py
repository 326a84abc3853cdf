"""A load-test record's replay with the stamps' union merged (shipped) against ``np.unique`` (before).

The traffic screen bins a short record's two force channels on the union of their stamps, and the
window buffer groups a batch by the union of its window indices (``windowing.sorted_union``).
``np.unique`` hashes every value since numpy 2.3; the shipped union merges the sorted parts with a
stable sort. Both give the same integers, so the replays are the same window for window (checked).

Streams: the real 2022-04-11 records of ``../shared`` (the reference record, then the 1 cm
record 44 minutes later; the reference record again 1.25 h later with 10 mm added through ``A``).
Printed, best of ``--repeat`` rounds (the two ways alternate within each round): the union of one
record's two 100 Hz stamp arrays alone, and each stream's ``Shadow.run``, as ratios of the shipped
way's time to ``np.unique``'s (the baseline) in the same run.

Run: ``.venv/bin/python benchmarks/record_union.py [--repeat R]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.inputs import traffic, windows
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.paths import shared_data_dir
from bridge_shadow.twin.real_records import Piece, build
from bridge_shadow.windowing import sorted_union


def unique_union(parts: list[np.ndarray]) -> np.ndarray:
    """Return the union as it was: ``np.unique`` of the concatenation."""
    return np.unique(np.concatenate(parts))


def _use(union: Callable[[list[np.ndarray]], np.ndarray]) -> None:
    traffic.sorted_union = union
    windows.sorted_union = union


def _best(fn: Callable[[], object], repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5, help="rounds; the best of each is printed (default 5)")
    repeat = ap.parse_args().repeat
    sur = load_surrogate()
    folder = shared_data_dir() / "Settlements"
    streams = {
        "reference, 1 cm record 44 min later": [Piece("ref", 0.0), Piece("lowered", 0.73)],
        "reference, itself 10 mm lower 1.25 h later": [Piece("ref", 0.0), Piece("ref", 1.25, (-0.01, -0.01))],
    }
    scenarios = {name: build(folder, sur.A, pieces) for name, pieces in streams.items()}
    one = next(iter(scenarios.values()))
    record = [s.stamp_ns[s.stamp_ns < one.starts_ns[1]] for s in one.data.forces.values()]
    print(f"union of one record's two stamp arrays ({sum(map(len, record)):,} stamps):")
    np.testing.assert_array_equal(sorted_union(record), unique_union(record))  # exact: integers
    base = _best(lambda: unique_union(record), 20 * repeat)
    ours = _best(lambda: sorted_union(record), 20 * repeat)
    print(
        f"  np.unique (baseline) {1e3 * base:7.2f} ms   merged {1e3 * ours:7.2f} ms   ratio {ours / base:.3f}"
    )
    cfg = load_config()
    for name, sc in scenarios.items():
        times = {"unique": np.inf, "merged": np.inf}
        means = {}
        for _ in range(repeat):
            for way, union in (("unique", unique_union), ("merged", sorted_union)):
                _use(union)
                t0 = time.perf_counter()
                res = Shadow(cfg, sur).run(sc.data)
                times[way] = min(times[way], time.perf_counter() - t0)
                means[way] = res.mean_m
        _use(sorted_union)
        np.testing.assert_array_equal(means["merged"], means["unique"])  # exact: the same integers in
        print(
            f"{name}: Shadow.run np.unique (baseline) {times['unique']:.3f} s   merged "
            f"{times['merged']:.3f} s   ratio {times['merged'] / times['unique']:.3f}"
        )


if __name__ == "__main__":
    main()
