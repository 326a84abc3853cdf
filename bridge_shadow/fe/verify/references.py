"""Reference values of the verification suite, each with where it comes from.

``bridge-shadow verify`` prints the short key of each case's reference in its table and the full
source below it; ``verify --json`` carries the full source in every case (key ``source``).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["REFERENCES", "Reference"]


@dataclass(frozen=True)
class Reference:
    """A published or closed-form reference: short ``key`` for tables, full ``source`` text."""

    key: str
    source: str


_MH85 = "MacNeal & Harder 1985, A proposed standard set of problems to test finite element accuracy, "
_MH85 += "Finite Elem. Anal. Des. 1:3-20"

#: Every reference the suite uses, by key.
REFERENCES: dict[str, Reference] = {
    r.key: r
    for r in (
        Reference(
            "MH85-SL",
            f"{_MH85}: Scordelis-Lo roof, vertical free-edge midpoint deflection 0.3024, the value MacNeal "
            "and Harder normalize with because shell elements converge to it (deep-shell theory: 0.3086)",
        ),
        Reference(
            "SL64",
            "Scordelis & Lo 1964 deep-shell theory, 0.3086 (as quoted by MacNeal & Harder 1985); flat "
            "Reissner-Mindlin facets converge about 2 % below it, to the 0.3024 of MH85-SL",
        ),
        Reference(
            "MH85-PC",
            f"{_MH85}: pinched cylinder with rigid end diaphragms, radial deflection under the load "
            "1.8248e-5 (series solution of Lindberg, Olson & Cowper 1969)",
        ),
        Reference(
            "MH85-SB",
            f"{_MH85}: straight cantilever 6.0 x 0.2 x 0.1, E = 1e7, nu = 0.3, unit tip shear: beam theory "
            "0.1081 in-plane, 0.4321 out-of-plane; meshes of their Fig. 2 (interior edges at 45 degrees "
            "through x = 1..5 on the axis, straight ends)",
        ),
        Reference(
            "MH85-TB",
            f"{_MH85}: twisted beam (90 degrees over 12, width 1.1, t = 0.32, E = 29e6, nu = 0.22), tip "
            "deflection 0.005424 in-plane, 0.001754 out-of-plane",
        ),
        Reference(
            "MH85-PT",
            f"{_MH85}: patch test 0.24 x 0.12, interior nodes (0.04, 0.02), (0.18, 0.03), (0.16, 0.08), "
            "(0.08, 0.08); exact linear field u = 1e-3 (x + y/2), v = 1e-3 (y + x/2), "
            "w = 1e-3 (x^2 + xy + y^2)/2",
        ),
        Reference(
            "TW59",
            "Timoshenko & Woinowsky-Krieger 1959, Theory of Plates and Shells, Navier series: simply "
            "supported square plate under uniform pressure, centre deflection 0.0040624 q a^4 / D (nu = 0.3)",
        ),
        Reference(
            "GCMQ19",
            "Chang, Lee, Carr, Dhakal & Pampanin 2019, Int. J. Numer. Meth. Engng 118:493-514, "
            "doi:10.1002/nme.6066, MacNeal's thin beam (E = 1e5, t = 1, nu = 0.3, tip shear P = 1, no "
            "drilling penalty): GCMQ-I tip deflection 1.0733 / 1.0488 / 1.0654 on meshes a / b / c",
        ),
        Reference(
            "PLATE", "closed form: a free plate under a through-thickness gradient bends to alpha dT/h"
        ),
        Reference(
            "2SPAN",
            "closed forms for two equal spans L (force method): dR_mid = -6 EI delta / L^3, "
            "dR_mid = -3 EI alpha dT / (h L), R_mid = 5 q L / 4, no reaction under free uniform temperature",
        ),
        Reference(
            "TIMO",
            "Timoshenko beam theory for the two spans, shear area = web h tw: flexibility "
            "L^3 / (6 EI) + L / (2 G As) under a mid-span force",
        ),
        Reference(
            "RICH",
            "our own regular-mesh Richardson extrapolation (order 2 from the two finest regular meshes), "
            "for observed convergence rates where the published value is itself rounded",
        ),
        Reference("SWEEP", "the same cases at DRILL_FACTOR = 1 (the default): relative change"),
    )
}
