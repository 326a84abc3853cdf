"""``bridge-shadow gap``: the sim-to-real gap diagnosis of a monitoring bag."""

from __future__ import annotations

import argparse
from typing import Any

from bridge_shadow.engine import add_engine_options

HELP = "diagnose the sim-to-real gap: where it lies, which effect causes it, how far it shrinks"
DESCRIPTION = """\
Diagnose the gap between the baseline model (FE surrogate u0, plus A x for a known imposed
settlement, plus its uniform thermal case) and the measured central reactions of a monitoring bag:

  where  share per channel, time of day, warming/cooling, sunny/overcast, frequency band, model part
  which  every effect of the vocabulary fitted on training days inside its plausible range and
         ranked by the held-out improvement (leave-one-day-out), with an AR(1) information
         criterion and partial effects; a fit that needs an implausible value is rejected and
         said so; every named effect comes with the effects the two reactions cannot tell from it
  how far  held-out residual RMS before/after per channel, and the shadow's posterior settlements
         before (the model in use: the answer of `bridge-shadow replay BAG`) and after adding
         the named effects to the model

Model-form effects (bearing_stiffness, connector_stiffness, support_spring, slab_joint_opening)
change A as well as u0 and the thermal response. Without a known settlement only their u0 and
thermal parts show: the reactions fix A x, not x. Give a known imposed settlement (a lowering of
the supports) with --imposed to let them act on A x.

A day of records (a load-test day: short records hours apart, less than two days of data): each
record is held out in turn for what happens inside the records, and the records' levels are
read pair by pair across every gap (`levels`): at a gap with an imposed step the model-form
effects are fitted to the response with the calibration's machinery (priors and plausible ranges
of bridge_shadow/model/parameters.py, Laplace evidence; the surrogate's parameter sweeps, no FE
solve) against the imposed step within the jacks' accuracy (--imposed-sd); at the other gaps
the settlement steps the shadow estimates. The named effect goes into the model for `after`.

--out-surrogate FILE writes the model with the named effects added (for `replay --surrogate`
and the node's surrogate_path), with its uncertainty and a discrepancy beyond the settlements
it was fitted on. Effects that change the model (a stiffness, a support spring, the slab joint)
are in it; effects that are loads (thermal, traffic, sensor drift) are taken off the record for
`after` only, which no surrogate can carry: the file's header and a WARN line name them.

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
    parser.add_argument(
        "--surrogate",
        metavar="YAML",
        help="surrogate file (default: surrogate_path of the parameters, else config/surrogate.yaml)",
    )
    parser.add_argument("--params", metavar="YAML", help="shadow parameter file (default config/shadow.yaml)")
    parser.add_argument(
        "--imposed",
        action="append",
        default=[],
        metavar="WHEN=SOUTH,NORTH",
        help="a known imposed settlement step in m (positive upward) at WHEN: ISO 8601 (Europe/Berlin "
        "unless it has an offset) or +DAYS after the first sample; repeatable",
    )
    parser.add_argument(
        "--alternatives",
        action="store_true",
        help="also run the shadow with each model-form effect the data cannot tell from a named one "
        "standing in for it (one more replay each, at most two)",
    )
    parser.add_argument(
        "--imposed-sd",
        type=float,
        default=None,
        metavar="M",
        help="accuracy of an imposed step, 1 sd per bearing, m (default 0.0005: the jacks, as in "
        "config/calibration.yaml)",
    )
    parser.add_argument(
        "--out-surrogate",
        metavar="YAML",
        help="write the model with the named effects added here (usable by replay and the node)",
    )
    parser.add_argument(
        "--force", action="store_true", help="replace an existing surrogate file at --out-surrogate"
    )
    parser.add_argument("--window", type=float, default=60.0, metavar="S", help="window length in s (60)")
    parser.add_argument(
        "--baseline-change",
        choices=("uncertainty", "linear", "sun"),
        default="uncertainty",
        help="on a day of records, the baseline's change between them, as calibrate reads it: "
        "uncertainty (the drifts within the records over the hours between; default), linear, or "
        "sun (the deck's vertical temperature difference under the clear-sky sun and the day's "
        "clearness, with the sun term's prior)",
    )
    add_engine_options(parser, "fit every candidate's held-out folds (for long archives)")


def parse_imposed(
    items: list[str], first_ns: int, last_ns: int | None = None
) -> list[tuple[int, float, float]]:
    """``WHEN=SOUTH,NORTH`` strings -> ``(t_ns, dx_south_m, dx_north_m)``; InputError when malformed.

    A step must lie inside the record, ``(first_ns, last_ns]`` when ``last_ns`` is given: a step
    before the first sample or after the last one changes nothing the data can show.
    """
    import datetime as dt
    from zoneinfo import ZoneInfo

    from bridge_shadow.errors import InputError
    from bridge_shadow.estimate.parameters.specs import check_settlement_m

    out = []
    for item in items:
        when, sep, values = item.rpartition("=")
        try:
            if not sep:
                raise ValueError
            south, north = (float(v) for v in values.split(","))
            if when.startswith("+"):
                t_ns = first_ns + round(float(when[1:]) * 86400e9)
            else:
                stamp = dt.datetime.fromisoformat(when)
                if stamp.tzinfo is None:
                    stamp = stamp.replace(tzinfo=ZoneInfo("Europe/Berlin"))
                # whole microseconds since the epoch, exactly (rounding the float seconds and adding
                # the microseconds again put a time of .5 s or more a second late)
                since = stamp - dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)
                t_ns = since // dt.timedelta(microseconds=1) * 1000
        except ValueError:
            raise InputError(
                f"--imposed {item!r}: expected WHEN=SOUTH,NORTH (ISO time or +DAYS; metres, positive upward)"
            ) from None
        for side, value in (("SOUTH", south), ("NORTH", north)):  # as synth --step: finite, under a metre
            check_settlement_m(f"--imposed {item!r}: {side}", value)
        if last_ns is not None and not first_ns < t_ns < last_ns:  # at an edge: nothing after or before
            from bridge_shadow.timefmt import iso_utc

            raise InputError(
                f"--imposed {item!r}: {iso_utc(t_ns)} is outside the record "
                f"({iso_utc(first_ns)} to {iso_utc(last_ns)}): the data cannot show that step"
            )
        same = [i for i, (t, s, n) in enumerate(out) if (t, s, n) == (t_ns, south, north)]
        if same:  # a copied line, most likely: summed, it doubled the step without a word
            raise InputError(
                f"--imposed {item!r} is given twice (entry {same[0] + 1} and {len(out) + 1}): to impose "
                "twice that step at one time give their sum once; steps of the two bearings apart "
                "(T=S,0 and T=0,N) add up"
            )
        out.append((t_ns, south, north))
    # steps at one instant add up (south and north given apart: T=-0.01,0 and T=0,-0.01); two
    # entries of one time crashed the level pairs with a traceback
    merged: dict[int, tuple[float, float]] = {}
    for t_ns, south, north in out:
        s0, n0 = merged.get(t_ns, (0.0, 0.0))
        merged[t_ns] = (s0 + south, n0 + north)
    return [(t_ns, s, n) for t_ns, (s, n) in sorted(merged.items())]


def _mm(x: list[float]) -> str:
    return f"{1e3 * x[0]:+.3f} / {1e3 * x[1]:+.3f}"


def _levels_lines(levels: dict | None) -> list[str]:
    """Describe the levels of a day of records (kN, mm)."""
    if not levels:
        return []
    import datetime as dt

    def hhmm(ns: int) -> str:
        from zoneinfo import ZoneInfo

        return dt.datetime.fromtimestamp(ns / 1e9, ZoneInfo("Europe/Berlin")).strftime("%H:%M")

    lines = [
        "",
        f"levels of the {len(levels['records'])} records (car-free levels, test car left out; "
        "times local, Europe/Berlin; elsewhere UTC, marked Z):",
    ]
    for p in levels["pairs"]:
        imp = p["imposed_m"]
        what = f"imposed {_mm(imp)} mm" if imp is not None else "no step given"
        lines.append(
            f"  {p['name']}: dR = {p['dR_n'][0] / 1e3:+.2f} +- {p['dR_sd_n'][0] / 1e3:.2f} / "
            f"{p['dR_n'][1] / 1e3:+.2f} +- {p['dR_sd_n'][1] / 1e3:.2f} kN over "
            f"{p['seconds_between'] / 3600.0:.1f} h; {what}"
        )
        if p.get("sun"):
            mean_k, sd_k = p["sun"]["sun_change_k"]
            lines.append(
                f"    the sun between them: the deck's vertical difference {mean_k:+.2f} +- "
                f"{1.96 * sd_k:.2f} K (its mean taken out of dR, its spread in the +-)"
            )
    for note in levels["not_measured"]:
        lines.append(f"  {note}")
    imp = levels.get("imposed")
    if imp:
        from bridge_shadow.gap.si import param_text
        from bridge_shadow.model.parameters import PARAMETERS

        lines.append(f"  the imposed steps explained by ({imp['validation']}):")
        for r in imp["explanations"]:
            # each in the text's units (kN/mm; a stiffness in SI and bare read as anything)
            params = ", ".join(
                param_text(f"{k} [{PARAMETERS[k].unit}]", v) if k in PARAMETERS else f"{k} {v:.3g}"
                for k, v in r["parameters"].items()
            )
            params = params or "as given"
            lines.append(
                f"    {r['effect']:<21} P {r['probability']:.2f}  "
                f"dlogZ {r['delta_log_evidence']:7.2f}  {params}"
            )
        if any("slab_joint_opening" in r["parameters"] for r in imp["explanations"]):
            lines.append(
                "    (slab_joint_opening: the share of the slab joints' stiffness kept over the central "
                "support, 1 = closed as built)"
            )
    for st in levels["steps_between_records"]:
        mark = "step" if st["significant"] else "no significant step"
        lines.append(
            f"  between records at {hhmm(st['at_ns'])}: {_mm(st['x_m'])} mm "
            f"(+-{1.96e3 * st['sigma_m'][0]:.2f} / {1.96e3 * st['sigma_m'][1]:.2f}): {mark}"
        )
    return lines


def _human(summary: dict) -> str:
    # here, not at the top: the gap package imports scipy.stats, which `--help` must not wait for
    from bridge_shadow.gap.si import params_text

    lines = [f"best: {summary['best']}"]
    if summary["indistinguishable_from"]:
        lines[0] += f"  (cannot be told apart from: {', '.join(summary['indistinguishable_from'])})"
    if (summary.get("best_effect") or {}).get("fits_imposed_steps") is False:
        lines[0] += "  (but it does not fit the imposed steps: check their sign, size and time)"
    lines.append(summary["statement"])
    named = ([summary["best_effect"]] if summary.get("best_effect") else []) + summary["also_present"]
    if named:
        lines += [
            "",
            "named effects (fitted values in mm, kN, K, h; the JSON's in SI; group = what the reactions "
            "cannot tell apart):",
        ]
        for e in named:
            lines.append(f"  {e['effect']:<21} {params_text(e['params'])}")
            for g in e["group"][1:]:
                lines.append(f"    or {g['effect']:<18} {params_text(g['params'])}")
            soft = e.get("size_if_model_softer")
            if soft:
                k = soft["with_support_springs_n_per_m"]
                per_day = 86400.0 if soft["unit"] == "m/s" else 1.0
                xs, xn = (1e3 * per_day * v for v in soft["value"])
                unit = "mm" if soft["unit"] == "m" else "mm/day"
                lines.append(
                    f"    its size depends on A: with support springs of {1e-6 * k:.3g} kN/mm (the soft end "
                    f"of their plausible range) the same reactions mean {xs:+.3f} / {xn:+.3f} {unit}"
                )
    lines += _levels_lines(summary.get("levels"))
    if summary["rejected_implausible"]:
        lines += ["", "rejected as implausible (the data would take them only outside the plausible range):"]
        for r in summary["rejected_implausible"]:
            given = f" given {', '.join(r['given'])}" if r.get("given") else ""
            lines.append(f"  {r['effect']}{given}: {r['reason']}")
    lines += ["", "rank  effect                held-out RMS reduction S/N/total   fit"]
    for c in summary["candidates"]:
        r = c["heldout_reduction"]
        mark = "*" if c["significant"] else " "
        note = "" if c["plausible"] else "  [implausible]"
        lines.append(
            f"{c['rank']:>4}{mark} {c['effect']:<21} {100 * r['south']:6.1f}% {100 * r['north']:6.1f}% "
            f"{100 * r['total']:6.1f}%   {params_text(c['params'])}{note}"
        )
    lines.append("  (* significant: beats the chance level of AR(1) noise with a plausible fit)")
    lines.append(
        "  (fit: each effect alone; [implausible]: alone it needs a value outside its plausible range."
        " A named effect is fitted with the ones named before it, where its value is plausible)"
    )
    w = summary["where"]
    lines.append("")
    lines.append(
        f"residual RMS: south {w['rms_n']['south'] / 1e3:.3f} kN, north {w['rms_n']['north'] / 1e3:.3f} kN; "
        f"share south {100 * w['channel_share']['south']:.0f}%"
    )
    imposed = summary["baseline"]["imposed"]
    if imposed:
        steps = ", ".join(f"{_mm(s['settlement_m'])} mm" for s in imposed)
        lines.append(f"imposed settlement in the baseline: {steps}")
    post = summary["posterior"]
    if post.get("computed"):
        b, a = post["before"], post["after"]
        lines += ["", "posterior settlements [mm], south / north, positive upward (95 % half-width):"]
        rows = [("before", b), ("after", a), *(("or", alt) for alt in post.get("alternatives", {}).values())]
        for label, p in rows:
            half = f"+-{1.96e3 * p['sigma_m'][0]:.3f} / {1.96e3 * p['sigma_m'][1]:.3f}"
            lines.append(f"  {label:<7} {_mm(p['mean_m'])}  ({half})  {p['what']}")
        if post.get("alternatives") == {}:
            lines.append(
                "  (--alternatives: none to run; the data tell the named effects from every other "
                "model-form effect)"
            )
        lines += _event_lines(b, a)
    return "\n".join(lines)


def _event_lines(before: dict[str, Any], after: dict[str, Any]) -> list[str]:
    """Say the settlement events of the runs before and after when the change moved them."""
    times = [[e["time"] for e in p.get("events", [])] for p in (before, after)]
    if times[0] == times[1]:
        return []
    out = []
    for label, p in (("before", before), ("after", after)):
        found = ", ".join(f"{e['time']} {_mm(e['size_m'])} mm ({e['kind']})" for e in p.get("events", []))
        out.append(f"  events {label}: {found or 'none'}")
    return out


def _diagnose(
    args: argparse.Namespace,
    data: Any,
    surrogate: Any,
    config: Any,
    imposed: list[tuple[int, float, float]],
    imposed_sd: float,
    mapper: Any,
) -> Any:
    """Run the diagnosis the command asks for (``mapper``: the folds on Dask, or None)."""
    from bridge_shadow.gap.diagnose import diagnose

    return diagnose(
        data,
        surrogate,
        width_s=args.window,
        holdout_days=args.holdout_days,
        imposed=imposed,
        imposed_sd_m=imposed_sd,
        shadow=True,
        shadow_config=config,
        alternatives=args.alternatives,
        surrogate_path=config.surrogate_path or None,
        mapper=mapper,
        baseline_change=args.baseline_change,
    )


def run(args: argparse.Namespace) -> int:
    """Read the bag, diagnose, print, and write the report."""
    import math
    import sys

    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.commands.output import emit_json, require_finite
    from bridge_shadow.engine import check_engine_options, optional_mapper
    from bridge_shadow.errors import InputError
    from bridge_shadow.estimate.parameters.specs import SPECS, check_value
    from bridge_shadow.fileio import check_output_dir
    from bridge_shadow.gap.posterior import IMPOSED_AVERAGE, shadow_config
    from bridge_shadow.gap.records import IMPOSED_SD_M
    from bridge_shadow.model.surrogate_file import load_surrogate, save_surrogate, surrogate_target

    check_value("--window", args.window, "float", SPECS["window_s"])  # the shadow's window_s range
    imposed_sd = IMPOSED_SD_M if args.imposed_sd is None else args.imposed_sd
    if not (imposed_sd > 0 and math.isfinite(imposed_sd)):
        raise InputError("--imposed-sd must be a positive, finite number of metres (jacks are never exact)")
    check_engine_options(args.scheduler, args.workers)  # before the work
    if args.report:
        check_output_dir(args.report, "--report directory")  # before the work
    if args.out_surrogate:
        surrogate_target(args.out_surrogate, create=False, force=args.force)
    config = shadow_config(args.params, args.surrogate)
    surrogate = load_surrogate(config.surrogate_path or None)
    data = read_monitoring(args.bag, topics=config.input_topics())
    if not any(len(s) for s in data.forces.values()):
        frc_01, frc_02, _ = config.input_topics()
        raise InputError(f"{args.bag}: no load cell message on {frc_01} or {frc_02}: nothing to diagnose")
    first = min(int(s.stamp_ns.min()) for s in data.forces.values() if len(s))
    last = max(int(s.stamp_ns.max()) for s in data.forces.values() if len(s))
    imposed = parse_imposed(args.imposed, first, last)
    with optional_mapper(args.scheduler, args.workers) as mapper:
        dg = _diagnose(args, data, surrogate, config, imposed, imposed_sd, mapper)
    summary = dict(dg.summary)
    post = summary.get("posterior", {})
    if post.get("computed"):  # the shadow's answers before and after: never printed as NaN
        require_finite(
            {f"posterior.{k}.{q}": post[k][q] for k in ("before", "after") for q in ("mean_m", "sigma_m")},
            "posterior",
        )
    summary["bag"] = str(args.bag)
    summary["surrogate_file"] = config.surrogate_path or "config/surrogate.yaml"
    off_record: list[str] = []
    if args.out_surrogate:
        after = dg.surrogate_after if dg.surrogate_after is not None else surrogate
        named = summary.get("posterior", {}).get("after", {})
        average = "the imposed steps' explanations averaged by probability (none named)"
        carried = [average if e == IMPOSED_AVERAGE else e for e in named.get("effects_in_surrogate", [])]
        if named.get("model_change_from_levels"):  # a day of records: the model its levels were read with
            carried.append("the model the records' levels were read with (provenance gap_model_change)")
        off_record = named.get("effects_off_the_record", [])
        header = (
            f"Written by `bridge-shadow gap {args.bag} --out-surrogate`: the model in use\n"
            f"({summary['surrogate_file']}) with what changes the model: "
            f"{', '.join(carried) or 'none'}.\n"
            + (
                f"Not in it: {', '.join(off_record)}, loads `after` took off the record (a surrogate\n"
                "cannot carry them): `replay` with this file does not take them off.\n"
                if off_record
                else ""
            )
            + "Units: A N/m, u0 N, thermal N/K; model_uncertainty covariance of [A, u0, thermal]."
        )
        written = save_surrogate(after, args.out_surrogate, header=header, force=args.force)
        summary["surrogate_written"] = str(written)
    if args.report:
        from bridge_shadow.gap.report import write_report

        summary["report"] = str(write_report(dg, args.report, str(args.bag)))
    if args.json:
        emit_json(summary)
    else:
        print(_human(summary))
        if args.report:
            print(f"report: {summary['report']}")
        if args.out_surrogate:
            print(f"wrote {summary['surrogate_written']}", file=sys.stderr)
    for line in summary.get("warnings", []):  # however the output goes (gap.summary.gap_warnings)
        print(f"bridge-shadow gap: WARN: {line}", file=sys.stderr)
    if off_record:  # replay with the file would not reproduce `after`: say so however the output goes
        print(
            f"bridge-shadow gap: WARN: {summary['surrogate_written']} does not carry "
            f"{', '.join(off_record)}: loads `after` took off the record, which a surrogate cannot "
            "carry; `replay --surrogate` with it differs from `after` by them",
            file=sys.stderr,
        )
    return 0
