"""``bridge-shadow verify``: run the FE verification suite (benchmarks and closed forms)."""

from __future__ import annotations

import argparse

HELP = "run the FE solver's verification suite (shell benchmarks, patch tests, closed forms)"
DESCRIPTION = """\
Run the bundled FE solver on published shell benchmarks (Scordelis-Lo roof with a convergence
table, pinched cylinder, MacNeal-Harder cantilevers, simply supported plate), membrane and
bending patch tests, a shell strip under a thermal gradient, and two equal spans as beams and as a
shell I-girder (settlement, thermal gradient, uniform load, free uniform temperature).

For each case: computed value, reference, ratio, tolerance, mesh, DOFs, seconds. Cases without a
tolerance are reported only. Cases with reference 0 report a normalized error. Exit code 0 only
if every case with a tolerance passes (1 otherwise).
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--json`` and ``--quick``."""
    parser.add_argument("--json", action="store_true", help="print one JSON object {cases: [...]}")
    parser.add_argument("--quick", action="store_true", help="coarser meshes where tolerances still hold")


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def run(args: argparse.Namespace) -> int:
    """Run the suite, print the table or the JSON, return 0 if all toleranced cases pass."""
    from bridge_shadow.commands.output import emit_json, progress
    from bridge_shadow.fe.verify import run_cases

    cases = run_cases(quick=args.quick, progress=None if args.json else progress)
    ok = all(c.passed is not False for c in cases)
    if args.json:
        emit_json({"cases": [c.as_dict() for c in cases]})
        return 0 if ok else 1
    head = f"{'case':36s} {'computed':>12s} {'reference':>12s} {'ratio':>8s} {'tol':>7s} {'mesh':>22s}"
    print(head + f" {'dofs':>7s} {'s':>6s}  result")
    for c in cases:
        verdict = "report" if c.passed is None else ("pass" if c.passed else "FAIL")
        print(
            f"{c.name:36s} {c.computed:12.5g} {c.reference:12.5g} {_fmt(c.ratio, '8.4f'):>8s} "
            f"{_fmt(c.tolerance, '7.2g'):>7s} {c.mesh:>22s} {c.dofs:7d} {c.seconds:6.2f}  {verdict}"
        )
    n_tol = sum(c.passed is not None for c in cases)
    n_ok = sum(c.passed is True for c in cases)
    print(f"{n_ok}/{n_tol} toleranced cases pass; {len(cases) - n_tol} reported only")
    return 0 if ok else 1
