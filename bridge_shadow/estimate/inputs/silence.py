"""Stretches of windows in which one force channel delivered nothing usable while the other did.

A window without one of the two channels cannot be used (``missing_topic``), and the estimate
stays where it was. When that lasts, something happened that the user must hear about: a load cell
that died or was unplugged, or one whose every reading was rejected (a reading at or below zero
is a bearing that lifted off its support). The per-topic ledger only speaks when *every* message
of a topic was rejected; a channel that worked for the first record and then fell silent (or out
of range) for the next one passed with a count among the rejected windows, while the estimate
kept the old state with its old, narrow interval (found with the 2022-04-11 records: the 10 mm
record copied an hour on with the north bearing 10 mm lower and the south one 10 mm higher
reads below zero on the north cell; no event, no warning, the truth 20 mm outside the interval).

``ChannelSilence`` follows the windows in order and keeps, per channel, the stretches of
consecutive windows in which that channel had no accepted sample while the other had some.
``MIN_SILENT_WINDOWS`` = 2: one such window happens at a record's edge when the two channels'
first (or last) stamps straddle a window boundary; two in a row cannot come from an offset
shorter than a window. Its state is plain data (checkpoints), and it sees the windows the
sequential part sees, so an archive's parallel reduction reports what one replay reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MIN_SILENT_WINDOWS", "ChannelSilence"]

#: Consecutive windows without a channel (the other one delivering) that make a stretch worth a
#: warning; see the module docstring.
MIN_SILENT_WINDOWS = 2


@dataclass
class ChannelSilence:
    """Per force channel, the stretches ``[first_k, last_k]`` of windows it was silent in alone.

    Attributes:
        runs: per channel, every stretch so far as ``[first_k, last_k]`` (the last one grows while
            the channel stays silent in the windows right after it).

    """

    runs: list[list[list[int]]] = field(default_factory=lambda: [[], []])

    def note(self, k: int, samples: np.ndarray) -> None:
        """Follow window ``k`` with its accepted ``samples`` per channel (windows in order)."""
        for c in (0, 1):
            if not (samples[c] == 0 and samples[1 - c] > 0):
                continue  # the channel delivered (or neither did): no stretch of it here
            runs = self.runs[c]
            if runs and runs[-1][1] == k - 1:
                runs[-1][1] = k
                continue
            if runs and runs[-1][1] - runs[-1][0] + 1 < MIN_SILENT_WINDOWS:
                runs.pop()  # a window at a record's edge: not a stretch
            runs.append([k, k])

    def stretches(self, c: int) -> list[tuple[int, int]]:
        """Return channel ``c``'s stretches of at least ``MIN_SILENT_WINDOWS`` windows (first, last k)."""
        return [(a, b) for a, b in self.runs[c] if b - a + 1 >= MIN_SILENT_WINDOWS]

    def state_dict(self) -> dict[str, object]:
        """Plain-data state (checkpoints)."""
        return {"runs": [[list(r) for r in rs] for rs in self.runs]}

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Restore ``state_dict`` output."""
        self.runs = [[[int(a), int(b)] for a, b in rs] for rs in state["runs"]]  # type: ignore[union-attr]
