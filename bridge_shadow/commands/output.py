"""Printing helpers shared by the subcommands: one JSON object on stdout, progress on stderr."""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import numpy as np

from bridge_shadow.jsonvalues import jsonable

__all__ = ["emit_json", "progress", "require_finite"]


def require_finite(values: dict[str, Any], what: str = "result") -> None:
    """Raise ResultError (one line) when any of the named numbers is NaN or infinite.

    ``values`` maps a name (``posterior.mean_m``) to a number or array-like of numbers (None, as
    JSON writes a non-finite float, counts as non-finite). A command checks its result with this
    before printing it, so a NaN posterior is never printed with exit 0.
    """
    from bridge_shadow.errors import ResultError

    for name, value in values.items():
        flat = np.asarray(jsonable(value), dtype=object).ravel()
        arr = np.array([np.nan if v is None else float(v) for v in flat])
        if not np.all(np.isfinite(arr)):
            shown = np.array2string(arr, precision=4)
            raise ResultError(f"the {what} is not finite ({name} = {shown}); nothing is reported as a result")


def emit_json(obj: dict[str, Any]) -> None:
    """Print exactly one JSON object on stdout."""
    sys.stdout.write(json.dumps(jsonable(obj), indent=2, sort_keys=False) + "\n")
    sys.stdout.flush()


#: Off a terminal (a log, a CI job, a service's journal) a long job says how far it is at most
#: this often [s]: ``calibrate`` with a day's pairs runs 5-6 minutes, and said nothing until done.
PLAIN_EVERY_S = 30.0
#: label -> (first call, last line) in monotonic seconds, and the fraction last seen
_plain: dict[str, tuple[float, float, float]] = {}


def progress(fraction: float, label: str = "", width: int = 30) -> None:
    """Draw a one-line progress bar on stderr when it is a terminal, else a plain line now and then.

    Off a terminal: ``label: N % (T s)`` once ``PLAIN_EVERY_S`` have passed since the job's first
    call or its last line, nothing for a job done sooner (nothing in a short run's captured stderr).
    """
    if not sys.stderr.isatty():
        _plain_line(fraction, label)
        return
    fraction = min(max(fraction, 0.0), 1.0)
    filled = round(width * fraction)
    end = "\n" if fraction >= 1.0 else ""
    sys.stderr.write(f"\r{label} [{'#' * filled}{'.' * (width - filled)}] {100 * fraction:5.1f}%{end}")
    sys.stderr.flush()


def _plain_line(fraction: float, label: str) -> None:
    now = time.monotonic()
    first, last, seen = _plain.setdefault(label, (now, now, fraction))
    if fraction < seen:  # the job began again (one that never reported its end ran before)
        first, last = now, now
    _plain[label] = (first, last, fraction)
    if fraction >= 1.0:
        _plain.pop(label, None)
        if last > first:  # it said how far it was: say it is done
            sys.stderr.write(f"{label}: done ({now - first:.0f} s)\n")
            sys.stderr.flush()
        return
    if now - last >= PLAIN_EVERY_S:
        sys.stderr.write(f"{label}: {100 * min(max(fraction, 0.0), 1.0):.0f} % ({now - first:.0f} s)\n")
        sys.stderr.flush()
        _plain[label] = (first, now, fraction)
