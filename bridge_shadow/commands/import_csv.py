"""``bridge-shadow import-csv``: munich-bridge-data CSV records -> a monitoring bag."""

from __future__ import annotations

import argparse
import sys
from datetime import date

HELP = "convert munich-bridge-data force/temperature CSVs (or zips of them) into a monitoring bag"
DESCRIPTION = """\
Convert the munich-bridge-data CSV format into a rosbag2 bag with the contract input topics
(/bridge/frc_01/force, /bridge/frc_02/force: WrenchStamped in N; /bridge/air_temperature:
Temperature in C). Each FILE is a force or temperature CSV, or a zip holding some, recognized by
its header, or a folder: its CSV and zip files (not its subfolders). Local time (Europe/Berlin)
becomes UTC; kN becomes N; several temperature files are merged; sample-and-hold repeats are kept
and counted; a swapped month/day in force stamps (2022-04-11 written as 2022-11-04) is detected
from the file name, the temperature files' dates, the file date or a future date, or fixed with
--date.

examples:
  bridge-shadow import-csv ../shared/data/munich-bridge-data/Settlements/*.zip --out /tmp/apr11
  bridge-shadow import-csv ../shared/data/munich-bridge-data/Settlements --out /tmp/apr11
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
    out = write_monitoring(args.out, data, args.storage, overwrite=args.force, compress=args.compress)
    summary = {"out": str(out), "storage": args.storage, **report.as_dict()}
    warnings = []
    if not any(len(data.forces[ch]) for ch in data.forces):  # said nowhere before: a replay found nothing
        warnings.append(
            "no force record among the inputs: the bag holds the air temperature only, and the shadow "
            "reads the load cells (import their CSVs with it)"
        )
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
    sys.stdout.write("\n".join(lines) + "\n")
    return 0
