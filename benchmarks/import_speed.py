"""``import-csv``'s table reader on the real records: the uniform reader against the row-by-row loop.

``parse_source`` reads a logger's uniform table in whole columns (``_uniform_rows``) and leaves
any other table to its row-by-row loop. Both are timed here on the same tables, in this process:
the loop (the uniform reader taken away) is the baseline, and the two results are checked equal.
Then the whole import (``import_csv``: zips, the date fix, time zones, merging) of each record.
The records are read from ``../shared/data/munich-bridge-data`` (``BRIDGE_SHADOW_DATA``). Usage::

    .venv/bin/python benchmarks/import_speed.py [--repeat R]
"""

from __future__ import annotations

import argparse
from datetime import date
from unittest import mock

import numpy as np
from _common import best_of

from bridge_shadow.importers import import_csv, munich_csv
from bridge_shadow.importers.sources import find_sources
from bridge_shadow.paths import shared_data_dir

#: (label, files of ``import_csv``, ``--date``)
RECORDS = (
    ("2022-03-07 reference, 100 Hz", ["ReferenceState/ReferenceStateForceAt100Hz.csv.zip"], "2022-03-07"),
    (
        "2022-04-11 the pair, 100 Hz",
        [
            "Settlements/UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
            "Settlements/UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
        ],
        None,
    ),
    ("2022-04-11 air, 1 Hz", ["Settlements/TemperatureData2022-04-11.zip"], None),
)


def _loop(source: munich_csv.CsvSource) -> munich_csv.Parsed:
    with mock.patch.object(munich_csv, "_uniform_rows", lambda *args: None):
        return munich_csv.parse_source(source)


def _same(a: munich_csv.Parsed, b: munich_csv.Parsed) -> bool:
    arrays = all(
        np.array_equal(getattr(a, n), getattr(b, n), equal_nan=True) for n in ("local_ns", "values", "ok")
    )
    return arrays and (a.written_dates, a.rejected) == (b.written_dates, b.rejected)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--repeat", type=int, default=3, help="best of R runs of each (default 3)")
    opts = ap.parse_args()
    root = shared_data_dir()
    print(f"{'record':32s} {'rows':>8s} {'loop (baseline)':>16s} {'uniform':>9s} {'ratio':>7s}  import_csv")
    for label, names, hint in RECORDS:
        files = [root / n for n in names]
        sources = list(find_sources(files))
        rows = sum(len(s.text.splitlines()) - 1 for s in sources)
        t_loop, slow = best_of(opts.repeat, lambda s=sources: [_loop(x) for x in s])
        t_fast, fast = best_of(opts.repeat, lambda s=sources: [munich_csv.parse_source(x) for x in s])
        if not all(_same(a, b) for a, b in zip(fast, slow, strict=True)):
            raise SystemExit(f"{label}: the uniform reader and the loop disagree")
        day = date.fromisoformat(hint) if hint else None
        t_all, _ = best_of(opts.repeat, lambda f=files, d=day: import_csv(f, date_hint=d))
        print(
            f"{label:32s} {rows:8d} {t_loop * 1e3:13.0f} ms {t_fast * 1e3:6.0f} ms {t_loop / t_fast:6.1f}x"
            f"  {t_all * 1e3:.0f} ms"
        )


if __name__ == "__main__":
    main()
