"""``bridge-shadow replay``: run a monitoring bag through the shadow (direct or through DDS)."""

from __future__ import annotations

import argparse
from typing import Any

HELP = "replay a monitoring bag through the shadow: posterior settlements, compensation, gating"
DESCRIPTION = """\
Replay a rosbag2 bag with the input topics (the contract's /bridge/frc_01/force,
/bridge/frc_02/force and /bridge/air_temperature, or the topic_* parameters) through the online
shadow: gate -> 60 s windows -> P-spline temperature compensation -> Kalman update of the two
central-support settlements over u = A x + u0.

By default the bag is decoded vectorized and fed to the pipeline directly; --live plays it through
the rclpy node in a loopback DDS graph (same pipeline, same posterior). Parameters come from
config/shadow.yaml or --params. --json prints one object: posterior.mean_m [south, north] (m),
posterior.covariance_m2 (m^2), messages used and rejected by reason, spline edf and lambda per
channel, and the rates: messages_per_s and seconds end to end (from the command's start: imports,
model, bag read and decode, shadow, --out; not --plots), pipeline_messages_per_s and
pipeline_seconds for the shadow alone (live: publishing to the node's flush). --out and --plots
work in both modes (live: drawn from the node's history service and final checkpoint). The direct
replay streams the bag in bounded memory: --out is written as windows close, and --plots draws at
most 10,000 windows, evenly spaced over the record. A progress bar shows on a terminal unless --json.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add BAG, --params, --live, --rate, --out, --plots, --json."""
    parser.add_argument("bag", metavar="BAG", help="rosbag2 directory (sqlite3 or MCAP)")
    parser.add_argument("--params", metavar="YAML", help="shadow parameter file (default config/shadow.yaml)")
    parser.add_argument("--live", action="store_true", help="play through the rclpy node over DDS (loopback)")
    parser.add_argument(
        "--rate",
        type=float,
        metavar="X",
        help="with --live: publish at X times the bag's pace (1 = real time; default: as fast as taken)",
    )
    parser.add_argument("--out", metavar="OUTBAG", help="write the outputs (mean, covariance, ...) as a bag")
    parser.add_argument("--plots", metavar="DIR", help="write PNG plots (compensation, posterior, ellipse)")
    parser.add_argument("--json", action="store_true", help="print one JSON object (SI units)")


def _summary(js: dict[str, Any]) -> str:
    import numpy as np

    mean = np.array(js["posterior"]["mean_m"])
    cov = np.array(js["posterior"]["covariance_m2"])
    sd = np.sqrt(np.diag(cov))
    rho = cov[0, 1] / (sd[0] * sd[1]) if sd.all() else float("nan")
    msgs = js["messages"]
    lines = [
        "posterior settlement (positive upward, 95% interval):",
        *(
            f"  {name:5s} {1e3 * m:+8.3f} mm ± {1e3 * 1.96 * s:.3f} mm"
            for name, m, s in zip(("south", "north"), mean, sd, strict=True)
        ),
        f"  correlation {rho:+.3f}",
        f"messages: {msgs['total']} in, {msgs['used']} used, {msgs['rejected']} rejected; "
        f"{js['messages_per_s']:.0f} msg/s",
        f"windows: {js['windows']['closed']} closed, {js['windows']['updates']} updates",
    ]
    rejected = {k: v for k, v in js["rejected"].items() if v}
    if rejected:
        lines.append("rejected: " + ", ".join(f"{k} {v}" for k, v in rejected.items()))
    for ch, sp in js["spline"].items():
        lines.append(
            f"compensation {ch}: edf {sp['edf']:.2f}, lambda {sp['lambda']:.3g}, "
            f"mean {1e-3 * sp['mean_force_n']:.2f} kN over {sp['windows']} windows"
        )
    return "\n".join(lines)


def _end_to_end_rate(js: dict[str, Any], started: float) -> None:
    """Make ``messages_per_s``/``seconds`` end to end; keep the pipeline's own under ``pipeline_*``."""
    import time

    seconds = time.perf_counter() - started
    js["pipeline_messages_per_s"] = js["messages_per_s"]
    js["pipeline_seconds"] = js["seconds"]
    js["seconds"] = seconds
    js["messages_per_s"] = js["messages"]["total"] / seconds if seconds > 0 else float("inf")


def run(args: argparse.Namespace) -> int:
    """Replay the bag and print the result; exit 0."""
    import sys
    import time

    started = getattr(args, "started", None) or time.perf_counter()

    from bridge_shadow.commands.output import emit_json, progress
    from bridge_shadow.estimate import Shadow, load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    show = None if args.json or not sys.stderr.isatty() else (lambda f: progress(f, "replay"))
    if args.rate is not None and (not args.live or not args.rate > 0):
        from bridge_shadow.errors import InputError

        raise InputError("--rate needs --live and a positive speed factor")
    if args.live:
        from bridge_shadow.ros.live_replay import run_live

        js = run_live(args.bag, args.params, out=args.out, plots=args.plots, rate=args.rate, progress=show)
        _end_to_end_rate(js, started)
        if args.json:
            emit_json(js)
        else:
            print(_summary(js))
        return 0

    from bridge_shadow.replay import HISTORY_CAPACITY, replay_bag

    config = load_config(args.params)
    surrogate = load_surrogate(config.surrogate_path or None)
    shadow = Shadow(config, surrogate)
    # streamed in bounded memory; outputs go to --out as windows close, --plots keeps a decimated history
    history = HISTORY_CAPACITY if args.plots else None
    result, _ = replay_bag(args.bag, shadow, out=args.out, history=history, progress=show)
    js = result.to_json()
    js["bag"] = str(args.bag)
    js["surrogate"] = {
        "A": surrogate.A.tolist(),
        "u0": surrogate.u0.tolist(),
        "solver": surrogate.provenance.get("solver", ""),
    }
    if args.out:
        js["out"] = str(args.out)
    _end_to_end_rate(js, started)
    if args.plots:
        from bridge_shadow.estimate.plots import write_plots

        js["plots"] = [str(p) for p in write_plots(args.plots, result, shadow)]
    if args.json:
        emit_json(js)
    else:
        print(_summary(js))
    return 0
