"""A day of records: telling one from a stream with outages, and reading its levels (``gap.levels``).

On a day of records (a load-test day: short records hours apart) the records' levels are read pair
by pair across the gaps and the imposed steps (``read_levels``); what the diagnosis then fits is
the variation inside the records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from bridge_shadow.gap.drivers import Drivers
from bridge_shadow.gap.fit import folds_of
from bridge_shadow.gap.records import OneChannel, Record
from bridge_shadow.model.surrogate_file import Surrogate
from bridge_shadow.series import MonitoringData

if TYPE_CHECKING:  # pragma: no cover - the level analysis is imported when a day of records needs it
    from bridge_shadow.gap.levels import ImposedAnalysis, LevelPair

__all__ = ["RECORD_COVERAGE", "DayLevels", "is_day_of_records", "read_levels", "sweeps_of"]

#: Share of the span from the first to the last record below which the windows with data make a
#: day of records (a load-test day: 12-minute records hours apart, 0.12 of the span on 2022-04-11,
#: 0.46 for its first two records alone) rather than a stream with outages (mostly data).
RECORD_COVERAGE = 0.5


@dataclass
class DayLevels:
    """The level analysis of a day of records (``gap.levels``).

    Attributes:
        records: the records. pairs: the level changes across the gaps and imposed steps.
        notes: pairs that could not be measured. imposed: what explains the imposed steps (None
        without one). steps: the free steps between records. model: the model after the imposed
        analysis (the model in use unless an effect was named there).

    """

    records: list[Record]
    pairs: list[LevelPair]
    notes: list[str]
    imposed: ImposedAnalysis | None
    steps: list[dict[str, Any]]
    model: Surrogate
    blind: list[OneChannel] = field(default_factory=list)

    def warnings(self) -> list[str]:
        """Return what must not pass silently: records with a silent channel, imposed steps unused."""
        from bridge_shadow.gap.levels import IMPOSED_UNUSED
        from bridge_shadow.timefmt import iso_utc

        out = [
            f"the record from {iso_utc(b.start_ns)} to {iso_utc(b.end_ns)} has {b.silent} silent: "
            "left out of the level analysis, and the change across it is not measured"
            for b in self.blind
        ]
        out += [f"imposed step not used: {note}" for note in self.notes if IMPOSED_UNUSED in note]
        return out

    def to_dict(self) -> dict[str, Any]:
        """Return the ``levels`` block of the JSON (SI)."""
        return {
            "records": [
                {
                    "index": r.index,
                    "start_ns": r.start_ns,
                    "end_ns": r.end_ns,
                    "windows": r.last - r.first + 1,
                }
                for r in self.records
            ],
            "pairs": [p.to_dict() for p in self.pairs],
            "not_measured": self.notes,
            "records_one_channel": [
                {"start_ns": b.start_ns, "end_ns": b.end_ns, "silent": b.silent} for b in self.blind
            ],
            "imposed": self.imposed.to_dict() if self.imposed is not None else None,
            "steps_between_records": self.steps,
            "model_after": {"A": self.model.A.tolist(), "u0": self.model.u0.tolist()},
        }


def is_day_of_records(
    d: Drivers, valid: np.ndarray, records: list[Record], holdout_days: Sequence[int] | None
) -> bool:
    """Tell a day of records: under two days with data, two or more records, mostly gaps.

    A stream with an outage is mostly data; a day of records is mostly gaps (RECORD_COVERAGE).
    """
    if holdout_days or len(records) < 2:
        return False
    span = records[-1].last - records[0].first + 1
    covered = sum(r.last - r.first + 1 for r in records)
    return folds_of(d.day, valid)[1] != "day" and covered < RECORD_COVERAGE * span


def sweeps_of(s: Surrogate, surrogate_path: str | None) -> dict[str, Any]:
    """Return the parameter sweeps of the model in use (its file's ``sweeps`` block, or none)."""
    from bridge_shadow.model.sweeps import read_sweeps

    block = getattr(s, "sweeps", None)
    return read_sweeps(block=block) if isinstance(block, dict) else read_sweeps(surrogate_path)


def read_levels(
    data: MonitoringData,
    records: list[Record],
    imposed: Sequence[tuple[int, float, float]],
    imposed_sd_m: float,
    s: Surrogate,
    sens: dict[str, Any],
    surrogate_path: str | None,
    baseline_change: str = "uncertainty",
    blind: Sequence[OneChannel] = (),
) -> DayLevels:
    """Read the levels of a day of records: the imposed steps' explanation, the free steps.

    ``baseline_change``: the baseline's change between the records (``calibrate.change``); with
    ``sun`` the model in use's ``thermal.vertical_gradient`` reads the sun's part.
    """
    from bridge_shadow.calibrate.change import SunBaseline
    from bridge_shadow.gap.levels import explain_imposed, free_steps, level_pairs

    sun = SunBaseline.of(s, "the model in use") if baseline_change == "sun" else None
    pairs, notes = level_pairs(data, records, imposed, imposed_sd_m, baseline_change, sun, blind)
    analysis = None
    model = s
    if any(p.imposed for p in pairs):
        analysis = explain_imposed(pairs, s, sweeps_of(s, surrogate_path), sens)
        if analysis.named:
            model = analysis.surrogate_after(s)
        else:  # none named: all of them, by probability (a misfit is said, as for a named one)
            model = analysis.surrogate_average(s)
    return DayLevels(records, pairs, notes, analysis, free_steps(pairs, model), model, list(blind))
