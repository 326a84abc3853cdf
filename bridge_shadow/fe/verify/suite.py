"""The verification suite: which problems run, on which meshes, judged by which tolerance (or why none)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from bridge_shadow.fe.verify.case import Case, make_case
from bridge_shadow.fe.verify.shells import (
    macneal_cantilever,
    patch_test,
    pinched_cylinder,
    scordelis_lo,
    ss_plate,
    thermal_strip,
    twisted_beam,
)
from bridge_shadow.fe.verify.spans import two_span_cases
from bridge_shadow.fe.verify.sweeps import DistortionRow, DrillRow, distortion_sweep, drill_sweep

__all__ = ["Report", "run_cases", "run_report", "suite"]

_COARSE = "coarsest mesh of the convergence study; the finer meshes are toleranced"
_MH_GOAL = (
    "distorted mesh: goal |ratio - 1| <= 5 % (commercial QUAD4 give 0.17-0.22 in-plane on the trapezoids, "
    "GCMQ19 0.985)"
)
_GCMQ_PAPER = {"rectangular": 1.0733, "parallelogram": 1.0488, "trapezoidal": 1.0654}


def _scordelis(quick: bool) -> list[Case]:
    sizes = (4, 8, 16) if quick else (8, 16, 32)
    out = []
    for n in sizes:
        s = scordelis_lo(n)
        coarse = n == sizes[0]
        out.append(
            make_case(
                f"scordelis_lo_{n}x{n}", s.value, 0.3024, None if coarse else 0.01, s.mesh, s.dofs, s.seconds,
                "MH85-SL", _COARSE if coarse else "",
            )
        )  # fmt: skip
    n = sizes[-1]
    s = scordelis_lo(n)
    out.append(
        make_case(
            f"scordelis_lo_{n}x{n}_deep_shell", s.value, 0.3086, None, s.mesh, s.dofs, s.seconds, "SL64",
            "a different theory (deep shell); flat facets converge to MH85-SL's 0.3024",
        )
    )  # fmt: skip
    return out


def _pinched() -> list[Case]:
    a, b, ref = pinched_cylinder(16), pinched_cylinder(32), 1.8248e-5
    return [
        make_case(
            "pinched_cylinder_16x16", a.value, ref, None, a.mesh, a.dofs, a.seconds, "MH85-PC", _COARSE
        ),
        make_case("pinched_cylinder_32x32", b.value, ref, 0.02, b.mesh, b.dofs, b.seconds, "MH85-PC"),
    ]


def _macneal() -> list[Case]:
    out = []
    for shape in ("rectangular", "trapezoidal", "parallelogram"):
        for direction, ref in (("inplane", 0.1081), ("outofplane", 0.4321)):
            s = macneal_cantilever(shape, direction)
            tol, why = (0.02, "") if shape == "rectangular" else (0.05, _MH_GOAL)
            name = f"macneal_{shape}_{direction}"
            out.append(make_case(name, s.value, ref, tol, s.mesh, s.dofs, s.seconds, "MH85-SB", why))
    for shape, ref in _GCMQ_PAPER.items():  # the membrane alone against its paper's table
        s = macneal_cantilever(shape, "inplane", drill=0.0, E=1.0e5, thickness=1.0)
        out.append(
            make_case(
                f"gcmq_paper_thin_beam_{shape}", s.value, ref, 5e-4, s.mesh, s.dofs, s.seconds, "GCMQ19",
                "reproduces the published table (4 digits) with the drilling penalty off",
            )
        )  # fmt: skip
    return out


def _others() -> list[Case]:
    out = []
    for direction, ref in (("inplane", 0.005424), ("outofplane", 0.001754)):
        s = twisted_beam(direction)
        name = f"twisted_beam_{direction}"
        out.append(make_case(name, s.value, ref, 0.02, s.mesh, s.dofs, s.seconds, "MH85-TB"))
    s = ss_plate(8)
    out.append(make_case("ss_plate_8x8", s.value, 0.0040624, 0.01, s.mesh, s.dofs, s.seconds, "TW59"))
    for kind in ("membrane", "bending"):
        s = patch_test(kind)
        out.append(
            make_case(
                f"patch_{kind}", s.value, 0.0, 1e-8, s.mesh, s.dofs, s.seconds, "MH85-PT",
                "normalized: largest interior DOF error over the largest DOF value",
            )
        )  # fmt: skip
    s = thermal_strip(10)
    ref = 1.2e-5 * 10.0 * 1.0**2 / (2 * 0.01)
    out.append(make_case("thermal_strip_gradient", s.value, ref, 1e-6, s.mesh, s.dofs, s.seconds, "PLATE"))
    return out


def suite(quick: bool = False) -> list[Callable[[], list[Case]]]:
    """Return the verification cases as thunks; ``quick`` uses coarser meshes (tolerances still hold)."""
    return [
        lambda: _scordelis(quick),
        _pinched,
        _macneal,
        _others,
        lambda: list(two_span_cases(n_beam=10, n_shell=15 if quick else 30)),
    ]


@dataclass
class Report:
    """Everything ``verify`` found: the cases and, when run, the two sweeps' rows."""

    cases: list[Case]
    distortion: list[DistortionRow] = field(default_factory=list)
    drill: list[DrillRow] = field(default_factory=list)

    def as_dict(self) -> dict[str, object]:
        """Return the JSON form ``{"cases": [...], "distortion_sweep": [...], "drill_sweep": [...]}``."""
        return {
            "cases": [c.as_dict() for c in self.cases],
            "distortion_sweep": [r.as_dict() for r in self.distortion],
            "drill_sweep": [r.as_dict() for r in self.drill],
        }


def run_report(
    quick: bool = False, sweeps: bool = True, progress: Callable[[float, str], None] | None = None
) -> Report:
    """Run the suite (and the sweeps); the sweeps' summary cases are appended to the cases."""
    thunks: list[Callable[[], object]] = list(suite(quick))
    if sweeps:
        thunks += [lambda: distortion_sweep(quick), lambda: drill_sweep(quick)]
    report = Report([])
    for k, thunk in enumerate(thunks):
        got = thunk()
        if isinstance(got, tuple):
            rows, cases = got
            if rows and isinstance(rows[0], DistortionRow):
                report.distortion = rows
            else:
                report.drill = rows
            report.cases.extend(cases)
        else:
            report.cases.extend(got)  # type: ignore[arg-type]
        if progress is not None:
            progress((k + 1) / len(thunks), "verify")
    return report


def run_cases(
    quick: bool = False, progress: Callable[[float, str], None] | None = None, sweeps: bool = True
) -> list[Case]:
    """Run the whole suite and return every case, in order."""
    return run_report(quick, sweeps, progress).cases
