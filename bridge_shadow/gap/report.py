"""Markdown report with PNG plots of a gap diagnosis (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.contract import SUPPORTS
from bridge_shadow.fileio import atomic_write, atomic_write_text, output_dir
from bridge_shadow.gap.diagnose import Diagnosis
from bridge_shadow.gap.si import params_text
from bridge_shadow.gap.windows import NS

__all__ = ["write_report"]


def _hours(dg: Diagnosis) -> np.ndarray:
    return (dg.windows.t_ns - dg.windows.t_ns[0]) / NS / 3600.0


def _plot_residual(dg: Diagnosis, plt: Any, path: Path) -> None:
    h = _hours(dg)
    fig, axes = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    best = dg.cv.get(dg.best)
    for c, ax in enumerate(axes):
        ax.plot(h, dg.resid[:, c] / 1e3, lw=0.6, color="0.3", label="residual (60 s means)")
        if best is not None:
            ax.plot(h, best.pred_full[:, c] / 1e3, lw=1.2, color="C3", label=f"fitted {dg.best}")
        if dg.joint_fit is not None:
            ax.plot(h, dg.joint_fit[:, c] / 1e3, lw=0.8, color="C0", label="with the effects also present")
        ax.set_ylabel(f"{SUPPORTS[c]} [kN]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("hours since start")
    fig.suptitle("Measured minus baseline model")
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def _plot_breakdown(summary: dict[str, Any], plt: Any, path: Path) -> None:
    where = summary["where"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    hours = where["time_of_day"]["hour_utc"]
    for sup in SUPPORTS:
        vals = np.array(where["time_of_day"]["mean_n"][sup], dtype=float) / 1e3
        ax1.plot(hours, vals, marker="o", ms=3, label=sup)
    ax1.set_xlabel("hour of day (UTC)")
    ax1.set_ylabel("mean residual [kN]")
    ax1.set_title("Time-of-day profile")
    ax1.grid(alpha=0.3)
    ax1.legend(fontsize=8)
    bands = list(where["bands"])
    x = np.arange(len(bands))
    for k, sup in enumerate(SUPPORTS):
        ax2.bar(x + 0.4 * k - 0.2, [where["bands"][b][sup] for b in bands], width=0.4, label=sup)
    ax2.set_xticks(x, bands, fontsize=8)
    ax2.set_ylabel("share of residual power")
    ax2.set_title("Frequency bands")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def _plot_heldout(dg: Diagnosis, plt: Any, path: Path) -> None:
    h = _hours(dg)
    # the best effect's held-out fit; on a day of records a level effect has none (the records'
    # levels are read pair by pair): the top candidate inside the records then
    name = dg.best if dg.best in dg.cv else dg.summary["candidates"][0]["effect"]
    pred = dg.cv[name].pred_cv
    fig, axes = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    for c, ax in enumerate(axes):
        ax.plot(h, dg.resid[:, c] / 1e3, lw=0.6, color="0.5", label="before (baseline)")
        ax.plot(h, (dg.resid[:, c] - pred[:, c]) / 1e3, lw=0.6, color="C0", label=f"after adding {name}")
        ax.set_ylabel(f"{SUPPORTS[c]} [kN]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("hours since start (each day predicted by a fit on the other days)")
    fig.suptitle("Held-out residual before and after")
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def _pct(x: float | None) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:.0f}%"


def _markdown(summary: dict[str, Any], source: str) -> str:
    w = summary["where"]
    post = summary["posterior"]
    lines = [
        "# Sim-to-real gap diagnosis",
        "",
        f"Record: `{source}`; {summary['windows']['count']} windows of {summary['windows']['width_s']:g} s; "
        f"validation: {summary['validation']['kind']} ({summary['validation']['folds']} folds); "
        f"AR(1) phi of the noise = {summary['noise']['ar1_phi']:.2f} "
        f"(effective sample size {summary['noise']['n_eff']:.0f}).",
        "",
        f"**Best: `{summary['best']}`.** {summary['statement']}",
        "",
        "## Where",
        "",
        "| | south | north |",
        "|---|---|---|",
        f"| residual RMS [kN] | {w['rms_n']['south'] / 1e3:.3f} | {w['rms_n']['north'] / 1e3:.3f} |",
        f"| mean residual [kN] | {w['mean_n']['south'] / 1e3:.3f} | {w['mean_n']['north'] / 1e3:.3f} |",
        f"| share of the gap | {_pct(w['channel_share']['south'])} | {_pct(w['channel_share']['north'])} |",
        f"| share in the time-of-day profile | {_pct(w['time_of_day']['share']['south'])} | "
        f"{_pct(w['time_of_day']['share']['north'])} |",
    ]
    for key, label in (("warming_rms_n", "warming"), ("cooling_rms_n", "cooling")):
        v = w["warming_cooling"][key]
        lines.append(f"| RMS while {label} [kN] | {v['south'] / 1e3:.3f} | {v['north'] / 1e3:.3f} |")
    for cls in ("sunny", "overcast", "night"):
        v = w["sun"][f"{cls}_rms_n"]
        lines.append(f"| RMS {cls} [kN] | {v['south'] / 1e3:.3f} | {v['north'] / 1e3:.3f} |")
    for band, v in w["bands"].items():
        lines.append(f"| power share, {band} band | {_pct(v['south'])} | {_pct(v['north'])} |")
    parts = w["model_part"]["heldout_gain_by_part"]
    lines += [
        "",
        "Held-out gain by model part: " + ", ".join(f"{k} {_pct(v)}" for k, v in parts.items()) + ".",
        "",
        "![residual](residual.png)",
        "",
        "![breakdown](breakdown.png)",
        "",
        "## Which effect",
        "",
        "| rank | effect | part | held-out RMS reduction S / N / total | partial gain (given) | BIC (AR1) "
        "| fitted |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in summary["candidates"]:
        red = c["heldout_reduction"]
        par = c["partial_effect"]
        fitted = params_text(c["params"])  # in mm, kN, K and h, as the CLI's text (the JSON's SI)
        lines.append(
            f"| {c['rank']} | {c['effect']} | {c['part']} | {_pct(red['south'])} / {_pct(red['north'])} / "
            f"{_pct(red['total'])} | {_pct(par['heldout_gain'])} ({par['given']}) | "
            f"{c['information_criterion']['bic_ar1']:.1f} | {fitted} |"
        )
    also = summary.get("also_present", [])
    if also:
        lines += ["", "Also present (forward selection, each given the ones before):", ""]
        for a in also:
            group = (
                f"; cannot be told apart from {', '.join(a['indistinguishable_from'])}"
                if a["indistinguishable_from"]
                else ""
            )
            if "cumulative_heldout_reduction" not in a:  # named by the levels of a day of records
                lines.append(f"- `{a['effect']}` ({a['part']}): {a.get('evidence', '')}{group}")
                continue
            red = a["cumulative_heldout_reduction"]
            lines.append(
                f"- `{a['effect']}` ({a['part']}): removes {_pct(a['partial_heldout_gain'])} of the "
                f"remaining held-out squared residual; cumulative held-out RMS reduction {_pct(red['total'])}"
                f"{group}"
            )
    rejected = summary.get("rejected_implausible", [])
    if rejected:
        lines += ["", "Rejected as implausible (the data would take them only outside their range):", ""]
        for r in rejected:
            given = f" (given {', '.join(r['given'])})" if r.get("given") else ""
            lines.append(f"- `{r['effect']}`{given}: {r['reason']}")
    lines += _levels_markdown(summary.get("levels"))
    lines += ["", "## How far it shrinks", "", "![held-out](heldout.png)", ""]
    if post.get("computed"):
        lines += [
            "Posterior settlements of the shadow [mm], south / north, positive upward:",
            "",
            "| | south | north | what |",
            "|---|---|---|---|",
        ]
        rows = [("before", post["before"]), ("after", post["after"])]
        rows += [(f"or ({k})", v) for k, v in post.get("alternatives", {}).items()]
        for label, v in rows:
            m = np.array(v["mean_m"]) * 1e3
            sd = np.array(v["sigma_m"]) * 1e3
            south = f"{m[0]:+.3f} +- {1.96 * sd[0]:.3f}"
            north = f"{m[1]:+.3f} +- {1.96 * sd[1]:.3f}"
            lines.append(f"| {label} | {south} | {north} | {v['what']} |")
    else:
        lines.append("The shadow's posteriors were not computed (`diagnose(..., shadow=True)` does).")
    lines.append("")
    return "\n".join(lines)


def _levels_markdown(levels: dict[str, Any] | None) -> list[str]:
    """Describe the levels of a day of records: pairs, the imposed steps' explanations, free steps."""
    if not levels:
        return []
    lines = [
        "",
        "## Levels of the records",
        "",
        f"A day of {len(levels['records'])} records: the level change across every gap (car-free levels, "
        "test car left out), kN, south / north:",
        "",
        "| pair | dR south | dR north | hours | imposed [mm] |",
        "|---|---|---|---|---|",
    ]
    for p in levels["pairs"]:
        imp = p["imposed_m"]
        imposed = "none (the shadow estimates it)"
        if imp is not None:
            imposed = f"{1e3 * imp[0]:+.1f} / {1e3 * imp[1]:+.1f}"
        lines.append(
            f"| {p['name']} | {p['dR_n'][0] / 1e3:+.2f} +- {p['dR_sd_n'][0] / 1e3:.2f} | "
            f"{p['dR_n'][1] / 1e3:+.2f} +- {p['dR_sd_n'][1] / 1e3:.2f} | "
            f"{p['seconds_between'] / 3600.0:.1f} | {imposed} |"
        )
    imp = levels.get("imposed")
    if imp:
        lines += ["", f"The imposed steps explained by ({imp['validation']}):", ""]
        lines += ["| effect | probability | delta log evidence | parameters |", "|---|---|---|---|"]
        for r in imp["explanations"]:
            params = ", ".join(f"{k} = {v:.3g}" for k, v in r["parameters"].items()) or "as imposed"
            lines.append(
                f"| {r['effect']} | {r['probability']:.2f} | {r['delta_log_evidence']:.2f} | {params} |"
            )
        lines += ["", imp["rule"] + "."]
        sets = imp.get("prior_sets") or {}
        best = sets.get(imp["best"]) if imp.get("named") else None
        if best:
            weights = ", ".join(
                f"{k} left out" if "left_out" in v else f"{k} {v['weight']:.2f}" for k, v in best.items()
            )
            head = f"The model after averages {imp['best']} over the prior sets ({weights})"
            lines += ["", f"{head}: {sets['rule']}."]
    steps = levels.get("steps_between_records") or []
    if steps:
        lines += ["", "Steps between records (the model after the imposed analysis), mm, 95 %:", ""]
        for st in steps:
            x, sd = np.array(st["x_m"]) * 1e3, 1.96e3 * np.array(st["sigma_m"])
            lines.append(
                f"- {x[0]:+.2f} +- {sd[0]:.2f} / {x[1]:+.2f} +- {sd[1]:.2f}"
                + ("" if st["significant"] else " (not significant)")
            )
    return lines


def write_report(dg: Diagnosis, out_dir: str | Path, source: str = "") -> Path:
    """Write ``report.md`` and its PNG plots into ``out_dir``; return the Markdown path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = output_dir(out_dir, "report directory")
    _plot_residual(dg, plt, out / "residual.png")
    _plot_breakdown(dg.summary, plt, out / "breakdown.png")
    _plot_heldout(dg, plt, out / "heldout.png")
    md = out / "report.md"
    atomic_write_text(md, _markdown(dg.summary, source), "report")
    return md


def _savefig(fig: Any, path: Path) -> None:
    """Save a PNG atomically (a failed save leaves neither half a file nor a temporary one)."""
    with atomic_write(path, "plot") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
