"""munich-bridge-data CSV records -> ``MonitoringData`` (SI units, UTC stamps), with a report.

Quirks handled (see ``../shared/data/munich-bridge-data/README.md``): cp1252 headers; force
stamps ``YYYY-MM-DD hh:mm:ss.fff`` whose month and day are swapped in some files (2022-04-11 reads
``2022-11-04``); temperature stamps ``DD.MM.YYYY hh:mm:ss.fff`` (day first); CRLF and trailing
commas; sample-and-hold repeats (kept, counted); several files per channel (merged, sorted, exact
duplicate stamps dropped); local time Europe/Berlin -> UTC; kN -> N.
"""

from __future__ import annotations

import itertools
import re
from collections import Counter
from dataclasses import dataclass, field
from datetime import date, datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS, FORCE_FRAMES, TEMPERATURE_FRAME
from bridge_shadow.errors import InputError
from bridge_shadow.importers.localtime import local_to_utc_ns
from bridge_shadow.importers.sources import CsvSource, find_sources
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

__all__ = ["ImportReport", "import_csv", "parse_source"]

_FORCE_TIME = re.compile(r"^(\d{4})-(\d{2})-(\d{2})[ T](\d{2}:\d{2}:\d{2}(?:\.\d{1,9})?)$")
_TEMP_TIME = re.compile(r"^(\d{2})\.(\d{2})\.(\d{4}) (\d{2}:\d{2}:\d{2}(?:\.\d{1,9})?)$")
_NAME_DATE = re.compile(r"(20\d{2})-(\d{2})-(\d{2})")
_KN_TO_N = 1000.0
_MAX_EXAMPLES = 20
TEMPERATURE = "air_temperature"


@dataclass
class Parsed:
    """One parsed CSV table.

    Attributes:
        source: where it came from.
        local_ns: (n,) int64 naive local stamps (ns since 1970-01-01 local).
        values: (n, k) float64 readings as written (kN or C); NaN/inf cells are kept as read.
        ok: (n, k) bool, False where a cell did not parse (that whole row is rejected).
        columns: channel name of each value column.
        written_dates: distinct calendar dates as written in the file.
        rejected: (line number, reason) of each rejected row or cell.

    """

    source: CsvSource
    local_ns: np.ndarray
    values: np.ndarray
    ok: np.ndarray
    columns: list[str]
    written_dates: list[date]
    rejected: list[tuple[int, str]] = field(default_factory=list)


@dataclass
class ImportReport:
    """What an import did; ``as_dict()`` is the ``--json`` summary (SI units, ISO UTC times)."""

    inputs: list[dict[str, Any]] = field(default_factory=list)
    rows: dict[str, int] = field(default_factory=dict)
    span: dict[str, dict[str, str | None]] = field(default_factory=dict)
    repeats: dict[str, int] = field(default_factory=dict)
    duplicates_dropped: dict[str, int] = field(default_factory=dict)
    non_finite: dict[str, int] = field(default_factory=dict)
    rejected: list[dict[str, Any]] = field(default_factory=list)
    date_fixes: list[dict[str, str]] = field(default_factory=list)
    utc_offsets_s: list[float] = field(default_factory=list)
    dst_ambiguous: int = 0

    def as_dict(self) -> dict[str, Any]:
        """Return the JSON-ready summary."""
        reasons = Counter(r["reason"] for r in self.rejected)
        return {
            "inputs": self.inputs,
            "rows": self.rows,
            "time_span": self.span,
            "repeats": self.repeats,
            "duplicates_dropped": self.duplicates_dropped,
            "non_finite": self.non_finite,
            "rejected": {
                "count": len(self.rejected),
                "by_reason": dict(reasons),
                "examples": self.rejected[:_MAX_EXAMPLES],
            },
            "date_fix": self.date_fixes,
            "utc_offsets_s": self.utc_offsets_s,
            "dst_ambiguous_samples": self.dst_ambiguous,
        }


