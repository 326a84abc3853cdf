"""Stamps for people: ISO 8601 in UTC, the one form every text output uses for a time.

Machine output keeps integer nanoseconds since the epoch (``time_ns``); a person reads
``2022-03-14T05:53Z``, never a window index (``window 27453953`` is ``k * window_s`` seconds since
1970 and says nothing without a calculator).
"""

from __future__ import annotations

import datetime as dt

__all__ = ["iso_utc"]

_FORMATS = {"minutes": "%Y-%m-%dT%H:%MZ", "seconds": "%Y-%m-%dT%H:%M:%SZ"}


def iso_utc(stamp_ns: int, precision: str = "minutes") -> str:
    """Return ``stamp_ns`` (ns since the epoch, UTC) as ISO 8601 UTC, e.g. ``2022-03-14T05:53Z``.

    ``precision`` is ``minutes`` (the window grid of the shadow, 60 s) or ``seconds``; the time is
    truncated, not rounded, so a window that starts at 05:53:00 reads 05:53.

    >>> iso_utc(1_647_237_180_000_000_000)
    '2022-03-14T05:53Z'
    >>> iso_utc(1_647_237_187_500_000_000, "seconds")
    '2022-03-14T05:53:07Z'
    """
    seconds, _ = divmod(int(stamp_ns), 1_000_000_000)
    return dt.datetime.fromtimestamp(seconds, dt.timezone.utc).strftime(_FORMATS[precision])
