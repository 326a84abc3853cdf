"""``bridge-shadow calibrate``: update named FE parameters from records with a known imposed settlement."""

from __future__ import annotations

import argparse
from pathlib import Path

from bridge_shadow.engine import add_engine_options

HELP = "calibrate the FE model on records with a known imposed settlement; write a calibrated surrogate"
DESCRIPTION = """\
Bayesian updating of named FE parameters (priors in bridge_shadow/model/parameters.py) against
record pairs (before, after) with a known imposed settlement, listed in a calibration file
(default config/calibration.yaml: the 2022-04-11 reference record and the record after lowering
both central bearings by 10 mm, read from the shared data directory).

  1. measured change per pair: car-free windows (the test car is detected and left out), levels
     and their AR(1) window noise (the shadow's noise model), the baseline's change between the
     two records as an uncertainty (or a modelled linear drift, or the sun's vertical
     temperature difference through the deck: baseline_change, --baseline-change);
  2. every candidate explanation (a set of parameters; the jacks' errors are estimated in each) is
     fitted by projected Levenberg-Marquardt with FE re-solves and adjoint sensitivities, and
     scored by its Laplace evidence; what each implies for the south-north (differential) mode is
     printed beside it;
  3. the explanations are averaged by their evidence (`choose: average`, the default; or one
     named, --choose NAME, or the best, --choose best): the surrogate's A, u0 and thermal cases
     are the weighted means and model_uncertainty holds each one's posterior and the spread
     between them; the FE is re-solved at the MAP of the most probable one for the sensitivities;
     a model discrepancy grows beyond the calibrated settlements (a 10 mm step used at 30 mm).

Priors and plausible ranges come from bridge_shadow/model/parameters.py, each derived from its
source (--priors NAME picks another of its prior sets); --prior-sensitivity refits the
explanations under every prior set and says which wins under each (a few minutes more), and
with choose: average the written model averages over the explanations under every set not
chosen after the data, so that where one prior is centred does not decide it.

One pair of records gives two numbers: at most two parameter combinations are fixed by it (the
identifiability report says which); every other direction stays at its prior.

Nothing is written without --out. Progress goes to stderr.

--check SURROGATE scores a surrogate on the file's pairs instead of calibrating (no FE solve):
x = A^-1 dR with its 95 % interval (the measurement and the surrogate's model uncertainty)
against the imposed settlement, per support and in the common mode. List a later record pair
(before, after, imposed_m) in a file of your own to check the calibrated model on it; exit 1
when an interval misses the imposed value.

examples:
  bridge-shadow calibrate                                    # report on the real pair
  bridge-shadow calibrate --out config/surrogate.yaml        # the committed default surrogate
  bridge-shadow calibrate --json --only support_springs --only slab_joint_opening
  bridge-shadow calibrate my_pairs.yaml --mesh coarse --out /tmp/cal.yaml --report /tmp/cal
  bridge-shadow calibrate --workers 2                        # the explanations in parallel on Dask
  bridge-shadow calibrate --check config/surrogate.yaml      # the default surrogate on the pair
  bridge-shadow calibrate later_pairs.yaml --check config/surrogate_fe.yaml
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options."""
    parser.add_argument(
        "spec", nargs="?", type=Path, default=None, help="calibration file (default config/calibration.yaml)"
    )
    parser.add_argument("--out", type=Path, default=None, help="write the calibrated surrogate YAML here")
    parser.add_argument("--force", action="store_true", help="replace an existing surrogate file at --out")
    parser.add_argument(
        "--mesh", default=None, metavar="LEVEL", help="coarse, default or fine (overrides the file)"
    )
    parser.add_argument(
        "--only", action="append", default=None, metavar="NAME", help="fit only this explanation (repeatable)"
    )
    parser.add_argument(
        "--choose",
        default=None,
        metavar="NAME",
        help="average (model average by evidence), best, or an explanation to write (default: the file's)",
    )
    parser.add_argument(
        "--priors", default=None, metavar="SET", help="prior set of model/parameters.py (default: the file's)"
    )
    parser.add_argument(
        "--no-sweeps",
        action="store_true",
        help="with --out: leave the parameter sweeps out of the surrogate (about 20 FE solves; the gap "
        "diagnosis then fits the stiffness effects to first order)",
    )
    parser.add_argument(
        "--prior-sensitivity",
        action="store_true",
        help="refit every explanation under each prior set and report which wins under each; "
        "with choose: average, the written model averages over the sets not chosen after the data",
    )
    parser.add_argument(
        "--baseline-change",
        choices=("uncertainty", "linear", "sun"),
        default=None,
        help="override the file's treatment of the baseline's change between two records: "
        "uncertainty (the drifts seen within them, over the time between), linear (that drift "
        "continued and subtracted) or sun (the deck's vertical temperature difference under the "
        "clear-sky sun and the day's clearness, with the sun term's prior; see "
        "bridge_shadow/calibrate/change.py)",
    )
    parser.add_argument(
        "--model", type=Path, default=None, help="bridge model YAML (default config/bridge.yaml)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter of the bridge model before calibrating (repeatable), SI units",
    )
    parser.add_argument("--report", type=Path, default=None, metavar="DIR", help="write figures here")
    parser.add_argument(
        "--check",
        type=Path,
        default=None,
        metavar="SURROGATE",
        help="score this surrogate YAML on the file's pairs instead of calibrating (exit 1 on a miss)",
    )
    add_engine_options(
        parser, "fit the explanations (each with FE solves of its own: more solves, the same fits)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args: argparse.Namespace) -> int:
    """Calibrate, print, write."""
    import sys

    from bridge_shadow.calibrate.report import summary_text, write_figures
    from bridge_shadow.calibrate.run import calibrate, default_spec_path
    from bridge_shadow.calibrate.spec import load_spec
    from bridge_shadow.commands.output import emit_json, progress
    from bridge_shadow.engine import optional_mapper
    from bridge_shadow.errors import InputError
    from bridge_shadow.model.config import MESH_LEVELS, load_bridge_config, parse_overrides
    from bridge_shadow.model.surrogate import write_surrogate

    spec = load_spec(args.spec if args.spec is not None else default_spec_path())
    if args.mesh is not None:
        if args.mesh not in MESH_LEVELS:
            raise InputError(f"--mesh must be one of {', '.join(MESH_LEVELS)}, got {args.mesh!r}")
        spec.mesh = args.mesh
    if args.baseline_change is not None:
        spec.baseline_change = args.baseline_change
    if args.choose is not None:
        if args.choose not in spec.explanations and args.choose not in ("best", "average"):
            raise InputError(
                f"--choose {args.choose}: not average, best or an explanation "
                f"({', '.join(spec.explanations)})"
            )
        spec.choose = args.choose
    if args.priors is not None:
        from bridge_shadow.model.parameters import PRIOR_SETS

        if args.priors not in PRIOR_SETS:
            raise InputError(f"--priors {args.priors}: not a prior set ({', '.join(PRIOR_SETS)})")
        spec.priors = args.priors
    if args.check is not None:
        return _check(args, spec)
    # the outputs are checked before the FE solves: a bad path costs no minutes
    from bridge_shadow.fileio import check_output_dir
    from bridge_shadow.model.surrogate_file import surrogate_target

    if args.out is not None:
        surrogate_target(args.out, create=False, force=args.force)
    if args.report is not None:
        check_output_dir(args.report, "figure directory")
    cfg = load_bridge_config(args.model, parse_overrides(args.overrides))
    with optional_mapper(args.scheduler, args.workers) as mapper:
        result = calibrate(
            spec,
            cfg,
            only=args.only,
            report=lambda f, s: progress(f, "calibrate"),
            sensitivity=args.prior_sensitivity,
            sweeps=args.out is not None and not args.no_sweeps,
            mapper=mapper,
        )
    doc = result.to_dict()
    if args.out is not None:
        what = "Model average of the explanations" if spec.choose == "average" else "One explanation"
        source = "config/calibration.yaml" if args.spec is None else str(args.spec)  # the pairs it read
        header = (
            f"# Generated by `bridge-shadow calibrate` ({source}; README, Calibration).\n"
            f"# Do not edit. {what} ({result.chosen} most probable), mesh {spec.mesh}.\n"
            "# Units: A N/m, u0 N, thermal N/K; sensitivities per unit relative change of the\n"
            "# parameter; model_uncertainty: covariance of [A, u0, thermal] (N/m, N, N/K);\n"
            "# discrepancy: relative error beyond the calibrated settlements.\n"
        )
        write_surrogate(result.run, args.out, header=header, force=args.force)
        doc["written_to"] = str(args.out)
    if args.report is not None:
        doc["figures"] = [str(p) for p in write_figures(result, args.report)]
    for line in doc.get("warnings", []):
        print(f"bridge-shadow calibrate: WARN: {line}", file=sys.stderr)
    if args.json:
        emit_json(doc)
    else:
        print(summary_text(result))
        if args.out is not None:
            print(f"wrote {args.out}", file=sys.stderr)
        for f in doc.get("figures", []):
            print(f"wrote {f}", file=sys.stderr)
    return 0


def _check(args: argparse.Namespace, spec: object) -> int:
    """``--check``: read every pair through the given surrogate; 1 when an interval misses."""
    from bridge_shadow.calibrate.check import check_pair, check_text
    from bridge_shadow.calibrate.run import measure_pairs
    from bridge_shadow.commands.output import emit_json, progress, require_finite
    from bridge_shadow.errors import InputError
    from bridge_shadow.model.surrogate_file import load_surrogate

    options = (
        "out",
        "force",
        "report",
        "only",
        "choose",
        "model",
        "mesh",
        "priors",
        "prior_sensitivity",
        "no_sweeps",
        "workers",
        "scheduler",
    )
    calibrating = [n for n in options if getattr(args, n)]
    if calibrating or args.overrides:
        names = ", ".join(f"--{n.replace('_', '-')}" for n in calibrating) or "--set"
        raise InputError(f"--check scores a surrogate and calibrates nothing: drop {names}")
    surrogate = load_surrogate(args.check)
    sun = None
    if spec.baseline_change == "sun":
        from bridge_shadow.calibrate.change import SunBaseline

        sun = SunBaseline.of(surrogate, str(args.check))
    pairs = measure_pairs(spec, report=lambda f, s: progress(f, "records"), sun=sun)
    checks = [check_pair(p.name, p.change, surrogate, p.imposed_m, p.imposed_sd_m) for p in pairs]
    require_finite(
        {f"{c.name}: {key}": c.to_dict()[key] for c in checks for key in ("x_m", "covariance_m2")},
        "settlement read through the surrogate",
    )
    if args.json:
        emit_json({"surrogate": str(args.check), "pairs": [c.to_dict() for c in checks]})
    else:
        print(check_text(checks, str(args.check)))
    return 0 if all(all(c.held()) for c in checks) else 1