def _iso(ns: int) -> str:
    stamp = datetime.fromtimestamp(ns // 1_000_000_000, tz=timezone.utc)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S") + f".{(ns % 1_000_000_000) // 1_000_000:03d}Z"


def _lines(text: str) -> list[str]:
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _to_float(col: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Parse a column of numbers; returns values and a mask of cells that did not parse."""
    try:
        return np.array(col, dtype=np.float64), np.zeros(len(col), dtype=bool)
    except ValueError:
        out = np.full(len(col), np.nan)
        bad = np.zeros(len(col), dtype=bool)
        for i, cell in enumerate(col):
            try:
                out[i] = float(cell)
            except ValueError:
                bad[i] = True
        return out, bad


#: Where a stamp of each kind has its digits and which characters stand between them (positions of
#: ``_FORCE_TIME`` and ``_TEMP_TIME`` without the fraction: ``YYYY-MM-DD hh:mm:ss``, ``DD.MM.YYYY
#: hh:mm:ss``), and the positions of year, month and day; a fraction follows at 19 as ``.`` and 1-9
#: digits.
_STAMP_LAYOUT: dict[str, tuple[dict[int, str], tuple[slice, slice, slice]]] = {
    "force": ({4: "-", 7: "-", 10: " T", 13: ":", 16: ":"}, (slice(0, 4), slice(5, 7), slice(8, 10))),
    "temperature": ({2: ".", 5: ".", 10: " ", 13: ":", 16: ":"}, (slice(6, 10), slice(3, 5), slice(0, 2))),
}


def _uniform_stamps(stamps: list[str], kind: str) -> np.ndarray | None:
    """Return the ISO form (``YYYY-MM-DDThh:mm:ss[.f]``) of stamps of one width, or None.

    None unless every stamp has the same length and the layout of its kind (``_STAMP_LAYOUT``) with
    ASCII digits: then each also matches ``_FORCE_TIME`` / ``_TEMP_TIME`` and the row-by-row loop
    would read it as the result says.
    """
    text = np.array(stamps)  # str: a "<U{width}" array
    width = text.dtype.itemsize // 4
    if not 19 <= width <= 29 or width == 20:
        return None
    code = text.view(np.uint32).reshape(len(stamps), width)
    if not bool(np.all(code[:, -1])):  # a shorter stamp, padded with NUL
        return None
    separators, (year, month, day) = _STAMP_LAYOUT[kind]
    if width > 19:
        separators = {**separators, 19: "."}
    digit = np.ones(width, dtype=bool)
    digit[list(separators)] = False
    cols = code[:, digit]
    if not bool(np.all((cols >= ord("0")) & (cols <= ord("9")))):
        return None
    for at, allowed in separators.items():
        if not bool(np.isin(code[:, at], [ord(c) for c in allowed]).all()):
            return None
    iso = np.empty_like(code)
    iso[:, 0:4], iso[:, 5:7], iso[:, 8:10] = code[:, year], code[:, month], code[:, day]
    iso[:, [4, 7]], iso[:, 10] = ord("-"), ord("T")
    iso[:, 11:] = code[:, 11:]
    return iso.view(text.dtype).reshape(-1)


def _uniform_rows(
    lines: list[str], kind: str, ncols: int
) -> tuple[list[int], np.ndarray, list[list[str]], set[tuple[int, int, int]]] | None:
    """Read the data rows of a uniform table at once; None if any row is otherwise.

    Uniform: every non-blank line has ``ncols`` fields (no trailing comma) and a stamp that
    ``_uniform_stamps`` reads; what a logger writes. Returns what the row-by-row loop of
    ``parse_source`` would (line numbers, ISO stamps, the cells of each value column, the written
    dates), in a few passes over whole columns instead of a split and a regular expression per
    line (a 100 Hz record of 12 minutes is 72,000 rows). Any other table is left to the loop,
    which says what is wrong with its rows.
    """
    body = lines[1:]
    used = list(map(str.strip, body))  # blank lines are skipped, as the loop skips them
    rows = list(itertools.compress(body, used))
    if not rows or set(map(str.count, rows, itertools.repeat(","))) != {ncols - 1}:
        return None
    fields = ",".join(rows).split(",")
    iso = _uniform_stamps(fields[0::ncols], kind)
    if iso is None:
        return None
    line_no = list(itertools.compress(range(2, len(body) + 2), used))
    written = {(int(d[0:4]), int(d[5:7]), int(d[8:10])) for d in np.unique(iso.astype("U10")).tolist()}
    return line_no, iso, [fields[j::ncols] for j in range(1, ncols)], written


def parse_source(source: CsvSource) -> Parsed:
    """Parse one table into naive local stamps and raw readings (no date fix, no units yet)."""
    lines = _lines(source.text)
    ncols = 3 if source.kind == "force" else 2
    columns = list(CHANNELS) if source.kind == "force" else [TEMPERATURE]
    uniform = _uniform_rows(lines, source.kind, ncols)
    if uniform is not None:
        return _parsed(source, *uniform, columns, [])
    pattern = _FORCE_TIME if source.kind == "force" else _TEMP_TIME
    rejected: list[tuple[int, str]] = []
    line_no: list[int] = []
    iso: list[str] = []
    cells: list[list[str]] = []
    dates: set[tuple[int, int, int]] = set()
    for no, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) == ncols + 1 and parts[-1].strip() == "":
            parts.pop()  # trailing comma
        if len(parts) != ncols:
            rejected.append((no, f"expected {ncols} fields, found {len(parts)}"))
            continue
        m = pattern.match(parts[0].strip())
        if m is None:
            rejected.append((no, "unreadable time stamp"))
            continue
        if source.kind == "force":
            y, mo, d, clock = int(m[1]), int(m[2]), int(m[3]), m[4]
        else:
            d, mo, y, clock = int(m[1]), int(m[2]), int(m[3]), m[4]
        dates.add((y, mo, d))
        iso.append(f"{y:04d}-{mo:02d}-{d:02d}T{clock}")
        line_no.append(no)
        cells.append(parts[1:])
    value_cells = [[c[j] for c in cells] for j in range(len(columns))]
    return _parsed(source, line_no, iso, value_cells, dates, columns, rejected)


def _parsed(
    source: CsvSource,
    line_no: list[int],
    iso: list[str] | np.ndarray,
    value_cells: list[list[str]],
    dates: set[tuple[int, int, int]],
    columns: list[str],
    rejected: list[tuple[int, str]],
) -> Parsed:
    """Return the ``Parsed`` table of the rows read: stamps and values parsed, bad cells rejected."""
    try:
        local = np.array(iso, dtype="datetime64[ns]").astype(np.int64)
    except ValueError:  # an impossible calendar date or clock time somewhere: find it
        local = np.empty(len(iso), dtype=np.int64)
        keep = np.ones(len(iso), dtype=bool)
        for i, text in enumerate(iso):
            try:
                local[i] = np.datetime64(text, "ns").astype(np.int64)
            except ValueError:
                keep[i] = False
                rejected.append((line_no[i], "impossible date or time"))
        local = local[keep]
        value_cells = [[c for c, k in zip(col, keep.tolist(), strict=True) if k] for col in value_cells]
        line_no = [n for n, k in zip(line_no, keep.tolist(), strict=True) if k]
    values = np.empty((len(line_no), len(columns)), dtype=np.float64)
    ok = np.ones(values.shape, dtype=bool)
    for j, name in enumerate(columns):
        col, bad = _to_float(value_cells[j])
        for i in np.flatnonzero(bad).tolist():
            rejected.append((line_no[i], f"unreadable value of {name}"))
        ok[:, j] = ~bad
        values[:, j] = col
    written = sorted(date(*t) for t in dates if _valid_date(*t))
    rejected.sort()
    return Parsed(source, local, values, ok, columns, written, rejected)


def _check_some_rows_read(parsed: Parsed, kept: int) -> None:
    """Refuse a table whose data rows were all rejected: a record must not vanish into a count.

    (A file with a bad row here and there is imported, its rejects listed; one of which no row could
    be read is a file that cannot be what its header says, and the bag without it would be a stream
    missing a record: the settlement it holds lost with exit 0.)
    """
    if kept or not parsed.rejected:
        return
    line, reason = parsed.rejected[0]
    raise InputError(
        f"{parsed.source.label}: none of its {len({n for n, _ in parsed.rejected})} data rows could be read "
        f"(line {line}: {reason}); nothing was written"
    )


def _valid_date(y: int, m: int, d: int) -> bool:
    try:
        date(y, m, d)
    except ValueError:
        return False
    return True


def _swapped(d: date) -> date | None:
    try:
        return date(d.year, d.day, d.month)
    except ValueError:
        return None


def _name_dates(source: CsvSource) -> set[date]:
    out = set()
    for part in (source.file, source.member):
        for y, m, d in _NAME_DATE.findall(Path(part).name if part else ""):
            if _valid_date(int(y), int(m), int(d)):
                out.add(date(int(y), int(m), int(d)))
    return out


#: What ``import_csv`` does with force stamps whose month and day could be swapped and no
#: evidence settles which: ``refuse`` (an InputError asking for ``--date``), or ``as_written``
#: (for a record whose calendar date does not matter to the caller, e.g. a reference level).
AMBIGUOUS_DATES = ("refuse", "as_written")


def _swap_evidence(
    written: list[date],
    source: CsvSource,
    explicit: date | None,
    temp_dates: set[date],
    today: date,
    ambiguous: str = "refuse",
) -> str | None:
    """Say why the force stamps of a file have month and day swapped, or None if they have not.

    The decision is for the whole file (a record crossing midnight keeps one convention). Dates
    whose day is above 12 (or equals the month) cannot be swapped. Otherwise the evidence, in
    order: ``--date``; the date in the file name or of the temperature files (day-first,
    unambiguous) matching one reading but not the other; the file's own date or today's, before
    which one reading lies and the other does not. When nothing settles it, ``ambiguous`` says
    what to do: ``refuse`` raises InputError with the hint ``--date``, ``as_written`` keeps it.
    """
    swaps = [_swapped(d) for d in written]
    if explicit is not None:
        if explicit in written:
            return None
        if explicit in swaps:
            return "--date"
        shown = ", ".join(str(d) for d in written)
        raise InputError(f"{source.label}: stamps read {shown}, which is not --date {explicit} nor its swap")
    if not written or any(d is None for d in swaps) or swaps == written:
        return None
    for what, known in (
        ("date in the file name", _name_dates(source)),
        ("date of the temperature files", temp_dates),
    ):
        if any(d in known for d in swaps) and not any(d in known for d in written):
            return what
        if any(d in known for d in written) and not any(d in known for d in swaps):
            return None  # the evidence confirms the stamps as written
    latest, latest_swapped = max(written), max(d for d in swaps if d is not None)
    limits = (
        (f"recording after the file was written ({source.modified})", source.modified),
        ("date in the future", today),
    )
    for what, limit in limits:
        if limit is None:
            continue
        if latest > limit >= latest_swapped:
            return what
        if latest_swapped > limit >= latest:
            return None  # the swapped reading is the impossible one
    if ambiguous == "as_written":
        return None
    shown = ", ".join(str(d) for d in written)
    other = ", ".join(str(d) for d in swaps if d is not None)
    raise InputError(
        f"{source.label}: the stamps read {shown}, which could also be {other} with month and day "
        "swapped (as in some munich-bridge-data exports), and neither the file name, the temperature "
        f"files nor the file dates settle it; give the recording date: --date {written[0]} or --date "
        f"{swaps[0]}"
    )


def _repeats(values: np.ndarray) -> int:
    """Count samples equal to the one before (sample-and-hold); NaN never counts."""
    return int(np.count_nonzero(values[1:] == values[:-1])) if len(values) > 1 else 0


def _merge(stamps: list[np.ndarray], values: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, int]:
    """Concatenate, sort by stamp (stable), drop exact duplicate stamps; return the drop count."""
    s = np.concatenate(stamps) if stamps else np.empty(0, np.int64)
    v = np.concatenate(values) if values else np.empty(0)
    order = np.argsort(s, kind="stable")
    s, v = s[order], v[order]
    keep = np.ones(len(s), dtype=bool)
    keep[1:] = s[1:] != s[:-1]
    return s[keep], v[keep], int(len(s) - np.count_nonzero(keep))


def import_csv(
    files: list[str | Path],
    *,
    date_hint: date | None = None,
    tz: str = "Europe/Berlin",
    today: date | None = None,
    ambiguous: str = "refuse",
) -> tuple[MonitoringData, ImportReport]:
    """Convert munich-bridge-data CSV files (or zips of them) to the contract topics.

    Args:
        files: force and/or temperature CSVs, or zips holding them (recognized by header).
        date_hint: the true recording date of the force files (``--date``); fixes a swapped
            month/day. Without it, a swap is detected from the file name, the temperature files'
            day-first dates, the file date or a future date.
        tz: time zone of the stamps.
        today: the present date for the future-date check (default: today, UTC).
        ambiguous: a force file whose month and day could be swapped and nothing settles it:
            ``refuse`` (InputError, hint ``--date``) or ``as_written`` (``AMBIGUOUS_DATES``).

    Returns:
        The monitoring data (N, C, UTC ns; ``log_ns`` = stamp) and the report.

    Raises:
        InputError: unreadable input, unknown header, date contradicting ``date_hint``, an
            ambiguous date (``ambiguous="refuse"``), no rows.

    """
    today = today or datetime.now(timezone.utc).date()
    report = ImportReport()
    parsed = [parse_source(s) for s in find_sources(files)]
    temp_dates = {d for p in parsed if p.source.kind == "temperature" for d in p.written_dates}
    stamps: dict[str, list[np.ndarray]] = {name: [] for name in (*CHANNELS, TEMPERATURE)}
    values: dict[str, list[np.ndarray]] = {name: [] for name in (*CHANNELS, TEMPERATURE)}
    offsets: set[int] = set()
    for p in parsed:
        if not len(p.local_ns) and not p.rejected and len(parsed) > 1:  # alone: "no data rows" below
            raise InputError(f"{p.source.label}: a header and no data rows; nothing was written")
        local = p.local_ns.copy()
        used_dates = list(p.written_dates)
        if p.source.kind == "force":
            evidence = _swap_evidence(p.written_dates, p.source, date_hint, temp_dates, today, ambiguous)
            if evidence is not None:
                used_dates = []
                for written in p.written_dates:
                    true = _swapped(written)
                    assert true is not None
                    day_ns = np.datetime64(written, "D").astype("datetime64[ns]").astype(np.int64)
                    on_day = (p.local_ns >= day_ns) & (p.local_ns < day_ns + 86_400 * 10**9)
                    shift = (np.datetime64(true, "D") - np.datetime64(written, "D")).astype("timedelta64[ns]")
                    local[on_day] += shift.astype(np.int64)
                    used_dates.append(true)
                    report.date_fixes.append(
                        {
                            "file": p.source.label,
                            "written": str(written),
                            "used": str(true),
                            "evidence": evidence,
                        }
                    )
        utc, offset_s, odd = local_to_utc_ns(local, tz)
        offsets.update(np.unique(offset_s).tolist())
        report.dst_ambiguous += odd
        scale = _KN_TO_N if p.source.kind == "force" else 1.0
        # a row with any unreadable cell is rejected whole: its other cells carry the same
        # doubtful stamp, and a kept half-row would displace a good sample at that stamp
        ok = p.ok.all(axis=1)
        kept = int(np.count_nonzero(ok))
        _check_some_rows_read(p, kept)
        for j, name in enumerate(p.columns):
            stamps[name].append(utc[ok])
            values[name].append(p.values[ok, j] * scale)
        report.rejected += [{"file": p.source.label, "line": n, "reason": r} for n, r in p.rejected]
        report.inputs.append(
            {
                "file": p.source.file,
                "member": p.source.member,
                "kind": p.source.kind,
                "rows": len(p.local_ns),
                "rows_read": kept,
                "rows_rejected": len({line for line, _ in p.rejected}),
                "dates": [str(d) for d in sorted(set(used_dates))],
            }
        )
    series: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name in (*CHANNELS, TEMPERATURE):
        s, v, dropped = _merge(stamps[name], values[name])
        series[name] = (s, v)
        report.rows[name] = len(s)
        report.repeats[name] = _repeats(v)
        report.non_finite[name] = int(np.count_nonzero(~np.isfinite(v)))
        report.duplicates_dropped[name] = dropped
        report.span[name] = {
            "start": _iso(int(s[0])) if len(s) else None,
            "end": _iso(int(s[-1])) if len(s) else None,
        }
    first = [int(s[0]) for s, _ in series.values() if len(s)]
    last = [int(s[-1]) for s, _ in series.values() if len(s)]
    report.span["all"] = {
        "start": _iso(min(first)) if first else None,
        "end": _iso(max(last)) if last else None,
    }
    if not any(report.rows.values()):
        raise InputError("no data rows in " + ", ".join(str(f) for f in files))
    report.utc_offsets_s = sorted(float(o) for o in offsets)
    forces = {ch: ForceSeries(*series[ch], FORCE_FRAMES[ch]) for ch in CHANNELS}
    temp = TemperatureSeries(
        *series[TEMPERATURE], frame_id=np.full(len(series[TEMPERATURE][0]), TEMPERATURE_FRAME)
    )
    return MonitoringData(forces, temp), report
