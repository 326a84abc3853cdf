"""One verification result and how it is judged: a tolerance, or a stated reason for having none."""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

from bridge_shadow.fe.verify.references import REFERENCES

__all__ = ["Case", "Timer", "make_case"]


@dataclass
class Case:
    """One verification result (SI units, as the benchmark defines them).

    Attributes:
        name: case name. computed, reference: the value and its reference (0 for normalized errors).
        ratio: computed / reference, None when the reference is 0.
        tolerance: allowed ``|ratio - 1|`` (or ``|computed|`` when the reference is 0); None: reported.
        mesh, dofs, seconds: what was solved and how long it took.
        passed: None for a reported case.
        source: where the reference comes from (full text). ref: its short key.
        reason: why a case has no tolerance, or what its tolerance stands for.

    """

    name: str
    computed: float
    reference: float
    ratio: float | None
    tolerance: float | None
    mesh: str
    dofs: int
    seconds: float
    passed: bool | None
    source: str
    reason: str
    ref: str

    def as_dict(self) -> dict[str, object]:
        """Return the JSON form: the contract's keys first, then ``passed``, ``source``, ``reason``."""
        return asdict(self)


def make_case(
    name: str,
    computed: float,
    reference: float,
    tol: float | None,
    mesh: str,
    dofs: int,
    seconds: float,
    ref: str,
    reason: str = "",
) -> Case:
    """Judge ``|computed / reference - 1| <= tol`` (or ``|computed| <= tol`` when the reference is 0).

    A case without a tolerance must say why (``reason``); ``ref`` is a key of ``REFERENCES``.
    """
    if tol is None and not reason:
        raise ValueError(f"verification case {name!r} has neither a tolerance nor a stated reason")
    if reference == 0.0:
        ratio = None
        passed = None if tol is None else bool(abs(computed) <= tol)
    else:
        ratio = computed / reference
        passed = None if tol is None else bool(abs(ratio - 1.0) <= tol)
    return Case(
        name,
        float(computed),
        float(reference),
        ratio,
        tol,
        mesh,
        int(dofs),
        float(seconds),
        passed,
        REFERENCES[ref].source,
        reason,
        ref,
    )


class Timer:
    """Context manager: ``seconds`` of wall time spent inside."""

    def __enter__(self) -> Timer:
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> None:
        self.seconds = time.perf_counter() - self.t0
