"""Every bridge's posterior over time: a table (CSV) and a plot, from the window outputs as they pass.

``PeriodicRows`` keeps one row per ``period_s`` of stamp time (the last window output of each
period) and the final posterior, so its size is the archive's length over the period (a year at
the default hour: 8,760 rows per bridge), never the number of windows. Columns (SI):

``bridge, time_utc, end_ns, window, mean_south_m, mean_north_m, sigma_south_m, sigma_north_m,
correlation, updates, events``

``updates`` and ``events`` count the windows used and the events started up to that row.
"""

from __future__ import annotations

import bisect
import csv
import datetime as dt
import io
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["COLUMNS", "DEFAULT_PERIOD_S", "PeriodicRows", "plot_summary", "write_csv"]

#: The summary table's period: one row an hour (a year: 8,760 rows per bridge).
DEFAULT_PERIOD_S = 3600.0
COLUMNS = (
    "bridge",
    "time_utc",
    "end_ns",
    "window",
    "mean_south_m",
    "mean_north_m",
    "sigma_south_m",
    "sigma_north_m",
    "correlation",
    "updates",
    "events",
)


def _utc(ns: int) -> str:
    return dt.datetime.fromtimestamp(ns / 1e9, dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def _row(
    bridge: str, index: int, end_ns: int, mean: np.ndarray, cov: np.ndarray, updates: int, events: int
) -> dict[str, Any]:
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    rho = float(cov[0, 1] / (sd[0] * sd[1])) if sd[0] > 0 and sd[1] > 0 else float("nan")
    return {
        "bridge": bridge,
        "time_utc": _utc(end_ns),
        "end_ns": int(end_ns),
        "window": int(index),
        "mean_south_m": float(mean[0]),
        "mean_north_m": float(mean[1]),
        "sigma_south_m": float(sd[0]),
        "sigma_north_m": float(sd[1]),
        "correlation": rho,
        "updates": int(updates),
        "events": int(events),
    }


class PeriodicRows:
    """The last window output of each period of one bridge, as summary rows."""

    def __init__(self, bridge: str, period_s: float = DEFAULT_PERIOD_S) -> None:
        self.bridge = bridge
        self.period_ns = max(round(period_s * 1e9), 1)
        self.rows: list[dict[str, Any]] = []
        self._last: Any = None
        self._counts = (0, 0)  # windows used and events started up to ``_last``

    def add(self, outputs: Iterable[Any]) -> None:
        """Offer window outputs in order."""
        for out in outputs:
            last = self._last
            if last is not None and out.end_ns // self.period_ns != last.end_ns // self.period_ns:
                self.rows.append(self._row(last, last.mean_m, last.covariance_m2))
            self._counts = (self._counts[0] + bool(out.updated), self._counts[1] + bool(out.event))
            self._last = out

    def _row(self, out: Any, mean: np.ndarray, cov: np.ndarray) -> dict[str, Any]:
        return _row(self.bridge, out.index, out.end_ns, mean, cov, *self._counts)

    def finish(self, shadow: Any) -> list[dict[str, Any]]:
        """Return the rows, the last with the shadow's final posterior (after its end-of-record refit).

        ``events`` counts the shadow's events (``event_records``) that began up to each row: a
        window output marks only a step the detector found in the data, and a change confirmed
        across a gap (every event of a load-test day) marks none, so the column read 0 throughout.
        """
        if self._last is not None:
            mean, cov = shadow.posterior
            self.rows.append(self._row(self._last, mean, cov))
        starts = sorted(int(e.time_ns) for e in shadow.event_records())
        for row in self.rows:
            row["events"] = bisect.bisect_right(starts, row["end_ns"])
        return self.rows


def write_csv(path: Path, rows: list[dict[str, Any]]) -> Path:
    """Write the summary table atomically (``COLUMNS``; floats in full precision)."""
    from bridge_shadow.fileio import atomic_write_text

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()} for r in rows)
    return atomic_write_text(path, buf.getvalue(), "archive summary table")


def plot_summary(path: Path, rows: list[dict[str, Any]]) -> Path:
    """Plot every bridge's posterior settlements over time (mm, 95 % band), one panel per support."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bridge_shadow.fileio import atomic_write

    bridges = list(dict.fromkeys(r["bridge"] for r in rows))
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for name in bridges:
        mine = [r for r in rows if r["bridge"] == name]
        t = np.array([np.datetime64(r["end_ns"], "ns") for r in mine])
        for ax, side in zip(axes, ("south", "north"), strict=True):
            m = 1e3 * np.array([r[f"mean_{side}_m"] for r in mine])
            s = 1e3 * 1.96 * np.array([r[f"sigma_{side}_m"] for r in mine])
            # each row's posterior holds until the next row: steps, not ramps across the hours
            # between a load-test day's records (a line drew every step as a slide)
            (line,) = ax.plot(t, m, lw=1.0, label=name, drawstyle="steps-post")
            ax.fill_between(t, m - s, m + s, color=line.get_color(), alpha=0.2, lw=0, step="post")
    for ax, side in zip(axes, ("south (FRC-01)", "north (FRC-02)"), strict=True):
        ax.set_ylabel(f"settlement {side}, mm")
        ax.grid(alpha=0.3)
    axes[0].set_title("posterior settlement over time (positive upward; band: 95 %)")
    axes[1].set_xlabel("time (UTC)")
    if len(bridges) <= 12:
        axes[0].legend(loc="best", fontsize=8)
    fig.autofmt_xdate()
    fig.tight_layout()
    with atomic_write(path, "archive summary plot") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path
