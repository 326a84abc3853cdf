"""``bridge-shadow synth``: write a synthetic monitoring bag from the truth twin, with its truth."""

from __future__ import annotations

import argparse
from typing import Any

from bridge_shadow.effects import EFFECTS
from bridge_shadow.engine import add_engine_options

HELP = "write a synthetic monitoring bag from the truth twin (and BAG/truth.yaml)"

DESCRIPTION = """\
Write a rosbag2 bag with the three input topics of the contract (/bridge/frc_01/force,
/bridge/frc_02/force as WrenchStamped in N; /bridge/air_temperature in C), simulated by the truth
twin: March weather at the bridge (diurnal cycle, day-to-day level and cloudiness), clear-sky sun at
Neubiberg, the FE surrogate (config/surrogate.yaml, else its closed-form placeholder), AR(1)-
correlated load-cell noise (60 s means phi ~ 0.9), dropouts and a few NaN readings. Without
--effect the bag is the baseline model (x = 0, FE uniform thermal response). The same seed gives
the same bag.

Forces come at --rate Hz (default 1 Hz) on both channels, the air temperature at --temp-rate Hz
(default one a minute). The ground truth (every parameter, the effects, the seed, and the true
settlement path: mean, start and end in m) goes to BAG/truth.yaml; nothing that estimates or
diagnoses reads it.

A reality that differs from the model: by default the twin's reactions come from the same
surrogate the shadow uses (config/surrogate.yaml). --reality-set NAME=VALUE (repeatable) solves the
FE model of config/bridge.yaml with those parameters once at synth time (--reality-mesh; e.g.
support_spring_south=2e7, slab_joint_opening=0.01), --reality-surrogate PATH takes another
surrogate file (e.g. config/surrogate_fe.yaml). The shadow keeps its own surrogate; the reality is
recorded in truth.yaml (reality). A before/after pair with a known imposed lowering: two bags, the
second with --step 0:SOUTH:NORTH (settled from its start), e.g.
  bridge-shadow synth --out before --start 2022-04-11T08:36 --days 0.01 --rate 2 \\
      --reality-set support_spring_south=2e7
  bridge-shadow synth --out after --start 2022-04-11T09:20 --days 0.01 --rate 2 \\
      --reality-set support_spring_south=2e7 --step 0:-0.01:-0.01

Long records stream: a record of more than 250,000 force samples (2.9 days at 1 Hz, 42 min at
100 Hz) is simulated and written segment by segment, in bounded memory (about 250 MB), the
weather, test-car crossings and settlement path continuous over the whole record. --archive DIR
writes a multi-day, multi-bridge archive the same way, one bag per --bag-days:
  bridge-shadow synth --archive /tmp/fleet --bridges 3 --days 30 --rate 1
  bridge-shadow archive /tmp/fleet

Effects (--effect NAME=VALUE, repeatable; SI units; see bridge_shadow/effects.py):
""" + "\n".join(f"  {e.name:<20} [{e.unit}] e.g. {e.realistic:g} (edge {e.edge:g})" for e in EFFECTS.values())
DESCRIPTION += """

support_spring takes K (N/m, a spring under both central bearings), south:K, north:K or KS,KN;
slab_joint_opening is the fraction of slab-joint stiffness kept over the hogging zone (1 = closed)."""


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, not {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options of ``synth``."""
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--out", metavar="BAG", help="output bag directory")
    where.add_argument(
        "--archive",
        metavar="DIR",
        help="write an archive instead: DIR/bridge_NN/day_DDDD bags of --bag-days each, per bridge a "
        "record of --days (seed + NN), its truth in DIR/bridge_NN/truth.yaml; for `bridge-shadow archive`",
    )
    parser.add_argument(
        "--bridges", type=int, default=None, metavar="N", help="with --archive: bridges (default 1)"
    )
    parser.add_argument(
        "--bag-days", type=float, default=None, metavar="D", help="with --archive: days per bag (default 1)"
    )
    parser.add_argument("--days", type=float, default=3.0, help="record length in days (default 3)")
    parser.add_argument("--rate", type=float, default=1.0, metavar="HZ", help="force rate, Hz (default 1)")
    parser.add_argument(
        "--temp-rate",
        type=float,
        default=1.0 / 60.0,
        metavar="HZ",
        help="air-temperature rate, Hz (default 1/60)",
    )
    parser.add_argument("--seed", type=_seed, default=0, help="random seed, >= 0 (default 0)")
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="inject an effect of the vocabulary with a magnitude in SI units (repeatable)",
    )
    parser.add_argument(
        "--step",
        action="append",
        default=[],
        metavar="DAY:SOUTH:NORTH",
        help="extra settlement step from DAY (days after the start) on, in m, positive upward (repeatable)",
    )
    parser.add_argument(
        "--reality-set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="the reality's FE parameter (repeatable; one FE solve of config/bridge.yaml at synth time)",
    )
    parser.add_argument(
        "--reality-mesh",
        default=None,
        metavar="LEVEL",
        help="with --reality-set: mesh of the reality's FE solve (coarse, default, fine; default: default)",
    )
    parser.add_argument(
        "--reality-surrogate",
        metavar="YAML",
        help="the reality's surrogate file (instead of config/surrogate.yaml)",
    )
    parser.add_argument(
        "--start",
        default=None,
        metavar="ISO",
        help="first stamp, ISO 8601; local Europe/Berlin unless it has an offset (default 2022-03-14T00:00)",
    )
    parser.add_argument("--storage", choices=("sqlite3", "mcap"), default="sqlite3", help="bag storage")
    parser.add_argument(
        "--compress", action="store_true", help="zstd-compress the MCAP chunks (mcap only, ~3.5x smaller)"
    )
    parser.add_argument(
        "--force", "--overwrite", dest="force", action="store_true", help="replace an existing bag at --out"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object with the summary")
    add_engine_options(parser, "with --archive: write the bags")


def _parse_steps(items: list[str]) -> list[tuple[float, float, float]]:
    import math

    from bridge_shadow.errors import InputError
    from bridge_shadow.estimate.parameters.specs import check_settlement_m

    steps = []
    for item in items:
        try:
            day, south, north = (float(v) for v in item.split(":"))
        except ValueError:
            raise InputError(f"--step {item!r}: expected DAY:SOUTH:NORTH (days, m, m)") from None
        if not math.isfinite(day) or day < 0:
            raise InputError(f"--step {item!r}: DAY must be a finite number >= 0")
        for side, value in (("SOUTH", south), ("NORTH", north)):
            check_settlement_m(f"--step {item!r}: {side}", value)
        steps.append((day, south, north))
    return steps


def _reality(args: argparse.Namespace) -> dict[str, Any]:
    """``simulate`` keyword arguments for the reality asked for (none: the default surrogate)."""
    from bridge_shadow.errors import InputError
    from bridge_shadow.model.config import parse_overrides
    from bridge_shadow.twin.reality import reality_from_file, reality_from_parameters

    if args.reality_set and args.reality_surrogate:
        raise InputError("give --reality-set or --reality-surrogate, not both")
    if args.reality_mesh is not None and not args.reality_set:
        raise InputError("--reality-mesh is the mesh of a --reality-set solve; without one it does nothing")
    if args.reality_surrogate:
        reality = reality_from_file(args.reality_surrogate)
    elif args.reality_set:
        overrides = parse_overrides(args.reality_set, "--reality-set")
        reality = reality_from_parameters(overrides, args.reality_mesh or "default")
    else:
        return {}
    return {"surrogate": reality.surrogate, "sensitivities_block": reality.block, "reality": reality.info}


def _bag_bytes(path: Any) -> int:
    return sum(f.stat().st_size for f in path.iterdir() if f.is_file())


def run(args: argparse.Namespace) -> int:
    """Simulate, write the bag and its truth, print a summary."""
    from bridge_shadow.bagio import check_bag_target
    from bridge_shadow.commands.output import emit_json
    from bridge_shadow.errors import InputError
    from bridge_shadow.estimate.parameters.specs import VALUE_SPECS, check_value
    from bridge_shadow.twin.bag import write_twin_bag
    from bridge_shadow.twin.simulate import parse_effects
    from bridge_shadow.twin.stream import SEGMENT_SAMPLES, record_samples, record_segments, write_stream_bag
    from bridge_shadow.twin.truth import truth_path

    check_value("--days", args.days, "float", VALUE_SPECS["days"])
    check_value("--rate", args.rate, "float", VALUE_SPECS["rate_hz"])
    check_value("--temp-rate", args.temp_rate, "float", VALUE_SPECS["rate_hz"])
    if args.compress and args.storage != "mcap":
        raise InputError("compression is available for mcap storage only")
    world = {
        "seed": args.seed,
        "effects": parse_effects(args.effect),
        "start": args.start,
        "temp_rate_hz": args.temp_rate,
        "steps": _parse_steps(args.step),
    }
    late = [s for s in world["steps"] if s[0] >= args.days]
    if late:
        day, south, north = late[0]
        raise InputError(
            f"--step {day:g}:{south:g}:{north:g}: day {day:g} lies outside the record of --days {args.days:g}"
        )
    if args.archive:
        return _archive(args, world)
    if args.workers is not None or args.scheduler:
        raise InputError(
            "--workers and --scheduler write the bags of an --archive; one --out bag is one task"
        )
    if args.bridges is not None or args.bag_days is not None:
        raise InputError("--bridges and --bag-days shape an --archive; one --out bag is one bridge's record")
    check_bag_target(args.out, args.force)  # before the simulation
    world.update(_reality(args))
    if record_samples(args.days, args.rate) <= SEGMENT_SAMPLES:
        out, truth = write_twin_bag(
            args.out,
            storage=args.storage,
            overwrite=args.force,
            compress=args.compress,
            days=args.days,
            rate_hz=args.rate,
            **world,
        )
    else:  # streamed segment by segment, in bounded memory
        out, truth = write_stream_bag(
            args.out,
            record_segments(args.days, args.rate, **world),
            storage=args.storage,
            overwrite=args.force,
            compress=args.compress,
        )
    truth_file = truth_path(out)
    counts = truth["counts"]
    summary = {
        "bag": str(out),
        "storage": args.storage,
        "compressed": bool(args.compress),
        "bytes": _bag_bytes(out),
        "truth": str(truth_file),
        "seed": truth["seed"],
        "duration_s": 86400.0 * truth["days"],  # SI (the JSON's); --days for people
        "rate_hz": truth["rate_hz"],
        "temp_rate_hz": truth["temp_rate_hz"],
        "start": truth["start"],
        "effects": truth["effects"],
        "messages": {
            "/bridge/frc_01/force": counts["force_messages"]["frc_01"],
            "/bridge/frc_02/force": counts["force_messages"]["frc_02"],
            "/bridge/air_temperature": counts["temperature_messages"],
        },
        "nan": {**counts["force_nan"], "air_temperature": counts["temperature_nan"]},
        "surrogate": truth["surrogate"]["provenance"].get("solver", "unknown"),
        "reality": truth["reality"],
    }
    if args.json:
        emit_json(summary)
        return 0
    eff = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in truth["effects"].items())
    eff = eff or "none (baseline)"
    m = summary["messages"]
    print(
        f"wrote {out} ({args.storage}, {summary['bytes'] / 1e6:.2f} MB): {truth['days']:g} days from "
        f"{truth['start_local']}, forces {m['/bridge/frc_01/force']} + {m['/bridge/frc_02/force']} msgs "
        f"at {truth['rate_hz']:g} Hz, air temperature {m['/bridge/air_temperature']} msgs; "
        f"seed {truth['seed']}; effects: {eff}; surrogate: {summary['surrogate']}; truth in {truth_file}"
    )
    return 0


def _archive(args: argparse.Namespace, world: dict[str, Any]) -> int:
    """Write ``--archive DIR``: bridges x days in bags of ``--bag-days``; print a summary."""
    import sys
    import time
    from pathlib import Path

    from bridge_shadow.commands.output import emit_json, progress
    from bridge_shadow.engine import optional_mapper
    from bridge_shadow.errors import InputError
    from bridge_shadow.fileio import check_output_dir
    from bridge_shadow.twin.simulate import simulate
    from bridge_shadow.twin.stream import write_archive

    t0 = time.perf_counter()
    args.bridges = 1 if args.bridges is None else args.bridges
    args.bag_days = 1.0 if args.bag_days is None else args.bag_days
    if args.bridges < 1:
        raise InputError(f"--bridges must be at least 1 (got {args.bridges})")
    if not (0 < args.bag_days < float("inf")):
        raise InputError(f"--bag-days must be a positive number of days (got {args.bag_days})")
    folder = Path(args.archive)
    check_output_dir(folder, "archive folder")
    taken = [p for p in (folder / f"bridge_{b:02d}" for b in range(args.bridges)) if p.exists()]
    if taken and not args.force:
        raise InputError(f"{taken[0]}: exists already (use --force to replace the archive's bridges)")
    if args.force:  # the archive's bridges, all: one more from before would join the next `archive`
        import re
        import shutil

        for p in sorted(folder.glob("bridge_*")) if folder.is_dir() else []:
            if p.is_dir() and re.fullmatch(r"bridge_\d{2,}", p.name):
                shutil.rmtree(p)
    world.update(_reality(args))
    simulate(min(args.days, args.bag_days), args.rate, span=(0, 1), **world)  # bad arguments fail now
    show = None if args.json or not sys.stderr.isatty() else (lambda f: progress(f, "synth"))
    with optional_mapper(args.scheduler, args.workers) as mapper:
        bridges = write_archive(
            folder,
            bridges=args.bridges,
            days=args.days,
            rate_hz=args.rate,
            bag_days=args.bag_days,
            storage=args.storage,
            compress=args.compress,
            progress=show,
            mapper=mapper,
            **world,
        )
    summary = {
        "archive": str(folder),
        "bridges": bridges,
        "duration_s": 86400.0 * args.days,  # SI (the JSON's); --days, --bag-days for people
        "bag_duration_s": 86400.0 * args.bag_days,
        "rate_hz": args.rate,
        "storage": args.storage,
        "seconds": time.perf_counter() - t0,
    }
    if args.json:
        emit_json(summary)
    else:
        bags = sum(b["bags"] for b in bridges)
        msgs = sum(
            sum(b["counts"]["force_messages"].values()) + b["counts"]["temperature_messages"] for b in bridges
        )
        print(
            f"wrote {folder}: {len(bridges)} bridge(s), {bags} bags of {args.bag_days:g} days, "
            f"{msgs} messages ({args.days:g} days at {args.rate:g} Hz each) in {summary['seconds']:.1f} s"
        )
    return 0
