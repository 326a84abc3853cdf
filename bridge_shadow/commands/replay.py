"""``bridge-shadow replay``: run a monitoring bag through the shadow (direct or through DDS)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

HELP = "replay a monitoring bag through the shadow: posterior settlements, compensation, gating"
DESCRIPTION = """\
Replay a rosbag2 bag with the input topics (the contract's /bridge/frc_01/force,
/bridge/frc_02/force and /bridge/air_temperature, or the topic_* parameters) through the online
shadow: gate -> 60 s windows -> P-spline temperature compensation -> Kalman update of the two
central-support settlements over u = A x + u0.

By default the bag is decoded vectorized and fed to the pipeline directly; --live plays it through
the rclpy node in a loopback DDS graph (same pipeline, same posterior). Parameters come from
config/shadow.yaml or --params; the replay ignores checkpoint_path there (a running node's
state is never touched) unless --checkpoint PATH names a checkpoint to resume and write. --json
prints one object: posterior.mean_m [south, north] (m), posterior.covariance_m2 (m^2), messages
used and rejected by reason, detected settlement events (time, window, size per support in m
with covariance and 95 % interval), warnings, the prior in use, spline edf and lambda per
channel, and the rates: messages_per_s and seconds end to end (from the command's start:
imports, model, bag read and decode, shadow, --out; not --plots), pipeline_messages_per_s and
pipeline_seconds for the shadow alone (live: publishing to the node's flush).

Nothing fails silently: a missing air-temperature topic runs uncompensated, windows whose air
reading is more than temperature_stale_s away are used with their compensation widened, a change
across a gap or among the first windows (of the data or after a gap) is weighed by the data and
reported, a run of windows rejected as an excursion that came back is reported with its size
when it moved the reactions' sum by more than any vehicle (traffic_vehicle_max_n), a topic whose
every message is rejected is named with the reason and the expected value, and so is a tenth of
a topic's messages rejected for their values or stamps (late ones too), load cells delivering
nothing usable to the end of the data, an event that moved one load cell alone (a sensor fault
fits it too), an air temperature that jumps more than air can, and windows too short for the
data's rate (WARN lines on stderr and "warnings" in the JSON); a replay in which no window
updated the estimate exits with 1.

--out and --plots work in both modes (live: drawn from the node's history service and final
checkpoint); --out never replaces an existing bag without --force. The text output's first line
(the bag and the surrogate in use, with the condition number of A) is printed before the work.
Outside make, --live keeps DDS on loopback in a domain of its own unless
ROS_AUTOMATIC_DISCOVERY_RANGE is set. The direct replay streams the bag in bounded memory: --out
is written as windows close, and --plots draws at most 10,000 windows, evenly spaced over the
record. A progress bar shows on a terminal unless --json.

To watch the topics of a paced live replay (the ros2 command-line tools are not in the venv:
they are not on the package index), --watch prints the node's latest outputs once a second:
  bridge-shadow replay bags/demo_3d --live --rate 3600 --watch
"""


#: Window counts the text summary names when non-zero: JSON key, words.
WINDOW_NOTES = (("uncompensated", "uncompensated"), ("stale_temperature", "with stale temperature"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add BAG, --params, --live, --rate, --out, --plots, --checkpoint, --watch, --json."""
    parser.add_argument(
        "bag",
        metavar="BAG",
        nargs="+",
        help="rosbag2 directory (sqlite3 or MCAP); several BAGs (e.g. a record's forces and its air "
        "temperature, overlapping in time) are read as one stream merged by log time (with --live too)",
    )
    parser.add_argument("--params", metavar="YAML", help="shadow parameter file (default config/shadow.yaml)")
    parser.add_argument(
        "--surrogate",
        metavar="YAML",
        help="surrogate file (default: the parameter surrogate_path, else config/surrogate.yaml, the "
        "calibrated model; config/surrogate_fe.yaml is the uncalibrated FE surrogate)",
    )
    parser.add_argument("--live", action="store_true", help="play through the rclpy node over DDS (loopback)")
    parser.add_argument(
        "--rate",
        type=float,
        metavar="X",
        help="with --live: publish at X times the bag's pace (1 = real time; default: as fast as taken)",
    )
    parser.add_argument("--out", metavar="OUTBAG", help="write the outputs (mean, covariance, ...) as a bag")
    parser.add_argument("--force", action="store_true", help="replace an existing bag at --out")
    parser.add_argument(
        "--storage", choices=("sqlite3", "mcap"), default="sqlite3", help="storage of the --out bag (sqlite3)"
    )
    parser.add_argument("--plots", metavar="DIR", help="write PNG plots (compensation, posterior, ellipse)")
    parser.add_argument(
        "--checkpoint",
        metavar="PATH",
        help=(
            "resume from this checkpoint if it exists and write the state there (periodically and at "
            "the end; with --live once, at the end: an interrupted live run leaves it as it was), the "
            "air temperature past the bag's last force held in it for the next bag's replay; a bag it "
            "took already is said and not replayed (its result printed, exit 0), a bag of older data "
            "leaves it as it was (exit 1); without it the replay neither reads nor writes a "
            "checkpoint, whatever checkpoint_path the --params file names (that is the live node's)"
        ),
    )
    parser.add_argument(
        "--watch",
        action="store_true",
        help="with --live: print the node's latest outputs (settlements, compensated forces, "
        "diagnostics) as they arrive, one line a second on stderr",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object (SI units)")


def _summary(js: dict[str, Any]) -> str:
    import numpy as np

    from bridge_shadow.timefmt import iso_utc

    mean = np.array(js["posterior"]["mean_m"])
    cov = np.array(js["posterior"]["covariance_m2"])
    sd = np.sqrt(np.diag(cov))
    rho = cov[0, 1] / (sd[0] * sd[1]) if sd.all() else float("nan")
    msgs = js["messages"]
    resumed = js.get("resumed")
    lines = [
        *(
            [
                "the bag(s) were taken whole into the checkpoint already: nothing replayed, "
                "the result is the checkpoint's"
            ]
            if js.get("already_taken")
            else []
        ),
        *(
            [
                f"resumed from a checkpoint of {resumed['windows']} windows ({resumed['updates']} updates, "
                f"{resumed['messages_used']} messages used"
                + (f", {h} air readings held" if (h := resumed.get("held_air")) else "")
                + (
                    # a bag taken already: no message read; the held air is the checkpoint's own
                    "): nothing below is of this run but the end-of-data close made again"
                    + (", which feeds the air held" if h else "")
                    if js.get("already_taken")
                    else "): the counts below are this run's" + (", the held air's among them" if h else "")
                )
            ]
            if resumed
            else []
        ),
        "posterior settlement (positive upward, 95% interval):",
        *(
            f"  {name:5s} {1e3 * m:+8.3f} mm ± {1e3 * 1.96 * s:.3f} mm"
            for name, m, s in zip(("south", "north"), mean, sd, strict=True)
        ),
        f"  correlation {rho:+.3f}",
        f"messages: {msgs['total']} in, {msgs['used']} used, {msgs['rejected']} rejected; "
        f"{js['messages_per_s']:.0f} msg/s",
        f"windows: {js['windows']['closed']} closed, {js['windows']['updates']} updates"
        + "".join(f", {n} {what}" for key, what in WINDOW_NOTES if (n := js["windows"].get(key, 0))),
        *_at_end_line(js["windows"].get("at_end")),
    ]
    from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS

    rejected = {k: v for k, v in js["rejected"].items() if v}
    messages = {k: v for k, v in rejected.items() if k in MESSAGE_REASONS}
    windows = {k: v for k, v in rejected.items() if k not in MESSAGE_REASONS}
    if messages:
        lines.append("rejected messages: " + ", ".join(f"{k} {v}" for k, v in messages.items()))
    if windows:
        lines.append("windows not used: " + ", ".join(_windows_text(k, v, js) for k, v in windows.items()))
    traffic = js.get("traffic", {})
    if traffic.get("windows_cut"):
        cut = traffic["samples_cut"]
        lines.append(
            f"traffic screen: {cut[0]} / {cut[1]} samples (south/north) of vehicles cut from "
            f"{traffic['windows_cut']} windows of short records (JSON `traffic`)"
        )
    released = traffic.get("released_unscreened", [])
    if released and traffic.get("hold_s"):
        lines.append(
            f"traffic screen: {len(released)} record(s) longer than traffic_hold_s "
            f"({traffic['hold_s']:g} s) passed unscreened, the first since {released[0]['since']} "
            "(a vehicle parked in them is data; continuous monitoring is, after its first hold)"
        )
    prior = js.get("prior", {})
    if prior:
        lines.append(
            "prior: sigma "
            + "/".join(f"{1e3 * s:.2f}" for s in prior["sigma_m"])
            + f" mm ({prior['source']})"
        )
    for i, e in enumerate(js.get("events", []), 1):
        size = ", ".join(
            f"{side} {1e3 * m:+.3f} ± {1.96e3 * sd:.3f} mm"
            for side, m, sd in zip(("south", "north"), e["size_m"], e["sigma_m"], strict=True)
        )
        if not e.get("size_significant95", True):
            size += " (its 95 % region holds zero: the forces changed, a settlement is not proven)"
        what = {
            "gap": "change across a gap",
            "held_run": "change at the end of a held run",
            "warmup": "step among the first windows (warm-up or after a gap)",
        }.get(e.get("kind", "step"), "settlement step")
        lines.append(f"event {i}: {what} at {iso_utc(e['time_ns'])}: {size}")
    for i, c in enumerate(js.get("unconfirmed_changes", []), 1):
        size = ", ".join(
            f"{side} {1e3 * m:+.3f} ± {1.96e3 * sd:.3f} mm"
            for side, m, sd in zip(("south", "north"), c["size_m"], c["sigma_m"], strict=True)
        )
        windows = f"{c['windows']} window{'s' if c['windows'] != 1 else ''}"
        if c["kind"] == "run_in_data":
            how = f"a run of {windows} until {c['until']} without a step's jump, used as data"
        elif c["kind"] == "excursion":
            how = (
                f"a run of {windows} until {c['until']} that came back, heavier than any "
                "vehicle: rejected as an excursion"
            )
        elif c["kind"] == "between_steps":
            how = (
                f"a state of {windows} until {c['until']} between two steps, heavier than "
                "any vehicle: left out"
            )
        elif c["kind"] == "before_gap":
            how = (
                "one window before a gap, no heavier than any vehicle: left out, the gap's segment "
                "weighs any change"
            )
        elif c["kind"] == "after_gap":
            how = (
                "a gap's first window before a drop no heavier than any vehicle (one that left): "
                "left out, the gap's segment begins after it"
            )
        elif c["kind"] == "at_end":
            how = (
                "the data's last window, no heavier than any vehicle: left out, one window cannot "
                "tell a vehicle that drove on from the window a step happened in"
            )
        elif c["kind"] == "step":
            how = "a step the detector found, its size not told from zero on the data: no event"
        else:
            where = {
                "gap": f"after a gap of {c['gap_s'] / 3600.0:.1f} h",
                "warmup": "a step among the first windows (the warm-up, or those after a gap)",
            }.get(c["kind"], "a held run")
            how = f"{where}, change probability {c['change_probability']:.3g}"
        lines.append(f"unconfirmed change {i} at {c['time']} ({how}): {size}")
    state = js["posterior"].get("state", {})
    if state.get("text"):
        lines.append(f"the posterior stands for {state['text']}")
    for ch, sp in js["spline"].items():
        if not sp["windows"]:  # nothing fitted: no numbers to print (null in JSON, NaN in a direct result)
            lines.append(f"compensation {ch}: no window used, no curve fitted")
            continue
        # JSON carries a non-finite lambda (no curve: no temperature) as null (the live node's report)
        lam = float("inf") if sp["lambda"] is None else sp["lambda"]
        lines.append(
            f"compensation {ch}: {sp['edf']:.2f} effective degrees of freedom, lambda {lam:.3g} °C³, "
            f"level {1e-3 * sp['mean_force_n']:.2f} kN over {sp['windows']} windows" + _sun_text(sp)
        )
    return "\n".join(lines)


def _factor(lbf: float | None) -> str:
    """``Bayes factor 1.3`` (``e^60`` when large) of a natural log; a note when none was computed."""
    if lbf is None or not math.isfinite(lbf):
        return "no Bayes factor yet"
    return f"Bayes factor {math.exp(lbf):.3g}" if lbf < 50.0 else f"Bayes factor e^{lbf:.0f}"


def _sun_text(sp: dict[str, Any]) -> str:
    """``, sun term ...``: the sun term's difference at full sun and its Bayes factor, or why it is out."""
    if "sun_gradient_k" not in sp:
        return ""
    deck, apart = sp.get("sun_gradient_log_bf"), sp.get("sun_gradient_log_bf_per_bearing")
    half = 1.96 * sp["sun_gradient_sd_k"]
    weight = sp.get("sun_gradient_weight")
    if sp.get("sun_gradient_fit") == "average" and weight is not None and math.isfinite(weight):
        return (
            f", sun term {sp['sun_gradient_k']:.2f} ± {half:.2f} K at full sun (the deck's g averaged "
            f"in with probability {weight:.2f}; {_factor(deck)} for one g, {_factor(apart)} for one each)"
        )
    lbf = deck if sp.get("sun_gradient_fit") == "deck" else apart  # the factor of the term in use
    known = lbf is not None and math.isfinite(lbf)  # (JSON: null where not computed)
    bf = _factor(lbf)
    if not sp.get("sun_gradient_used", True):
        if known and apart is not None and apart > lbf:
            return f", sun term not used ({bf}; a g of each bearing's own fits better: not the deck's sun)"
        return f", sun term not used ({bf}, below sun_gradient_min_bayes_factor)"
    return f", sun term {sp['sun_gradient_k']:.2f} ± {half:.2f} K at full sun ({bf})"


def _windows_text(reason: str, count: int, js: dict[str, Any]) -> str:
    """``outlier 2 (at ...)``: the count of one reason with the windows' times (first and last of many)."""
    times = [w["time"] for w in js.get("rejected_windows", []) if w["reason"] == reason]
    if not times:
        return f"{reason} {count}"
    shown = ", ".join(times) if len(times) <= 3 else f"{times[0]} ... {times[-1]}"
    return f"{reason} {count} ({shown})"


def _loud(js: dict[str, Any]) -> int:
    """WARN lines on stderr for what must not pass silently; the exit code.

    1 when no window updated the estimate, or when none of this run's load-cell messages was used
    (a bag replayed after a checkpoint of later data: the windows the checkpoint held open may
    still update, but nothing of the bag reached the estimate).
    """
    import sys

    from bridge_shadow.contract import CHANNELS

    for line in js.get("warnings", []):
        print(f"bridge-shadow replay: WARN: {line}", file=sys.stderr)
    if js.get("already_taken"):
        return 0  # the checkpoint's own result: nothing of the bags was to be used (said)
    if held := js.get("air_held_whole"):
        print(
            f"bridge-shadow replay: the bag holds no load-cell message: its {held} air readings are held "
            "in the checkpoint, for the next bag's replay to merge with its forces",
            file=sys.stderr,
        )
        return 0
    used = js["messages"]["used_by_topic"]
    if js.get("resumed") and js["windows"]["updates"] and not any(used.get(ch, 0) for ch in CHANNELS):
        print(
            "bridge-shadow replay: error: none of this run's load-cell messages was used (the updates are "
            "of the data the checkpoint held"
            + ("; the checkpoint is left as it was" if js.get("checkpoint_kept") else "")
            + "); see the WARN lines and the rejected counts",
            file=sys.stderr,
        )
        return 1
    if not js["windows"]["updates"]:
        what = "the checkpoint's" if js.get("resumed") else "the prior"
        print(
            f"bridge-shadow replay: error: no window updated the estimate (the posterior printed is {what}); "
            "see the WARN lines and the rejected counts",
            file=sys.stderr,
        )
        return 1
    return 0


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

    from bridge_shadow.bagio import check_bag_target
    from bridge_shadow.commands.output import progress
    from bridge_shadow.errors import InputError
    from bridge_shadow.estimate import load_config
    from bridge_shadow.estimate.parameters.specs import VALUE_SPECS, check_value
    from bridge_shadow.fileio import check_output_dir
    from bridge_shadow.model.surrogate_file import describe_surrogate, load_surrogate

    show = None if args.json or not sys.stderr.isatty() else (lambda f: progress(f, "replay"))
    if args.rate is not None:
        if not args.live:
            raise InputError("--rate needs --live (it paces the publishing to the node)")
        check_value("--rate", args.rate, "float", VALUE_SPECS["rate"])
    if args.watch and not args.live:
        raise InputError("--watch needs --live (it shows the node's topics)")
    bags = [args.bag] if isinstance(args.bag, str | Path) else list(args.bag)
    bag = bags[0] if len(bags) == 1 else bags  # one bag: read as ever; several: merged
    # the outputs are checked before the replay runs, so a bad path costs no time
    if args.out:
        check_bag_target(args.out, args.force, reading=bags)
    if args.plots:
        check_output_dir(args.plots, "plot directory")
    over = {"surrogate_path": str(Path(args.surrogate).resolve())} if args.surrogate else None
    # a params file's checkpoint_path belongs to the live node: never read or written here
    config = load_config(args.params, over).replace(checkpoint_path=args.checkpoint or "")
    surrogate = load_surrogate(config.surrogate_path or None)  # a bad file stops us here, one line
    if not args.json:
        # the first line leaves at once: a reader that takes it and goes (`| head -1`) ends the
        # replay with exit 141 when the result is written, as any tool whose pipe was closed
        mode = " (live)" if args.live else ""
        used = describe_surrogate(surrogate, config.surrogate_path or None)
        print(f"replay {' + '.join(map(str, bags))}{mode}: surrogate {used}", flush=True)
    # a bag the checkpoint took whole before (the same command again): said, nothing changed
    taken = _signatures(bags) if args.checkpoint else []
    if taken and (again := _already_taken(args, config, surrogate, bags, taken)) is not None:
        _end_to_end_rate(again, started)
        return _report(again, args.json)
    if args.live:
        from bridge_shadow.ros.live_replay import run_live

        before = _resumed_counts(config, surrogate, args.checkpoint)
        js = run_live(
            bag,
            args.params,
            out=args.out,
            overwrite=args.force,
            storage=args.storage,
            plots=args.plots,
            rate=args.rate,
            overrides=over,
            progress=None if args.watch else show,
            checkpoint=args.checkpoint,
            watch=args.watch,
            taken=taken,
        )
        if before is not None:
            _this_run(js, before)
        _end_to_end_rate(js, started)
        return _report(js, args.json)

    from bridge_shadow.contract import INPUT_TOPICS
    from bridge_shadow.estimate.startup import open_shadow
    from bridge_shadow.replay import HISTORY_CAPACITY, replay_bag
    from bridge_shadow.replay.air_tail import mark_air_held_whole

    shadow, notes = open_shadow(config, surrogate)  # an unusable checkpoint stops us before the bag
    for line in notes:
        print(f"bridge-shadow replay: {line}", file=sys.stderr)
    before = _counts(shadow) if _has_counted(shadow) else None  # resumed: count this run apart
    # streamed in bounded memory; outputs go to --out as windows close, --plots keeps a decimated
    # history; the air temperature may be absent: the shadow then runs uncompensated and says so
    history = HISTORY_CAPACITY if args.plots else None
    result, stats = replay_bag(
        bag,
        shadow,
        out=args.out,
        overwrite=args.force,
        storage=args.storage,
        history=history,
        progress=show,
        required=list(INPUT_TOPICS)[:2],
        taken=taken,
    )
    js = result.to_json()
    if before is not None:
        _this_run(js, before)
    if stats.checkpoint_kept:
        js["checkpoint_kept"] = True  # none of the bag's load-cell messages used: not written
    elif config.checkpoint_path:
        # the checkpoint holds the state before the end-of-data close: the next bag's run closes
        # these windows again and counts them too (a chain's windows add up less these)
        js["windows"]["at_end"] = {
            "closed": stats.closed_at_end,
            "updates": stats.updates_at_end,
            "held_air": stats.held_air,
        }
        mark_air_held_whole(js, stats.forces, stats.held_air)
    js["bag"] = str(bags[0])
    if len(bags) > 1:
        js["bags"] = [str(b) for b in bags]  # read merged by log time
    js["surrogate"] = surrogate.summary()
    if args.out:
        js["out"] = str(args.out)
    _end_to_end_rate(js, started)
    if args.plots:
        from bridge_shadow.estimate.plots import write_plots

        js["plots"] = [str(p) for p in write_plots(args.plots, result, shadow)]
    return _report(js, args.json)


def _signatures(bags: list[Any]) -> list[dict[str, Any]]:
    """Return each bag's signature (``replay.taken``); none if a bag cannot be read (the replay says why)."""
    from bridge_shadow.bagio.errors import BagError
    from bridge_shadow.replay.taken import bag_signature

    try:
        return [bag_signature(b) for b in bags]
    except BagError:
        return []


def _already_taken(
    args: argparse.Namespace, config: Any, surrogate: Any, bags: list[Any], signatures: list[dict[str, Any]]
) -> dict[str, Any] | None:
    """Return the replay JSON of bags the checkpoint took whole already (``replay.taken``), else None.

    Their messages all lie at or before the checkpoint's data: replayed, every one was rejected,
    the run exited 1 and the checkpoint was written again. Instead nothing is read or written: the
    result is the checkpoint's, its end-of-data close made again (with the air it holds), as the
    run that took the bags printed it (with ``--live`` too: no node is started). None: no usable
    checkpoint (the replay says what it does about it), or a bag it did not take.

    Raises:
        InputError: ``--out`` or ``--plots`` asked for (there is nothing of the bags to write).

    """
    import json
    import sys
    from collections import Counter

    import numpy as np

    from bridge_shadow.contract import CHANNELS
    from bridge_shadow.errors import InputError
    from bridge_shadow.estimate import Shadow
    from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS
    from bridge_shadow.estimate.state.checkpoint import CheckpointError, load_entry
    from bridge_shadow.replay.air_tail import air_piece
    from bridge_shadow.replay.taken import find_taken
    from bridge_shadow.series import TemperatureSeries

    file = Path(args.checkpoint)
    listed = load_entry(file, "taken_bags")  # a look first: one entry (None: no checkpoint there)
    found = None if listed is None else find_taken(json.loads(str(listed)), signatures)
    if found is None:
        return None
    try:  # the checkpoint's own state; nothing written (no checkpoint path)
        shadow = Shadow.resume(file, config.replace(checkpoint_path=""), surrogate)
    except CheckpointError:
        return None
    what = "; ".join(
        f"{bag} ({e['messages']} messages, {e['start']} to {e['end']}; taken by the run of {e['taken_at']})"
        for bag, e in zip(bags, found, strict=True)
    )
    said = f"taken whole into {file} already: {what}"
    if args.out or args.plots:
        raise InputError(
            f"{said}: the checkpoint's data reach past them, so a replay from it has nothing of them for "
            "--out or --plots; replay them without --checkpoint for their outputs and plots"
        )
    print(
        f"bridge-shadow replay: {said} (the same files, unchanged since): nothing replayed, "
        "the checkpoint is left as it was; the result printed is the checkpoint's",
        file=sys.stderr,
    )
    before = _counts(shadow)
    no_air = TemperatureSeries(np.empty(0, np.int64), np.empty(0))
    shadow.run(air_piece(no_air, CHANNELS))  # the air it holds fed, then the end-of-data close
    # that air is the checkpoint's own, fed by the run that took the bags: no message of this run
    # (nor a warning judging one: "no load cell message" of the air alone)
    for ledger in shadow.ledgers:
        ledger.used_before, ledger.rejected_before = ledger.used, Counter(ledger.rejected)
    js = shadow.result([], 0, 0.0).to_json()
    rejected = {
        r: (n if r in MESSAGE_REASONS else before["rejected"].get(r, 0)) for r, n in shadow.rejected.items()
    }
    _this_run(js, {**before, "used": dict(shadow.used), "rejected": rejected})
    js["already_taken"] = [{**e, "bag": str(bag)} for bag, e in zip(bags, found, strict=True)]
    js["bag"] = str(bags[0])
    if len(bags) > 1:
        js["bags"] = [str(b) for b in bags]
    js["surrogate"] = surrogate.summary()
    return js


def _at_end_line(at_end: dict[str, int] | None) -> list[str]:
    """Say what the end-of-data close did, which a replay resumed from the checkpoint does again."""
    if not at_end:
        return []
    lines = []
    if at_end["closed"] or at_end["updates"]:
        lines.append(
            f"  of them at the end of the data: {at_end['closed']} closed, {at_end['updates']} updates "
            "(the checkpoint holds the state before: the next bag's replay makes them again, with its data)"
        )
    if held := at_end.get("held_air", 0):
        lines.append(
            f"  the checkpoint holds {held} air readings unfed (past the bag's last force, or all of a bag "
            "without forces): read in this run's counts, and again, merged, by the next bag's replay"
        )
    return lines


def _has_counted(shadow: Any) -> bool:
    """Whether a resumed shadow has counted anything: windows, or messages used or rejected.

    A checkpoint of a 12-minute record still held for the traffic screen has closed no window yet
    but has taken every message of it; the next bag's counts were then reported as the two bags'
    together (``290441 used`` of ``145192 in``) and without ``resumed``.
    """
    return bool(shadow.n_windows or any(shadow.used.values()) or any(shadow.rejected.values()))


def _counts(shadow: Any) -> dict[str, Any]:
    """Return what a (resumed) shadow has counted: messages used and rejected, windows, updates."""
    return {
        "used": dict(shadow.used),
        "rejected": dict(shadow.rejected),
        "windows": int(shadow.n_windows),
        "updates": int(shadow.n_updates),
        "held_air": len(shadow.held_air) if shadow.held_air is not None else 0,
        "uncompensated": int(shadow.uncompensated),
        "stale_temperature": int(shadow.stale_temperature),
    }


def _resumed_counts(config: Any, surrogate: Any, checkpoint: str | None) -> dict[str, Any] | None:
    """Return the counts of the checkpoint the live node will resume (None: it starts fresh)."""
    if not checkpoint or not Path(checkpoint).is_file():
        return None
    from bridge_shadow.estimate import Shadow
    from bridge_shadow.estimate.startup import UNUSABLE_HINT
    from bridge_shadow.estimate.state.checkpoint import CheckpointError

    try:
        shadow = Shadow.resume(Path(checkpoint), config, surrogate)
    except CheckpointError as err:  # unusable: the error the node would give, with its hint
        if config.checkpoint_unusable == "fresh":
            return None  # the node sets it aside and starts from the prior
        raise CheckpointError(f"{err} ({UNUSABLE_HINT})") from None
    return _counts(shadow) if _has_counted(shadow) else None


def _this_run(js: dict[str, Any], before: dict[str, Any]) -> None:
    """Make the counts of a resumed replay this run's (the shadow's own go on from the checkpoint).

    Without this, ``messages.total`` (this run's) sat beside ``used`` and ``rejected`` counted
    since the checkpoint's first window, which could add up to more than the messages read.
    ``resumed`` keeps what the checkpoint held.
    """
    from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS
    from bridge_shadow.estimate.result import split_rejected

    msgs = js["messages"]
    for topic, n in before["used"].items():
        msgs["used_by_topic"][topic] = msgs["used_by_topic"].get(topic, 0) - n
    msgs["used"] = int(sum(msgs["used_by_topic"].values()))
    for reason, n in before["rejected"].items():
        js["rejected"][reason] = js["rejected"].get(reason, 0) - n
    msgs["rejected"] = int(sum(v for k, v in js["rejected"].items() if k in MESSAGE_REASONS))
    msgs["rejected_by_reason"], js["windows"]["rejected_by_reason"] = split_rejected(js["rejected"])
    for key in ("uncompensated", "stale_temperature"):
        js["windows"][key] = js["windows"].get(key, 0) - before.get(key, 0)
    for key, name in (("closed", "windows"), ("updates", "updates")):
        js["windows"][key] -= before[name]
    js["resumed"] = {
        "windows": before["windows"],
        "updates": before["updates"],
        "messages_used": int(sum(before["used"].values())),
        "held_air": before["held_air"],  # fed this run, merged with the bag (counted in its messages)
    }


def _report(js: dict[str, Any], as_json: bool) -> int:
    """Check that the result is finite, print it (JSON or text), say what must not pass silently."""
    from bridge_shadow.commands.output import emit_json, require_finite

    post = js["posterior"]
    numbers = {"posterior.mean_m": post["mean_m"], "posterior.covariance_m2": post["covariance_m2"]}
    for i, e in enumerate(js.get("events", []), 1):
        numbers[f"events[{i}].size_m"] = e["size_m"]
    require_finite(numbers, "posterior")
    if as_json:
        emit_json(js)
    else:
        print(_summary(js))
    return _loud(js)
