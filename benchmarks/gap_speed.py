"""Gap diagnosis speed: three days diagnosed at 60 s windows (target: under 60 s on 2 cores).

Makes 3-day truth-twin records (forces at ``--rate`` Hz; one effect withheld, then four at once,
which takes the simulated chance level), writes each as a bag, then times in the same run:

- baseline ``read``: ``bagio.read_monitoring`` of the bag (what any consumer of the bag pays);
- ``aggregate``: the 60 s window statistics (mean, spread, max, median) of the record;
- ``diagnose``: the whole diagnosis in memory (windows, drivers, every candidate with whole-day
  cross-validation and grids, the support spring's nonlinear fits, partial effects, groups, where),
  without the shadow's posteriors;
- ``bridge-shadow gap --json``: the command end to end (read + diagnose + the shadow run before and
  after adding the named effects, as ``replay`` runs it + JSON).

Prints seconds and the ratio to the read baseline. Usage::

    .venv/bin/python benchmarks/gap_speed.py [--rate HZ] [--repeat R]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
import time
from pathlib import Path

from _common import DEMO_EFFECTS

from bridge_shadow.bagio import read_monitoring, write_monitoring
from bridge_shadow.cli import main as cli_main
from bridge_shadow.gap.diagnose import diagnose
from bridge_shadow.gap.windows import aggregate
from bridge_shadow.twin.simulate import simulate


def _best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1.0, help="force rate, Hz (default 1)")
    parser.add_argument("--days", type=float, default=3.0)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    cases = {
        "one effect (settlement_drift)": {"settlement_drift": 2e-4},
        "four effects (demo-like; simulated chance level)": DEMO_EFFECTS,
    }
    for label, effects in cases.items():
        data, _ = simulate(args.days, args.rate, 5, effects)
        with tempfile.TemporaryDirectory() as tmp:
            bag = Path(tmp) / "bag"
            write_monitoring(bag, data)
            t_read = _best(lambda bag=bag: read_monitoring(bag), args.repeat)
            t_agg = _best(lambda data=data: aggregate(data), args.repeat)
            t_diag = _best(lambda data=data: diagnose(data), args.repeat)

            def cli(bag: Path = bag) -> None:
                with contextlib.redirect_stdout(io.StringIO()):
                    assert cli_main(["gap", str(bag), "--json"]) == 0

            t_cli = _best(cli, args.repeat)
        n = data.n_messages
        print(f"== {label}")
        print(
            f"{args.days:g} days, forces at {args.rate:g} Hz: {n} messages, {int(args.days * 1440)} windows"
        )
        print(f"{'step':<28}{'seconds':>10}{'x read':>10}")
        for name, t in (
            ("read (baseline)", t_read),
            ("aggregate", t_agg),
            ("diagnose", t_diag),
            ("bridge-shadow gap --json", t_cli),
        ):
            print(f"{name:<28}{t:>10.3f}{t / t_read:>10.2f}")
        verdict = "OK" if t_cli < 60.0 else "TOO SLOW"
        print(f"end to end {t_cli:.2f} s against the 60 s target: {verdict}")


if __name__ == "__main__":
    main()
