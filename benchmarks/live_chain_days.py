"""A load-test day's records as bags of their own, through the node: the live chain and the live merge.

Four bags of one day, each a record imported with the day's whole temperature file (as
``import-csv RECORD.zip TemperatureData2022-04-11.zip`` makes it): the reference record, the 10 mm
record, and the 10 mm record moved 230 and 480 minutes on and lowered 10 and 20 mm more through
the calibrated ``A`` (``test_later_records_cli._later_record``). The reference is the direct
replay of the four bags merged by log time; then, each against it:

- the offline chain: one ``replay BAG --checkpoint CK`` per bag;
- the live chain: one ``replay BAG --live --checkpoint CK`` per bag (``ros.live_chain``);
- the live merge: ``replay BAG BAG BAG BAG --live``.

Printed per step: exit code, posterior mean (mm), forces rejected ``late``, events, the checkpoint's
held air, seconds; and the largest relative difference of the final mean and covariance from the
reference. The real records are read from ``BRIDGE_SHADOW_DATA`` (default ``../shared/...``).

Run: ``.venv/bin/python benchmarks/live_chain_days.py [--work DIR] [--skip-live]``
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import io
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "test"))
from test_later_records_cli import LATER, LOWERED, REF, TEMPERATURE, _later_record

from bridge_shadow.cli import main
from bridge_shadow.paths import shared_data_dir
from bridge_shadow.ros.netenv import confine_to_loopback


def _run(*args: object, cmd: str = "replay") -> tuple[int, dict[str, Any]]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main([cmd, *map(str, args), "--json"])
    out = buf.getvalue()
    return rc, (json.loads(out) if out.strip() else {})


def _bags(work: Path) -> list[Path]:
    data = shared_data_dir() / "Settlements"
    bags = [work / name for name in ("ref", "ten", "later230", "later480")]
    if all(b.exists() for b in bags):
        return bags
    _run(data / REF, data / TEMPERATURE, "--out", bags[0], "--force", cmd="import-csv")
    _run(data / LOWERED, data / TEMPERATURE, "--out", bags[1], "--force", cmd="import-csv")
    for bag, minutes, step in ((bags[2], 230, -0.01), (bags[3], 480, -0.02)):
        zipped = work / f"{bag.name}_{LATER}"
        _later_record(data / LOWERED, zipped, dt.timedelta(minutes=minutes), np.array([step, step]))
        _run(zipped, data / TEMPERATURE, "--out", bag, "--force", cmd="import-csv")
    return bags


def _line(label: str, rc: int, js: dict[str, Any], seconds: float) -> str:
    if not js:
        return f"  {label:<24} exit {rc}, no result"
    mean = 1e3 * np.asarray(js["posterior"]["mean_m"])
    events = ",".join(e["kind"] for e in js["events"]) or "none"
    held = js["windows"].get("at_end", {}).get("held_air", "-")
    late = js["rejected"].get("late", 0)
    return (
        f"  {label:<24} exit {rc}  {mean[0]:+8.3f} / {mean[1]:+8.3f} mm  late {late:>6}  "
        f"events {events:<14} held air {held:>6}  {seconds:5.1f} s"
    )


def _against(js: dict[str, Any], ref: dict[str, Any]) -> str:
    if not js:
        return "  no result to compare"
    rel = []
    for key in ("mean_m", "covariance_m2"):
        a, b = np.asarray(js["posterior"][key]), np.asarray(ref["posterior"][key])
        rel.append(float(np.max(np.abs(a - b) / np.abs(b))))
    return f"  against the direct merged replay: mean {rel[0]:.1e}, covariance {rel[1]:.1e} (relative)"


def main_(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work", type=Path, help="folder for the four bags (kept; default: a temporary one)")
    parser.add_argument("--skip-live", action="store_true", help="the offline chain only (no DDS)")
    args = parser.parse_args(argv)
    confine_to_loopback(new_domain=True)  # DDS on loopback, a domain of this run
    with tempfile.TemporaryDirectory(prefix="live_chain_days_") as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        bags = _bags(work)
        t = time.perf_counter()
        rc, ref = _run(*bags)
        print("direct replay of the four bags merged by log time:")
        print(_line("merged", rc, ref, time.perf_counter() - t))
        modes = [("offline chain", [])] + ([] if args.skip_live else [("live chain", ["--live"])])
        for label, extra in modes:
            print(f"{label}, one replay --checkpoint per bag:")
            ck = work / f"{label.replace(' ', '_')}.npz"
            ck.unlink(missing_ok=True)
            js: dict[str, Any] = {}
            for bag in bags:
                t = time.perf_counter()
                rc, js = _run(bag, *extra, "--checkpoint", ck)
                print(_line(bag.name, rc, js, time.perf_counter() - t))
            print(_against(js, ref))
        if not args.skip_live:
            print("live merge, replay BAG BAG BAG BAG --live:")
            t = time.perf_counter()
            rc, js = _run(*bags, "--live")
            print(_line("merged live", rc, js, time.perf_counter() - t))
            print(_against(js, ref))
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
