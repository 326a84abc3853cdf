"""``bridge-shadow import-csv``: munich-bridge-data CSV records -> a monitoring bag."""

from __future__ import annotations

import argparse
import sys
from datetime import date
from typing import Any

HELP = "convert munich-bridge-data force/temperature CSVs (or zips of them) into a monitoring bag"
DESCRIPTION = """\
Convert the munich-bridge-data CSV format into a rosbag2 bag with the contract input topics
(/bridge/frc_01/force, /bridge/frc_02/force: WrenchStamped in N; /bridge/air_temperature:
Temperature in C). Each FILE is a force or temperature CSV, or a zip holding some, recognized by
its header, or a folder: its CSV and zip files (not its subfolders); a relative FILE not found
here is read from the shared data folder (../shared/data/munich-bridge-data beside the checkout,
or $BRIDGE_SHADOW_DATA). Local time (Europe/Berlin) becomes UTC; kN becomes N; several
temperature files are merged; sample-and-hold repeats are kept and counted; a swapped month/day
in force stamps (2022-04-11 written as 2022-11-04) is detected from the file name, the
temperature files' dates, the file date or a future date, or fixed with --date.

examples:
  bridge-shadow import-csv ../shared/data/munich-bridge-data/Settlements/*.zip --out /tmp/apr11
  bridge-shadow import-csv ../shared/data/munich-bridge-data/Settlements --out /tmp/apr11
  bridge-shadow import-csv Settlements --out /tmp/apr11    # the same, from the shared data folder
"""


def _date(text: str) -> date:
    try:
        return date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a date YYYY-MM-DD: {text!r}") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the arguments."""
    parser.add_argument(
        "files", nargs="+", metavar="FILE", help="force/temperature CSV or zip, or a folder of them"
    )
    parser.add_argument("--out", required=True, metavar="BAG", help="output bag directory")
    parser.add_argument("--storage", choices=("sqlite3", "mcap"), default="sqlite3", help="bag storage")
    parser.add_argument(
        "--date",
        type=_date,
        default=None,
        metavar="YYYY-MM-DD",
        help="true recording date of the force files",
    )
    parser.add_argument(
        "--force", "--overwrite", dest="force", action="store_true", help="replace an existing bag at --out"
    )
    parser.add_argument("--compress", action="store_true", help="zstd-compressed chunks (mcap storage only)")
    parser.add_argument("--json", action="store_true", help="print one JSON summary object")
    parser.add_argument(
        "--air-near-forces",
        action="store_true",
        help="write only the air temperature within 10 minutes of a force sample (a bag that a later "
        "record's bag will follow into a running node fed by a player of its own; replay --checkpoint, "
        "replay --live --checkpoint and archive do not need it; calibrate and gap read the day's whole "
        "air for its warming, so keep the default for them)",
    )


#: The air temperature may run this far past the last force stamp before the import warns, s.
AIR_BEYOND_S = 600.0


def _air_near_forces(data: Any) -> tuple[Any, int]:
    """Keep the air readings within ``AIR_BEYOND_S`` of a force sample; return the data and how many went."""
    import numpy as np

    from bridge_shadow.series import MonitoringData, TemperatureSeries
    from bridge_shadow.windowing import sorted_union

    forces = [f.stamp_ns for f in data.forces.values() if len(f)]
    t = data.temperature
    if not forces or not len(t):
        return data, 0
    both = sorted_union(forces)
    at = np.searchsorted(both, t.stamp_ns)
    before = both[np.clip(at - 1, 0, len(both) - 1)]
    after = both[np.clip(at, 0, len(both) - 1)]
    near = np.minimum(np.abs(t.stamp_ns - before), np.abs(after - t.stamp_ns))
    keep = near <= round(AIR_BEYOND_S * 1e9)
    fields = (t.stamp_ns, t.temp_c, t.variance, t.frame_id, t.log_ns)
    air = TemperatureSeries(*(f[keep] for f in fields))
    return MonitoringData(data.forces, air), int(np.count_nonzero(~keep))


