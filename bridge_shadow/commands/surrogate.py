"""``bridge-shadow surrogate``: solve the bridge FE model; print the surrogate, write it with ``--out``."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "run the bridge FE model and write the surrogate u = A x + u0 (+ thermal, sensitivities)"
DESCRIPTION = """\
Builds the parametric FE model of the test bridge from config/bridge.yaml and computes:
  A        2x2 N/m, reaction change of [FRC-01 south, FRC-02 north] per metre of upward
           displacement of each central bearing (unit-settlement solves, checked against the
           Schur complement to 1e-8 relative)
  u0       [south, north] N, reactions under self-weight + superimposed load, zero settlement
  thermal  N/K for uniform, vertical_gradient (top warmer), transverse_gradient (south warmer)
  sensitivities  change of A, u0, thermal per unit relative change of bearing_stiffness,
           connector_stiffness, support_spring_south/north and slab_joint_opening (adjoint:
           U^T dK U, no extra solve; a support spring at .inf gets its per-compliance form)
  sweeps   A, u0, thermal FE-solved at 7-8 values over the plausible range of bearing_stiffness,
           connector_stiffness and slab_joint_opening (with --out; --no-sweeps skips them): what
           the gap diagnosis fits a large stiffness change with
and prints them with provenance (model sha256, overrides, mesh, DOFs, solver, seconds). Nothing is
written without --out: config/surrogate.yaml is the calibrated model of the real bridge
(`bridge-shadow calibrate`), config/surrogate_fe.yaml the uncalibrated FE surrogate of the
as-built model; regenerate both with `make models`.

examples:
  bridge-shadow surrogate                          # default mesh, print only
  bridge-shadow surrogate --out config/surrogate_fe.yaml   # the committed uncalibrated surrogate
  bridge-shadow surrogate --mesh coarse --out /tmp/s.yaml --json
  bridge-shadow surrogate --set support_spring_south=2e7 --set slab_joint_opening=0.1 --out /tmp/s.yaml
  bridge-shadow surrogate --mesh coarse --vtk /tmp/vtk --png docs/model.png
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the options."""
    parser.add_argument("--mesh", default="default", metavar="LEVEL", help="coarse, default or fine")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a named parameter of bridge.yaml (repeatable), SI units",
    )
    parser.add_argument(
        "--model", type=Path, default=None, help="bridge model YAML (default config/bridge.yaml)"
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="write the surrogate YAML here (default: write nothing)"
    )
    parser.add_argument("--force", action="store_true", help="replace an existing surrogate file at --out")
    parser.add_argument("--vtk", type=Path, default=None, metavar="DIR", help="write mesh + deflected shapes")
    parser.add_argument("--png", type=Path, default=None, help="write a 3D view of the model")
    parser.add_argument("--no-sensitivities", action="store_true", help="skip the stiffness sensitivities")
    parser.add_argument(
        "--no-sweeps", action="store_true", help="skip the parameter sweeps (about 20 FE solves, with --out)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _summary(doc: dict) -> str:
    a, u0, th, prov = doc["A"], doc["u0"], doc["thermal"], doc["provenance"]
    lines = [
        f"mesh {prov['mesh']}: {prov['dofs']} DOFs, {prov['seconds']:.1f} s, solver {prov['solver']}",
        f"A [kN/mm]     [[{a[0][0] / 1e6:8.3f} {a[0][1] / 1e6:8.3f}]",
        f"               [{a[1][0] / 1e6:8.3f} {a[1][1] / 1e6:8.3f}]]"
        f"   Schur check {prov['schur_check']['max_rel_diff']:.1e}",
        f"u0 [kN]       {u0[0] / 1e3:8.2f} {u0[1] / 1e3:8.2f}   (total dead load "
        f"{prov['total_dead_load_N'] / 1e3:.1f} kN)",
    ]
    lines += [f"{k:<13} {v[0] / 1e3:8.3f} {v[1] / 1e3:8.3f}  kN/K" for k, v in th.items()]
    lower = [sum(row) * -0.01 / 1e3 for row in a]
    lines.append(f"1 cm lowering of both central bearings: dR = {lower[0]:.2f} / {lower[1]:.2f} kN")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Compute and write the surrogate."""
    import sys

    from bridge_shadow.commands.output import emit_json, progress
    from bridge_shadow.model.config import load_bridge_config, parse_overrides
    from bridge_shadow.model.surrogate import compute_surrogate, write_surrogate

    cfg = load_bridge_config(args.model, parse_overrides(args.overrides))
    cfg.mesh(args.mesh)  # fail early on an unknown level
    # every output path is checked before the FE solves, so a bad one costs no minutes
    from bridge_shadow.fileio import check_output_dir, check_output_file
    from bridge_shadow.model.surrogate_file import surrogate_target

    if args.out is not None:
        surrogate_target(args.out, create=False, force=args.force)
    if args.png is not None:
        check_output_file(args.png, "model picture")
    if args.vtk is not None:
        check_output_dir(args.vtk, "VTK directory")
    run_ = compute_surrogate(
        cfg,
        args.mesh,
        sensitivities=not args.no_sensitivities,
        report=lambda f, s: progress(f, "surrogate"),
        sweeps=args.out is not None and not args.no_sweeps,
    )
    out = args.out
    if out is not None:
        write_surrogate(run_, out, force=args.force)
    doc = run_.document()
    doc["provenance"]["written_to"] = str(out) if out is not None else None
    if args.vtk is not None:
        from bridge_shadow.fe.vtk import write_vtu

        vtu = write_vtu(args.vtk / f"bridge_{args.mesh}.vtu", run_.base.model, run_.base.results)
        doc["provenance"]["vtk"] = str(vtu)
    if args.png is not None:
        from bridge_shadow.model.plot import plot_model

        doc["provenance"]["png"] = str(plot_model(run_.base.mesh, args.png, run_.base))
    if args.json:
        emit_json(doc)
    else:
        print(_summary(doc))
        note = f"wrote {out}" if out is not None else "wrote nothing (give --out to write the surrogate)"
        print(note, file=sys.stderr)
    return 0
