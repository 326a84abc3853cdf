"""Verification of the FE solver: published shell benchmarks, patch tests, closed forms, two sweeps.

Each case builds its model from scratch, solves it and returns a :class:`Case` with the computed
value, the reference, their ratio, the tolerance it must meet, the reference's source, and, for a
case without a tolerance, the reason why. Cases whose reference is zero (patch tests, free thermal
expansion, sweep spreads) report a normalized error as ``computed`` with ``reference = 0`` and an
absolute tolerance. Nothing is tuned per case: every shell uses the same element with the same
drilling factor, except where a case says otherwise (the GCMQ paper check, the drilling sweep).

Modules: ``references`` (values and sources), ``case`` (a result and its judgement), ``shells``
(shell problems), ``spans`` (two equal spans, beam and shell girder), ``sweeps`` (mesh distortion
with convergence rates; drilling penalty over six decades), ``suite`` (what runs, on which meshes).
"""

from bridge_shadow.fe.verify.case import Case
from bridge_shadow.fe.verify.references import REFERENCES, Reference
from bridge_shadow.fe.verify.shells import patch_test, scordelis_lo_model, thermal_strip
from bridge_shadow.fe.verify.spans import i_girder
from bridge_shadow.fe.verify.suite import Report, run_cases, run_report, suite

__all__ = [
    "REFERENCES",
    "Case",
    "Reference",
    "Report",
    "i_girder",
    "patch_test",
    "run_cases",
    "run_report",
    "scordelis_lo_model",
    "suite",
    "thermal_strip",
]
