"""Stamps for people: ISO 8601 in UTC (the one format every output of the project uses)."""

from __future__ import annotations

import datetime as dt

__all__ = ["iso_utc"]

_NS = 1_000_000_000


def iso_utc(stamp_ns: int) -> str:
    """``2022-04-11T06:36:00Z`` for a stamp in ns since the epoch (whole seconds, UTC)."""
    return dt.datetime.fromtimestamp(int(stamp_ns) // _NS, dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
