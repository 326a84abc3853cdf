"""The sweeps behind ``bridge-shadow verify``: mesh distortion with convergence rates; drilling penalty.

* Distortion: the Scordelis-Lo roof and the simply supported plate on regular meshes and with their
  interior nodes moved at random (up to 10 % and 20 % of the spacing each way, fixed seed), on
  successively halved meshes. Each row gives the value, its ratio to the published reference, the
  error against the best estimate of the converged value (the plate's Navier series; for the roof our
  Richardson extrapolation from the finest regular mesh and one twice as fine, as the published
  0.3024 is rounded), the observed order ``log2(e_h / e_{h/2})`` of that error, and the change the
  distortion makes against the regular mesh of the same size. The roof converges non-monotonically
  (from above, then from just below near 32 x 32), so its observed orders swing where the error
  changes sign; the plate's are clean and toleranced.
* Drilling penalty: the cases that see it (warped twisted beam, in-plane cantilevers, cylinders,
  the shell I-girder) at ``DRILL_FACTOR`` over six decades, each as a ratio of its value at the
  default.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from bridge_shadow.fe.elements.shell import DRILL_FACTOR
from bridge_shadow.fe.verify.case import Case, make_case
from bridge_shadow.fe.verify.shells import (
    Solution,
    macneal_cantilever,
    pinched_cylinder,
    scordelis_lo,
    ss_plate,
    twisted_beam,
)
from bridge_shadow.fe.verify.spans import girder_mid_reactions

__all__ = ["DistortionRow", "DrillRow", "distortion_sweep", "drill_sweep"]

#: Interior-node perturbations of the distortion sweep (fraction of the mesh spacing, each way).
DISTORTIONS = (0.0, 0.1, 0.2)
#: Drilling penalty factors of the sweep (the default is 1).
DRILL_FACTORS = (1e-6, 1e-4, 1e-2, 1e-1, 1.0, 10.0)


@dataclass
class DistortionRow:
    """One mesh of the distortion sweep (see the module docstring for the columns)."""

    problem: str
    distortion: float
    n: int
    dofs: int
    value: float
    ratio: float
    error: float
    rate: float | None
    distortion_effect: float

    def as_dict(self) -> dict[str, object]:
        """Return the JSON form."""
        return asdict(self)


@dataclass
class DrillRow:
    """One case at one drilling penalty: its value and its ratio to the value at the default."""

    case: str
    drill_factor: float
    value: float
    ratio_to_default: float

    def as_dict(self) -> dict[str, object]:
        """Return the JSON form."""
        return asdict(self)


_PROBLEMS: dict[str, tuple[Callable[..., Solution], float, str]] = {
    "scordelis_lo": (scordelis_lo, 0.3024, "MH85-SL"),
    "ss_plate": (ss_plate, 0.0040624, "TW59"),
}


def distortion_sweep(quick: bool = False, seed: int = 0) -> tuple[list[DistortionRow], list[Case]]:
    """Run the distortion sweep; return its rows and the toleranced summary cases."""
    sizes = (4, 8, 16) if quick else (4, 8, 16, 32)
    rows: list[DistortionRow] = []
    cases: list[Case] = []
    top = max(DISTORTIONS)
    for name, (solve, published, ref) in _PROBLEMS.items():
        sols = {(d, n): solve(n, d, seed) for d in DISTORTIONS for n in sizes}
        if name == "ss_plate":
            converged = published
        else:  # Richardson, order 2, from the finest regular mesh and one twice as fine
            coarse, fine = sols[(0.0, sizes[-1])].value, solve(2 * sizes[-1]).value
            converged = fine + (fine - coarse) / 3
        for d in DISTORTIONS:
            errors = [abs(sols[(d, n)].value / converged - 1) for n in sizes]
            for k, n in enumerate(sizes):
                sol = sols[(d, n)]
                rate = None if k == 0 else float(np.log2(errors[k - 1] / max(errors[k], 1e-300)))
                rows.append(
                    DistortionRow(
                        name,
                        d,
                        n,
                        sol.dofs,
                        sol.value,
                        sol.value / published,
                        errors[k],
                        rate,
                        sol.value / sols[(0.0, n)].value - 1,
                    )
                )
        n = sizes[-1]
        sol = sols[(top, n)]
        seconds = sum(s.seconds for s in sols.values())
        cases.append(
            make_case(
                f"{name}_{n}x{n}_distorted_{top:.0%}",
                sol.value,
                published,
                0.01,
                sol.mesh,
                sol.dofs,
                sol.seconds,
                ref,
                "interior nodes moved at random by up to 20 % of the spacing each way (seed 0)",
            )
        )
        effect = abs(sol.value / sols[(0.0, n)].value - 1)
        cases.append(
            make_case(
                f"{name}_distortion_effect_{n}x{n}",
                effect,
                0.0,
                1e-3,
                f"{n}x{n} vs regular",
                sol.dofs,
                seconds,
                ref,
                "normalized: |distorted / regular - 1| at the finest mesh (the distortion error vanishes)",
            )
        )
        if name == "ss_plate":
            rates = [r.rate for r in rows if r.problem == name and r.distortion == top and r.rate is not None]
            order = float(np.mean(rates[-2:]))
            cases.append(
                make_case(
                    f"ss_plate_distorted_{top:.0%}_convergence_order",
                    order,
                    2.0,
                    0.25,
                    f"{sizes[-3]}..{n} quarter",
                    sol.dofs,
                    seconds,
                    ref,
                    "observed order of the deflection error (mean of the last two halvings); "
                    "bilinear elements: 2",
                )
            )
    return rows, cases


def _drill_cases(factor: float, quick: bool) -> dict[str, float]:
    """Values of the penalty-sensitive cases at one drilling factor."""
    out = {
        "twisted_beam_inplane": twisted_beam("inplane", factor).value,
        "twisted_beam_outofplane": twisted_beam("outofplane", factor).value,
    }
    for shape in ("rectangular", "trapezoidal", "parallelogram"):
        out[f"macneal_{shape}_inplane"] = macneal_cantilever(shape, "inplane", factor).value
    out["scordelis_lo_16x16"] = scordelis_lo(16, drill=factor).value
    out["pinched_cylinder_32x32"] = pinched_cylinder(32, factor).value
    n = 15 if quick else 30
    out[f"two_span_shell_{2 * n}_settlement"] = girder_mid_reactions(n, factor)[0][0]
    return out


def drill_sweep(quick: bool = False) -> tuple[list[DrillRow], list[Case]]:
    """Run the drilling-penalty sweep; return its rows and two summary cases (decade and full range)."""
    factors = sorted({*DRILL_FACTORS, DRILL_FACTOR})
    values = {f: _drill_cases(f, quick) for f in factors}
    base = values[DRILL_FACTOR]
    rows = [DrillRow(c, f, v, v / base[c]) for f in factors for c, v in values[f].items()]
    lo, hi = DRILL_FACTOR / 10, DRILL_FACTOR * 10
    near = [abs(r.ratio_to_default - 1) for r in rows if lo <= r.drill_factor <= hi]
    spread = [abs(r.ratio_to_default - 1) for r in rows]
    worst = max(rows, key=lambda r: abs(r.ratio_to_default - 1))
    label = f"{len(base)} cases"
    cases = [
        make_case(
            "drill_factor_within_a_decade",
            max(near),
            0.0,
            0.01,
            label,
            0,
            0.0,
            "SWEEP",
            f"normalized: largest |value / value at {DRILL_FACTOR:g} - 1| for DRILL_FACTOR in "
            f"[{lo:g}, {hi:g}]",
        ),
        make_case(
            "drill_factor_over_six_decades",
            max(spread),
            0.0,
            None,
            label,
            0,
            0.0,
            "SWEEP",
            f"largest change over {min(factors):g}..{max(factors):g} is {worst.case} at "
            f"{worst.drill_factor:g}; with almost no penalty the drilling rotation of warped quads is "
            "held only by the small angles between neighbours, so the twisted beam softens",
        ),
    ]
    return rows, cases
