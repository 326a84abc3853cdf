"""``bridge-shadow verify``: run the FE verification suite (benchmarks, closed forms, two sweeps)."""

from __future__ import annotations

import argparse

HELP = "run the FE solver's verification suite (shell benchmarks, patch tests, closed forms, sweeps)"
DESCRIPTION = """\
Run the bundled FE solver on published shell benchmarks (Scordelis-Lo roof with a convergence
table, pinched cylinder, MacNeal-Harder straight cantilevers on their standard rectangular,
trapezoidal and parallelogram meshes, twisted beam, simply supported plate), membrane and bending
patch tests, the membrane against its own paper's table, a shell strip under a thermal gradient,
and two equal spans as beams and as a shell I-girder (settlement, thermal gradient, uniform load,
free uniform temperature). Then two sweeps: the Scordelis-Lo roof and the plate with randomly
perturbed interior nodes on successively halved meshes (observed convergence orders), and the
drilling penalty DRILL_FACTOR over six decades.

For each case: computed value, reference, ratio, tolerance, the reference's key (sources listed
below the table), mesh, DOFs, seconds, and the verdict; a case without a tolerance says why.
Cases with reference 0 report a normalized error. Exit code 0 only if every case with a tolerance
passes (1 otherwise). --json prints {"cases": [...], "distortion_sweep": [...], "drill_sweep": [...]};
each case has the keys name, computed, reference, ratio, tolerance, mesh, dofs, seconds, passed,
source, reason, ref.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--json`` and ``--quick``."""
    parser.add_argument("--json", action="store_true", help="print one JSON object {cases: [...], ...}")
    parser.add_argument("--quick", action="store_true", help="coarser meshes where tolerances still hold")


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def _print_cases(report: object) -> None:
    from bridge_shadow.fe.verify import REFERENCES

    cases = report.cases  # type: ignore[attr-defined]
    head = f"{'case':42s} {'computed':>11s} {'reference':>11s} {'ratio':>7s} {'tol':>6s} {'ref':>8s} "
    print(head + f"{'mesh':>24s} {'dofs':>6s} {'s':>5s}  result")
    for c in cases:
        verdict = "report" if c.passed is None else ("pass" if c.passed else "FAIL")
        note = f"  ({c.reason})" if c.reason else ""
        print(
            f"{c.name:42s} {c.computed:11.5g} {c.reference:11.5g} {_fmt(c.ratio, '7.4f'):>7s} "
            f"{_fmt(c.tolerance, '6.2g'):>6s} {c.ref:>8s} {c.mesh:>24s} {c.dofs:6d} {c.seconds:5.2f}  "
            f"{verdict}{note}"
        )
    n_tol = sum(c.passed is not None for c in cases)
    n_ok = sum(c.passed is True for c in cases)
    print(f"{n_ok}/{n_tol} toleranced cases pass; {len(cases) - n_tol} reported only, each with its reason")
    print("\nreferences:")
    for key in dict.fromkeys(c.ref for c in cases):
        print(f"  {key:8s} {REFERENCES[key].source}")


def _print_distortion(rows: list) -> None:
    if not rows:
        return
    print("\nmesh distortion sweep (interior nodes moved at random by up to a fraction of the spacing):")
    print(
        f"  {'problem':14s} {'distort':>7s} {'mesh':>7s} {'dofs':>6s} {'value':>11s} {'ratio':>7s} "
        f"{'error':>9s} {'order':>6s} {'vs regular':>10s}"
    )
    for r in rows:
        print(
            f"  {r.problem:14s} {r.distortion:7.0%} {f'{r.n}x{r.n}':>7s} {r.dofs:6d} {r.value:11.5g} "
            f"{r.ratio:7.4f} {r.error:9.2e} {_fmt(r.rate, '6.2f'):>6s} {r.distortion_effect:+10.1e}"
        )
    print(
        "  ratio: to the published value; error: to the converged value (plate: Navier series; roof: "
        "Richardson of the\n  finest regular mesh and one twice as fine); order: log2 of the error ratio "
        "of successive meshes (the roof\n  converges non-monotonically: its order swings where the error "
        "changes sign); vs regular: distorted / regular - 1"
    )


def _print_drill(rows: list) -> None:
    if not rows:
        return
    from bridge_shadow.fe.elements.shell import DRILL_FACTOR

    factors = sorted({r.drill_factor for r in rows})
    names = list(dict.fromkeys(r.case for r in rows))
    table = {(r.case, r.drill_factor): r.ratio_to_default for r in rows}
    print(f"\ndrilling penalty sweep: value / value at DRILL_FACTOR = {DRILL_FACTOR:g} (gamma = factor * G)")
    print(f"  {'case':32s} " + " ".join(f"{f:>8g}" for f in factors))
    for name in names:
        print(f"  {name:32s} " + " ".join(f"{table[(name, f)]:8.4f}" for f in factors))


def run(args: argparse.Namespace) -> int:
    """Run the suite, print the tables or the JSON, return 0 if all toleranced cases pass."""
    from bridge_shadow.commands.output import emit_json, progress
    from bridge_shadow.fe.verify import run_report

    report = run_report(quick=args.quick, progress=None if args.json else progress)
    ok = all(c.passed is not False for c in report.cases)
    if args.json:
        emit_json(report.as_dict())
        return 0 if ok else 1
    _print_cases(report)
    _print_distortion(report.distortion)
    _print_drill(report.drill)
    return 0 if ok else 1
