"""``bridge-shadow gap``: the sim-to-real gap diagnosis of a monitoring bag."""

from __future__ import annotations

import argparse

HELP = "diagnose the sim-to-real gap: where it lies, which effect causes it, how far it shrinks"
DESCRIPTION = """\
Diagnose the gap between the baseline model (FE surrogate u0 plus its uniform thermal case) and
the measured central reactions of a monitoring bag:

  where  share per channel, time of day, warming/cooling, sunny/overcast, frequency band, model part
  which  every effect of the vocabulary fitted on training days and ranked by the held-out
         improvement (leave-one-day-out), with an AR(1) information criterion and partial effects;
         effects the two reactions cannot tell apart are reported together
  how far  held-out residual RMS before/after per channel, and the posterior settlements before
         and after adding the best effect

`best` is `none` when no candidate beats the chance level of AR(1) noise. The diagnosis never
reads a twin's ground-truth file. JSON output is SI (N, m, s, C)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the gap options."""
    parser.add_argument("bag", help="rosbag2 directory with the contract input topics")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument("--report", metavar="DIR", help="write report.md and PNG plots into DIR")
    parser.add_argument(
        "--holdout-days",
        metavar="DAY",
        type=int,
        nargs="+",
        help="hold out these whole days (0 = first 24 h of the record) instead of leave-one-day-out",
    )
    parser.add_argument("--surrogate", metavar="YAML", help="surrogate file (default config/surrogate.yaml)")
    parser.add_argument(
        "--replay",
        action="store_true",
        help="also replay the whole online shadow before/after adding the best effect (slower)",
    )
    parser.add_argument("--window", type=float, default=60.0, metavar="S", help="window length in s (60)")


def _human(summary: dict) -> str:
    lines = [
        f"best: {summary['best']}",
        summary["statement"],
        "",
        "rank  effect                held-out RMS reduction S/N/total",
    ]
    for c in summary["candidates"]:
        r = c["heldout_reduction"]
        mark = "*" if c["significant"] else " "
        lines.append(
            f"{c['rank']:>4}{mark} {c['effect']:<21} {100 * r['south']:6.1f}% {100 * r['north']:6.1f}% "
            f"{100 * r['total']:6.1f}%"
        )
    w = summary["where"]
    lines.append("")
    lines.append(
        f"residual RMS: south {w['rms_n']['south'] / 1e3:.3f} kN, north {w['rms_n']['north'] / 1e3:.3f} kN; "
        f"share south {100 * w['channel_share']['south']:.0f}%"
    )
    pb, pa = summary["posterior"]["before"]["mean_m"], summary["posterior"]["after"]["mean_m"]
    lines.append(
        f"posterior settlements [mm]: before {1e3 * pb[0]:+.3f} / {1e3 * pb[1]:+.3f}, "
        f"after {1e3 * pa[0]:+.3f} / {1e3 * pa[1]:+.3f}"
    )
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Read the bag, diagnose, print, and write the report."""
    import math

    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.commands.output import emit_json
    from bridge_shadow.errors import InputError
    from bridge_shadow.fileio import check_output_dir
    from bridge_shadow.gap.diagnose import diagnose
    from bridge_shadow.model.surrogate_file import load_surrogate

    if not (args.window > 0 and math.isfinite(args.window)):
        raise InputError("--window must be a positive, finite number of seconds")
    if args.report:
        check_output_dir(args.report, "report directory")  # before the work
    data = read_monitoring(args.bag)
    surrogate = load_surrogate(args.surrogate) if args.surrogate else None
    dg = diagnose(data, surrogate, width_s=args.window, holdout_days=args.holdout_days, replay=args.replay)
    summary = dict(dg.summary)
    summary["bag"] = str(args.bag)
    if args.report:
        from bridge_shadow.gap.report import write_report

        summary["report"] = str(write_report(dg, args.report, str(args.bag)))
    if args.json:
        emit_json(summary)
    else:
        print(_human(summary))
        if args.report:
            print(f"report: {summary['report']}")
    return 0
