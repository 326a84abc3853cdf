"""PNG plots of a replay (matplotlib Agg): compensation, raw vs compensated, posterior, ellipse.

Human-facing, so forces are in kN and settlements in mm.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS, SUPPORTS
from bridge_shadow.fileio import atomic_write, output_dir
from bridge_shadow.timefmt import iso_utc

__all__ = ["broken_at_gaps", "write_plots"]


def broken_at_gaps(end_ns: np.ndarray, gap_ns: int, *series: np.ndarray) -> list[np.ndarray]:
    """Return ``series`` (rows per window), a NaN row where the windows' ends jump by more than ``gap_ns``.

    A line drawn through the hours between two records read as the settlement sliding from one
    state to the next, where the shadow reports a step; the NaN row breaks it there. The first
    array returned is ``end_ns`` itself (float, NaN at the breaks).
    """
    end = np.asarray(end_ns)
    at = np.flatnonzero(np.diff(end) > gap_ns) + 1
    out = [np.insert(end.astype(float), at, np.nan)]
    for y in series:
        y = np.asarray(y, float)
        out.append(np.insert(y, at, np.full(y.shape[1:], np.nan), axis=0))
    return out


def write_plots(directory: str | Path, result: Any, shadow: Any) -> list[Path]:
    """Write the four PNGs of a ``ReplayResult`` into ``directory``; return their paths.

    All four are drawn before the first is written: Ctrl-C while drawing (seconds for a long
    record) leaves the folder as it was, not two of four new plots beside two old ones.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = output_dir(directory, "plot directory")
    h = result.history()
    t0 = int(h["end_ns"][0]) if len(h["end_ns"]) else 0
    since = f"time (h since {iso_utc(t0)})" if len(h["end_ns"]) else "time (h)"
    end, force, comp, mean_m, cov = broken_at_gaps(
        h["end_ns"],
        round(shadow.config.gap_s * 1e9),
        h["force_n"],
        h["compensated_n"],
        h["mean_m"],
        h["covariance_m2"],
    )
    t_h = (end - t0) / 3.6e12
    drawn: list[tuple[Path, bytes]] = []

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for c, ax in enumerate(axes):
        ok = np.isfinite(h["temp_c"][:, c]) & np.isfinite(h["force_n"][:, c])
        ax.plot(h["temp_c"][ok, c], 1e-3 * h["force_n"][ok, c], ".", ms=3, alpha=0.5, label="60 s means")
        fit = shadow.fit
        if fit is not None and ok.any():
            grid = np.linspace(h["temp_c"][ok, c].min(), h["temp_c"][ok, c].max(), 200)
            g = shadow.compensation.curve(fit, np.column_stack([grid, grid]))[:, c]
            level = np.nanmean(h["compensated_n"][ok, c])  # the curve is centred: y - g(T) has mean ybar
            ax.plot(grid, 1e-3 * (g + level), "r-", label=f"g(T) + mean level, edf {fit.edf[c]:.1f}")
        ax.set(xlabel="air temperature (°C)", ylabel="reaction (kN)", title=f"{CHANNELS[c]} ({SUPPORTS[c]})")
        if not ok.any():
            used = np.isfinite(h["force_n"][:, c]).any()
            _note(ax, "no air temperature: windows used uncompensated" if used else "no window used")
        ax.legend()
    drawn.append((out / "compensation_curve.png", _png(fig)))

    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    for c, ax in enumerate(axes):
        ax.plot(t_h, 1e-3 * force[:, c], "-", lw=0.8, label="raw")
        ax.plot(t_h, 1e-3 * comp[:, c], "-", lw=0.8, label="compensated")
        ax.set(ylabel=f"{SUPPORTS[c]} (kN)")
        if not len(t_h):
            _note(ax, "no window closed")
        ax.legend()
    axes[-1].set(xlabel=since)
    drawn.append((out / "raw_vs_compensated.png", _png(fig)))

    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    sd = np.sqrt(np.stack([cov[:, 0, 0], cov[:, 1, 1]], axis=1))
    for c, ax in enumerate(axes):
        mu = 1e3 * mean_m[:, c]
        ax.fill_between(t_h, mu - 2e3 * sd[:, c], mu + 2e3 * sd[:, c], alpha=0.3, label="±2σ")
        ax.plot(t_h, mu, "-", label="posterior mean")
        ax.set(ylabel=f"{SUPPORTS[c]} settlement (mm)")
        if not len(t_h):
            _note(ax, "no window closed: the prior")
        ax.legend()
    axes[-1].set(xlabel=since)
    drawn.append((out / "posterior.png", _png(fig)))

    fig, ax = plt.subplots(figsize=(5.5, 5))
    mean, cov = 1e3 * result.mean_m, 1e6 * result.covariance_m2
    prior = 1e3 * np.asarray(shadow.prior_sigma_m)
    theta = np.linspace(0, 2 * np.pi, 200)
    circle = np.stack([np.cos(theta), np.sin(theta)])
    k95 = np.sqrt(5.991)  # chi2(2) 95%
    vals, vecs = np.linalg.eigh(cov)
    ell = mean[:, None] + k95 * vecs @ (np.sqrt(np.clip(vals, 0, None))[:, None] * circle)
    ax.plot(k95 * prior[0] * circle[0], k95 * prior[1] * circle[1], "k--", lw=0.8, label="prior 95%")
    ax.plot(ell[0], ell[1], "r-", label="posterior 95%")
    ax.plot(*mean, "r+")
    ax.set(xlabel="south settlement (mm)", ylabel="north settlement (mm)", title="credible region")
    ax.axis("equal")
    ax.legend()
    drawn.append((out / "credible_ellipse.png", _png(fig)))
    for path, png in drawn:
        with atomic_write(path, "plot") as tmp:
            Path(tmp).write_bytes(png)
    return [path for path, _ in drawn]


def _note(ax: Any, text: str) -> None:
    """Say in the middle of an empty plot why it is empty."""
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.35")


def _png(fig: Any) -> bytes:
    """Return the figure as PNG bytes (and close it)."""
    import io

    import matplotlib.pyplot as plt

    fig.tight_layout()
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, dpi=110, format="png")
    finally:
        plt.close(fig)
    return buffer.getvalue()
