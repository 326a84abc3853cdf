"""Human-readable calibration report (kN, mm) and its figures; the JSON stays SI.

``summary_text`` is what ``bridge-shadow calibrate`` prints; ``write_figures`` draws the records with
the car-free windows and levels, and the explanations' evidence and implied differential mode
(``--report DIR``; the README's figures come from here).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from bridge_shadow.calibrate.run import CalibrationResult

__all__ = ["plateau_comparison", "summary_text", "write_figures"]

KN, MM = 1e3, 1e-3


def plateau_comparison(result: CalibrationResult) -> list[dict[str, Any]]:
    """Parked-car plateaus before vs after, matched in order: sums above the baseline and their ratio.

    The car's weight and positions are unknown, so the plateaus cannot fix a stiffness; with the car
    parked at the same places, equal sums before and after say the response to a live load did
    not change with the lowering (linear behaviour); the south-north split of a plateau follows
    the car's lateral position.
    """
    out = []
    for p in result.pairs:
        b, a = p.change.before, p.change.after
        if b is None or a is None:
            continue
        for i, (pb, pa) in enumerate(zip(b.car.plateaus, a.car.plateaus, strict=False)):
            sb, sa = float(pb.height_n.sum()), float(pa.height_n.sum())
            out.append(
                {
                    "pair": p.name,
                    "plateau": i + 1,
                    "before_n": pb.height_n.tolist(),
                    "after_n": pa.height_n.tolist(),
                    "sum_ratio": sa / sb if sb else float("nan"),
                }
            )
    return out


def summary_text(result: CalibrationResult) -> str:
    """Return the printed report (kN, mm)."""
    spec = result.spec
    lines = [
        f"calibration on {len(result.pairs)} record pair(s), mesh {spec.mesh}, "
        f"baseline change: {spec.baseline_change}"
    ]
    for p in result.pairs:
        c = p.change
        s = c.sd_n / KN
        total_sd = np.sqrt(c.cov_n2.sum()) / KN
        lines.append(
            f"  {p.name}: imposed {p.imposed_m[0] / MM:+.1f} / {p.imposed_m[1] / MM:+.1f} mm (sd "
            f"{p.imposed_sd_m[0] / MM:.2f}); measured dR = {c.dR_n[0] / KN:+.2f} +- {s[0]:.2f} / "
            f"{c.dR_n[1] / KN:+.2f} +- {s[1]:.2f} kN (south/north), "
            f"sum {c.dR_n.sum() / KN:+.2f} +- {total_sd:.2f}"
        )
        lines.append(
            f"    {c.dt_s / 60:.1f} min between the levels, air {c.air_temp_change_k:+.2f} K; sd parts (kN): "
            + ", ".join(
                f"{k} {v[0] / KN:.2f}/{v[1] / KN:.2f}"
                for k, v in ((k, np.sqrt(np.diag(m))) for k, m in c.parts.items())
            )
        )
        for label, r in (("before", c.before), ("after", c.after)):
            if r is None:
                continue
            lines.append(
                f"    {label:6s} level {r.level_n[0] / KN:.2f} / {r.level_n[1] / KN:.2f} kN, drift "
                f"{r.rate_n_per_s[0] * 60 / KN:+.3f} / {r.rate_n_per_s[1] * 60 / KN:+.3f} kN/min, "
                f"{r.windows} car-free windows of {r.window_s:g} s, "
                f"test car on {100 * (1 - r.car.free_fraction):.0f} % of the record, "
                f"{len(r.car.plateaus)} parked plateaus"
            )
    plats = plateau_comparison(result)
    if plats:
        lines.append(
            "  test-car plateaus, sum above the baseline before -> after (kN): "
            + ", ".join(f"{sum(q['before_n']) / KN:.2f} -> {sum(q['after_n']) / KN:.2f}" for q in plats)
            + "; equal sums: the live-load response did not change with the lowering (linear). The car's "
            "weight and positions are unknown, so they do not constrain any stiffness."
        )
    lines.append("")
    lines.append("explanations (Laplace evidence; the imposed-settlement errors are estimated in each):")
    head = (
        f"  {'explanation':<20} {'logZ':>7} {'dlogZ':>6} {'P':>5} {'chi2':>6} {'k_common S/N':>13} "
        f"{'k_diff':>6} {'x = A^-1 dR (mm)':>17} {'jack err (mm)':>14}"
    )
    ref = result.reference_n is not None
    if ref:
        head += f" {'ref +-x (mm)':>12}"
    if any(r["heldout_logpdf"] is not None for r in result.table()):
        head += f" {'held-out':>9}"
    lines.append(head)
    lines.append("  " + " " * 44 + "(kN/mm)   (kN/mm)")
    for r in result.table():
        kc = r["common_stiffness_n_per_m"]
        x = r["in_sample"][0]["x_m"]
        jack = next(iter(r["imposed_error_m"].values()))["map"]
        line = (
            f"  {r['name']:<20} {r['log_evidence']:7.2f} {r['delta_log_evidence']:6.2f} "
            f"{r['probability']:5.2f} {r['chi2_data']:6.2f} {kc[0] / 1e6:6.2f}/{kc[1] / 1e6:<6.2f} "
            f"{r['differential_stiffness_n_per_m'] / 1e6:6.2f} "
            f"{x[0] / MM:8.2f}/{x[1] / MM:<8.2f} {jack[0] / MM:+6.2f}/{jack[1] / MM:+.2f}"
        )
        if ref:
            line += f" {r['reference']['half_difference_m'] / MM:12.2f}"
        if r["heldout_logpdf"] is not None:
            line += f" {r['heldout_logpdf']:9.2f}"
        if r["name"] == result.chosen:
            line += "  <- chosen"
        lines.append(line)
    if ref:
        lines.append(
            f"  ref +-x: half the south-north difference of x = A^-1 (R - u0) for {spec.reference_name} "
            f"(R = {result.reference_n[0] / KN:.1f} / {result.reference_n[1] / KN:.1f} kN): "
            "the inferred split "
            "depends on the explanation"
        )
    chosen = result.explanations[result.chosen]
    row = next(r for r in result.table() if r["name"] == result.chosen)
    lines.append("")
    how = {"best": "highest evidence", "average": "the most probable; the FE sensitivities are solved here"}
    lines.append(f"chosen: {result.chosen} ({how.get(spec.choose, 'named in the file')})")
    lines.append(
        "  parameter                        prior centre [95 % range]          MAP       "
        "posterior 95 %        post/prior sd"
    )
    for n, v in row["map"].items():
        bound = " (at its bound)" if v["at_bound"] else ""
        lines.append(
            f"  {n:<32} {v['prior_centre']:9.3g} [{v['prior_range'][0]:.2g}, {v['prior_range'][1]:.2g}]"
            f"  {v['map']:9.3g}  [{v['low95']:.3g}, {v['high95']:.3g}]  "
            f"{v['posterior_to_prior_sd']:6.2f}{bound}"
        )
    a, u0 = result.run.surrogate.A, result.run.surrogate.u0
    zero = "the car-free level of the first pair's before record" if spec.zero == "before" else "as built"
    lines.append(
        f"  A (kN/mm) [[{a[0, 0] / 1e6:.3f}, {a[0, 1] / 1e6:.3f}], "
        f"[{a[1, 0] / 1e6:.3f}, {a[1, 1] / 1e6:.3f}]] "
        + ("(the model average, below)" if spec.choose == "average" else "(FE re-solved at the MAP)")
        + f", u0 {u0[0] / KN:.1f} / {u0[1] / KN:.1f} kN ({zero}: x = 0 there)"
    )
    for s in chosen.in_sample():
        lines.append(
            f"  in-sample {s['pair']}: x = A^-1 dR = {s['x_m'][0] / MM:.2f} / {s['x_m'][1] / MM:.2f} mm, "
            f"common {s['common_m'] / MM:.2f} mm ({100 * s['common_error_rel']:+.1f} % of "
            f"{np.mean(s['imposed_m']) / MM:.1f}), "
            f"differential {s['differential_m'] / MM:+.2f} mm"
        )
    ident = chosen.identifiability()
    lines.append(f"  identifiability: {ident['summary']}")
    for d in ident["directions"]:
        combo = ", ".join(f"{k} {v:+.2f}" for k, v in d["combination"].items())
        lines.append(
            f"    s = {d['singular_value']:.2f} "
            f"(posterior/prior sd {d['posterior_to_prior_sd']:.2f}): {combo}"
        )
    lines += _average_lines(result)
    lines += _sensitivity_lines(result)
    lines.append(f"{result.store.solves} FE solves, {result.seconds:.1f} s")
    return "\n".join(lines)


def _average_lines(result: CalibrationResult) -> list[str]:
    """Describe the model average: weights, stiffness, its spread, the in-sample reading (kN/mm, mm)."""
    avg = result.extra.get("model_average")
    if not avg:
        return []
    written = "written to the surrogate" if result.spec.choose == "average" else "not written (--choose)"
    top = sorted(avg["weights"].items(), key=lambda kv: -kv[1])
    kc, kd = avg["common_stiffness_n_per_m"], avg["differential_stiffness_n_per_m"]
    sd = avg["sd"]
    sets = avg.get("prior_sets")
    over = "the explanations"
    if sets:
        over += f" under the prior sets {', '.join(sets['sets'])}"
    out = [
        "",
        f"model average over {over} by their evidence ({written}):",
        "  weights: " + ", ".join(f"{k} {w:.2f}" for k, w in top if w >= 0.005),
        f"  common-mode stiffness {kc[0] / 1e6:.2f} / {kc[1] / 1e6:.2f} kN/mm, differential "
        f"{kd / 1e6:.2f} kN/mm; sd of A11 / A22 {sd['A11'] / 1e6:.2f} / {sd['A22'] / 1e6:.2f}, "
        f"of A12 {sd['A12'] / 1e6:.2f} kN/mm (each explanation's posterior and the spread between them)",
    ]
    for member, why in (sets or {}).get("left_out", {}).items():
        out.append(f"  left out: {member}: {why}")
    for s in avg["in_sample"]:
        out.append(
            f"  in-sample {s['pair']}: x = A^-1 dR = {s['x_m'][0] / MM:.2f} / {s['x_m'][1] / MM:.2f} mm, "
            f"common {s['common_m'] / MM:.2f} mm"
        )
    disc = result.run.surrogate.discrepancy
    if disc is not None:
        out.append(
            f"  discrepancy beyond the calibrated settlements ({disc.low_m[0] / MM:.0f}.."
            f"{disc.high_m[0] / MM:.0f} / {disc.low_m[1] / MM:.0f}..{disc.high_m[1] / MM:.0f} mm): "
            f"{100 * disc.relative_sd:.0f} % "
            f"(1 sd) of the distance beyond, correlation {disc.correlation:.1f} between the supports"
        )
    return out


def _sensitivity_lines(result: CalibrationResult) -> list[str]:
    """Which explanation wins under each prior set (--prior-sensitivity)."""
    rows = result.extra.get("prior_sensitivity")
    if not rows:
        return []
    out = ["", "prior sensitivity (which explanation wins under each defensible prior):"]
    for r in rows:
        mark = " (in use)" if r["in_use"] else ""
        best3 = ", ".join(
            f"{e['name']} {e['delta_log_evidence']:+.2f} ({e['probability']:.2f})"
            for e in r["explanations"][:4]
        )
        avg = r["model_average"]
        kc, kd = avg["common_stiffness_n_per_m"], avg["differential_stiffness_n_per_m"]
        x = avg["in_sample"][0]["x_m"] if avg["in_sample"] else [float("nan")] * 2
        out.append(f"  {r['prior_set']}{mark}: winner {r['winner']}; {best3}")
        out.append(
            f"    average: common {kc[0] / 1e6:.2f} / {kc[1] / 1e6:.2f} kN/mm, differential {kd / 1e6:.2f} "
            f"kN/mm, in-sample x {x[0] / MM:.2f} / {x[1] / MM:.2f} mm  [{r['description']}]"
        )
    return out


def _save(fig: Any, path: Path) -> Path:
    """Lay out, write (atomically: temporary file, then rename) and close a figure."""
    import matplotlib.pyplot as plt

    from bridge_shadow.fileio import atomic_write

    fig.tight_layout()
    try:
        with atomic_write(path, "figure") as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)
    return path


def write_figures(result: CalibrationResult, out_dir: str | Path) -> list[Path]:
    """Draw ``calibration_records.png`` and ``calibration_explanations.png`` into ``out_dir``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bridge_shadow.calibrate.car import bin_record
    from bridge_shadow.calibrate.records import load_record
    from bridge_shadow.fileio import output_dir

    out = output_dir(out_dir, "figure directory")
    files = []
    spec = result.spec
    ps = spec.pairs[0]
    fig, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True)
    for col, (label, paths, level) in enumerate(
        (
            ("before", ps.before, result.pairs[0].change.before),
            ("after", ps.after, result.pairs[0].change.after),
        )
    ):
        binned = bin_record(load_record(paths, spec.base_dir))
        t_min = binned.t_s / 60
        for row, name in enumerate(("south (FRC-01)", "north (FRC-02)")):
            ax = axes[row, col]
            y = binned.force_n[:, row] / KN
            ax.plot(t_min, y, lw=0.8, color="0.3", label="1 s means")
            car = level.car.car
            ax.plot(t_min[~car], y[~car], ".", ms=2, color="tab:green", label="car-free")
            for a0, a1 in level.car.intervals_s:
                ax.axvspan(a0 / 60, a1 / 60, color="tab:orange", alpha=0.15, lw=0)
            base = level.car.baseline[row]
            ax.plot(
                t_min,
                (base[0] + base[1] * binned.t_s) / KN,
                color="tab:blue",
                lw=1,
                label="car-free baseline",
            )
            tc = (level.t_ns - level.start_ns) / 1e9 / 60
            ax.plot([tc], [level.level_n[row] / KN], "o", color="tab:red", label="level")
            lo = np.nanmin(y[~car]) if (~car).any() else np.nanmin(y)
            ax.set_ylim(lo - 1.0, lo + 13.0)
            ax.set_title(f"{label}: {name}", fontsize=9)
            ax.set_ylabel("kN")
            if row == 1:
                ax.set_xlabel("min after the record start")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    c = result.pairs[0].change
    fig.suptitle(
        f"{ps.name}: dR = {c.dR_n[0] / KN:+.1f} +- {c.sd_n[0] / KN:.1f} / "
        f"{c.dR_n[1] / KN:+.1f} +- {c.sd_n[1] / KN:.1f} kN"
        " (south / north); test car shaded",
        fontsize=10,
    )
    files.append(_save(fig, out / "calibration_records.png"))

    rows = result.table()
    names = [r["name"] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), sharey=True)
    y = np.arange(len(rows))[::-1]
    colors = ["tab:red" if n == result.chosen else "tab:blue" for n in names]
    axes[0].barh(y, [r["probability"] for r in rows], color=colors)
    for yi, r in zip(y, rows, strict=True):
        axes[0].text(r["probability"] + 0.01, yi, f"{r['delta_log_evidence']:+.1f}", va="center", fontsize=7)
    axes[0].set_yticks(y, names, fontsize=8)
    axes[0].set_xlim(0, 1)
    axes[0].set_xlabel("posterior probability (equal prior odds); label: log evidence - best")
    axes[1].barh(y, [r["differential_stiffness_n_per_m"] / 1e6 for r in rows], color="tab:purple")
    axes[1].set_xlabel("differential-mode stiffness (kN/mm)")
    if result.reference_n is not None:
        axes[2].barh(y, [r["reference"]["half_difference_m"] / MM for r in rows], color="tab:green")
        axes[2].set_xlabel(f"+-x implied by {spec.reference_name} (mm)")
    for ax in axes:
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(
        "explanations of the 10 mm lowering: evidence, and what each implies for the south-north split",
        fontsize=10,
    )
    files.append(_save(fig, out / "calibration_explanations.png"))
    return files
