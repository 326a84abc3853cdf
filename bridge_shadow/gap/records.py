"""Records of a monitoring bag: runs of windows with data separated by gaps (no ROS import).

A load-test day is a few short records hours apart; ``records_of`` finds them on the window grid
of the gap diagnosis. The level analysis of such a day is :mod:`bridge_shadow.gap.levels`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["IMPOSED_SD_M", "RECORD_GAP_WINDOWS", "OneChannel", "Record", "one_channel_records", "records_of"]

NS = 1_000_000_000
#: A gap of more windows than this between two windows with data separates two records (as the
#: gap diagnosis's ``candidates.STEP_GAP_WINDOWS``: 5 minutes of 60 s windows).
RECORD_GAP_WINDOWS = 5
#: The jacks' accuracy per bearing (1 sd, m) when ``--imposed-sd`` is not given: as in
#: config/calibration.yaml, +-1 mm (95 %) on a step set by hand and read off a scale.
IMPOSED_SD_M = 5.0e-4


@dataclass(frozen=True)
class Record:
    """A run of windows with data, separated from the next by a gap.

    Attributes:
        index: position in the day. first, last: window indices (inclusive).
        start_ns, end_ns: the first window's left edge and the last window's right edge (UTC ns).

    """

    index: int
    first: int
    last: int
    start_ns: int
    end_ns: int


def records_of(t_ns: np.ndarray, valid: np.ndarray, width_s: float) -> list[Record]:
    """Split the window grid into records: runs of windows with data on both channels.

    Two windows with data belong to different records when more than ``RECORD_GAP_WINDOWS``
    windows without data lie between them.
    """
    have = np.flatnonzero(np.asarray(valid).all(axis=1))
    if not len(have):
        return []
    cuts = np.flatnonzero(np.diff(have) > RECORD_GAP_WINDOWS + 1)
    starts = np.r_[have[0], have[cuts + 1]]
    ends = np.r_[have[cuts], have[-1]]
    half = round(0.5 * width_s * NS)
    return [
        Record(i, int(a), int(b), int(t_ns[a]) - half, int(t_ns[b]) + half)
        for i, (a, b) in enumerate(zip(starts, ends, strict=True))
    ]


@dataclass(frozen=True)
class OneChannel:
    """A record with one force channel silent: outside every record (``records_of`` needs both).

    Attributes:
        start_ns, end_ns: its first window's left edge and its last window's right edge (UTC ns).
        silent: the channel without data (``frc_01`` or ``frc_02``).

    """

    start_ns: int
    end_ns: int
    silent: str


def one_channel_records(
    t_ns: np.ndarray, valid: np.ndarray, width_s: float, records: list[Record], channels: tuple[str, str]
) -> list[OneChannel]:
    """Find the records that ``records_of`` leaves out because one channel is silent in all of them.

    A level pair across one of them spans a state nobody measured: a settlement there is in the
    pair's change (the day's imposed step read across four hours and two lowerings named a stiffness
    that the calibrated model does not need).
    """
    valid = np.asarray(valid, bool)
    one = valid.any(axis=1) & ~valid.all(axis=1)
    for r in records:
        one[r.first : r.last + 1] = False
    have = np.flatnonzero(one)
    if not len(have):
        return []
    cuts = np.flatnonzero(np.diff(have) > RECORD_GAP_WINDOWS + 1)
    half = round(0.5 * width_s * NS)
    out = []
    for a, b in zip(np.r_[have[0], have[cuts + 1]], np.r_[have[cuts], have[-1]], strict=True):
        heard = valid[a : b + 1].any(axis=0)
        silent = [ch for ch, h in zip(channels, heard, strict=True) if not h]
        out.append(
            OneChannel(
                int(t_ns[a]) - half,
                int(t_ns[b]) + half,
                silent[0] if silent else "both in turn, never together",
            )
        )
    return out
