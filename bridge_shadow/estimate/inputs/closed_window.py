"""A closed 60 s window on its way to an output: the per-window record ``Shadow`` decides on."""

from __future__ import annotations

import numpy as np

__all__ = ["Window"]


class Window:
    """A closed window on its way to an output (slots: this is the per-window hot path).

    ``action`` is None while undecided, then ``invalid``, ``warm``, ``accept``, ``reject``,
    ``event`` (the first window of a new segment) or ``change`` (the first window of a provisional
    segment: an unconfirmed change).
    """

    __slots__ = (
        "action",
        "bv",
        "event_end",
        "force",
        "g",
        "g_fit",
        "gvar",
        "i0",
        "k",
        "reason",
        "samples",
        "seg",
        "svar",
        "temp",
        "tvar",
    )

    def __init__(
        self,
        k: int,
        samples: np.ndarray,
        force: np.ndarray,
        temp: np.ndarray,
        reason: str,
        i0: np.ndarray,
        bv: np.ndarray,
        svar: float = 0.0,
        tvar: float = 0.0,
    ) -> None:
        self.k = k
        self.samples = samples
        self.force = force
        self.temp = temp
        self.reason = reason
        self.i0 = i0
        self.bv = bv
        self.svar = svar  # variance of the sun covariate (the sun term's; 0 without it)
        self.tvar = tvar  # variance of a stale window's air temperature, K^2 (0 when fresh)
        self.action: str | None = "invalid" if reason else None
        self.event_end = False  # the last window of an event's confirmation run
        self.g = (0.0, 0.0)  # the centred curve at this window's temperature, N
        self.gvar = (0.0, 0.0, 0.0)  # the curve's own covariance there (a, b, d), N^2
        self.g_fit = -1  # the fit that ``g`` comes from
        self.seg = -1  # the segment of a warm-up window (set on arrival; -1 otherwise)