def _air_beyond_forces(data: Any) -> list[str]:
    """Say when the bag's air temperature runs past its last force by more than ``AIR_BEYOND_S``.

    The shadow's data clock follows every topic, the air's too: feeding this bag closes the
    windows up to the air's last reading. ``replay --checkpoint`` (and ``--live`` with it: the
    player holds that air back, ``ros.live_chain``) holds the air past the last force in its
    checkpoint for the next bag, and ``archive`` and ``replay BAG BAG`` read overlapping bags
    merged, so none of them loses a later record's forces; a running node fed one bag after the
    other by a player of its own cannot hold it, and rejects the forces of a later record before
    the air's end as ``late`` (found with a withheld 13:39 record imported on its own after the
    public records, each bag with the day's whole temperature file).
    """
    from bridge_shadow.timefmt import iso_utc

    forces = [s.stamp_ns for s in data.forces.values() if len(s)]
    air = data.temperature.stamp_ns
    if not forces or not len(air):
        return []
    last_force = max(int(s.max()) for s in forces)
    last_air = int(air.max())
    beyond_s = (last_air - last_force) / 1e9
    if beyond_s <= AIR_BEYOND_S:
        return []
    return [
        f"the air temperature runs {beyond_s / 3600.0:.1f} h past the last force record (to "
        f"{iso_utc(last_air)}, the forces to {iso_utc(last_force)}): replay --checkpoint (live or "
        "not) and archive keep it for a bag of later records, but a running node fed such a bag after "
        "this one by a player of its own rejects its forces before that time as late; for that, import "
        "the records of a day together into one bag, or with --air-near-forces"
    ]


def run(args: argparse.Namespace) -> int:
    """Import, write the bag, print the summary."""
    from bridge_shadow.bagio import check_bag_target, write_monitoring
    from bridge_shadow.commands.output import emit_json
    from bridge_shadow.errors import InputError
    from bridge_shadow.importers import import_csv

    if args.compress and args.storage != "mcap":
        raise InputError("--compress needs --storage mcap")
    check_bag_target(args.out, args.force)  # before reading the records
    data, report = import_csv(args.files, date_hint=args.date)
    air_dropped = 0
    if args.air_near_forces:
        data, air_dropped = _air_near_forces(data)
    out = write_monitoring(args.out, data, args.storage, overwrite=args.force, compress=args.compress)
    summary = {"out": str(out), "storage": args.storage, **report.as_dict(), "air_dropped": air_dropped}
    warnings = []
    if not any(len(data.forces[ch]) for ch in data.forces):  # said nowhere before: a replay found nothing
        warnings.append(
            "no force record among the inputs: the bag holds the air temperature only, and the shadow "
            "reads the load cells (import their CSVs with it)"
        )
    warnings.extend(_air_beyond_forces(data))
    summary["warnings"] = warnings
    for line in warnings:
        print(f"bridge-shadow import-csv: WARN: {line}", file=sys.stderr)
    if args.json:
        emit_json(summary)
        return 0
    lines = [f"wrote {out} ({args.storage})"]
    for name, rows in report.rows.items():
        span = report.span[name]
        lines.append(
            f"  {name:16s} {rows:8d} rows  {span['start'] or '-'} .. {span['end'] or '-'}"
            f"  repeats {report.repeats[name]}  duplicates dropped {report.duplicates_dropped[name]}"
            f"  non-finite {report.non_finite[name]}"
        )
    for fix in report.date_fixes:
        lines.append(f"  date fixed {fix['written']} -> {fix['used']} ({fix['evidence']}): {fix['file']}")
    rejected = summary["rejected"]
    lines.append(f"  rejected rows: {rejected['count']} {rejected['by_reason'] or ''}".rstrip())
    for source in report.inputs:
        if source["rows_rejected"]:
            total = source["rows_read"] + source["rows_rejected"]
            name = source["file"] + (f"!{source['member']}" if source["member"] else "")
            lines.append(f"    {source['rows_rejected']} of {total} rows in {name}")
    lines.append(f"  UTC offsets (h): {[o / 3600.0 for o in report.utc_offsets_s]}")
    if air_dropped:
        lines.append(
            f"  air temperature: {air_dropped} readings more than {AIR_BEYOND_S / 60:g} min from a force "
            "sample not written (--air-near-forces)"
        )
    sys.stdout.write("\n".join(lines) + "\n")
    return 0
