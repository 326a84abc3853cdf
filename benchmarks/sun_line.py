"""How often the sun line speaks (``report.sun_ambiguity_lines``), and where the interval misses.

Two studies, counts only (no timing):

- **grid**: streams of the two public records of 2022-04-11 (``twin.real_records``): either record
  first, then a copy 0.73 h (the 10 mm record at its own time), 1.25, 2, 3.5 or 4 h on (the last
  under the air of 6.5 h) with 0, -3, -5, -10 or +3 mm added through the calibrated ``A``, whole or
  cut to minutes 0-2.58, 3-8 or 9-13 (200 streams). Printed: the 95 % intervals that miss the
  truth and how many of those the line warned of; the streams warned whose interval held (with a
  change, and without one).
- **twin**: ``twin.loadtest.load_test_day`` at 4 K of sun with its 10 mm steps, without steps and
  with 3 mm steps, and ``scheduled_day``: days warned and intervals missing, over ``--seeds``.

Usage::

    .venv/bin/python benchmarks/sun_line.py [--seeds 20] [--verbose]
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.paths import shared_data_dir
from bridge_shadow.twin.loadtest import LoadTestDay, load_test_day, scheduled_day
from bridge_shadow.twin.real_records import Piece, build

SUN = "cannot be told from the deck's sun"
HOURS = ((1.25, None), (2.0, None), (3.5, None), (4.0, 6.5), (0.733, None))
STEPS_M = (0.0, -0.003, -0.005, -0.01, 0.003)
CUTS = ((0.0, 2.58), (9.0, 13.0), (3.0, 8.0), None)


def _judge(data, truth_m: np.ndarray, surrogate) -> tuple[bool, bool]:
    """Run the shadow on ``data``: (the 95 % interval holds the truth, the sun line was said)."""
    shadow = Shadow(load_config(), surrogate)
    shadow.run(data)
    mean, cov = shadow.posterior
    held = bool(np.all(np.abs(mean - truth_m) < 1.96 * np.sqrt(np.diag(cov))))
    return held, any(SUN in w for w in shadow.warnings())


def grid(folder: Path, surrogate, verbose: bool) -> None:
    """Print the real-record streams: misses warned, warnings where the interval held."""
    rows = []
    for (at, air), step, cut, first in itertools.product(HOURS, STEPS_M, CUTS, ("ref", "lowered")):
        second = "lowered" if at == 0.733 else first
        pieces = [Piece(first, 0.0), Piece(second, at, (step, step), temp_at_h=air, cut_min=cut)]
        try:
            sc = build(folder, surrogate.A, pieces)
        except ValueError:  # no continuous air temperature for that copy
            continue
        held, warned = _judge(sc.data, sc.truth_m, surrogate)
        rows.append((held, warned, bool(sc.changes())))
        if verbose and (warned or not held):
            print(f"  {first} then {second} at {at} h (air {air}), {step * 1e3:+.0f} mm, {cut}: ", end="")
            print(f"interval holds {held}, warned {warned}")
    misses = [r for r in rows if not r[0]]
    print(f"grid: {len(rows)} streams of the real records")
    print(f"  intervals missing the truth {len(misses)}, warned {sum(r[1] for r in misses)}")
    print(f"  warned, interval held: with a change {sum(r[0] and r[1] and r[2] for r in rows)}", end="")
    print(f", without {sum(r[0] and r[1] and not r[2] for r in rows)} of {sum(not r[2] for r in rows)}")


def twin(seeds: int, surrogate) -> None:
    """Print the twin's load-test days at 4 K of sun: days warned, intervals missing."""
    cases = (
        ("four records, 10 mm steps", LoadTestDay(), load_test_day),
        ("four records, no steps", LoadTestDay(steps_m=((0.0, 0.0),) * 3), load_test_day),
        ("four records, 3 mm steps", LoadTestDay(steps_m=((-0.003, -0.003),) * 3), load_test_day),
        ("2022-04-11's schedule", LoadTestDay(), scheduled_day),
    )
    for label, spec, make in cases:
        warned = missed = 0
        for seed in range(seeds):
            data, truth = make(seed, spec, surrogate)
            held, said = _judge(data, np.asarray(truth["record_x_m"][-1], float), surrogate)
            warned += said
            missed += not held
        print(f"twin, {label}, 4 K of sun: {seeds} days, warned {warned}, intervals missing {missed}")


def main() -> None:
    """Run both studies."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="twin days per case (default 20)")
    parser.add_argument("--verbose", action="store_true", help="every grid stream warned or missed")
    args = parser.parse_args()
    surrogate = load_surrogate()
    folder = shared_data_dir() / "Settlements"
    grid(folder, surrogate, args.verbose)
    twin(args.seeds, surrogate)


if __name__ == "__main__":
    main()
