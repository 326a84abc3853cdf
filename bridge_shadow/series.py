"""In-memory monitoring data: the contract topics as numpy arrays (no ROS import).

Bag readers (``bagio``), the CSV importer and the truth twin all produce ``MonitoringData``;
bag writers and the shadow pipeline consume it. Stamps are ``header.stamp`` in integer
nanoseconds since the Unix epoch (UTC); ``log_ns`` is the bag's receive time (equal to the stamp
unless a source says otherwise).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from bridge_shadow.contract import CHANNELS, FORCE_FRAMES, TEMPERATURE_FRAME

__all__ = ["ForceSeries", "MonitoringData", "TemperatureSeries", "frame_ids"]


def frame_ids(frame_id: np.ndarray | str, n: int) -> np.ndarray:
    """(n,) object array of frame ids: ``frame_id`` as given, or one str repeated ``n`` times.

    A repeated id is one str object referenced ``n`` times (``fill``): ``np.full`` with a str
    converts it to a unicode array first and makes a new str per element, about 30 times slower
    on a day of samples.
    """
    if isinstance(frame_id, str):
        out = np.empty(n, dtype=object)
        out.fill(frame_id)
        return out
    return np.asarray(frame_id, dtype=object)


@dataclass
class ForceSeries:
    """One load-cell channel.

    Attributes:
        stamp_ns: (n,) int64, header stamp, ns since epoch (UTC).
        force_n: (n,) float64, ``wrench.force.z`` in N, compression positive (may hold NaN).
        frame_id: (n,) object array of str, ``header.frame_id`` per message.
        log_ns: (n,) int64, bag log time (defaults to ``stamp_ns``).

    """

    stamp_ns: np.ndarray
    force_n: np.ndarray
    frame_id: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=object))
    log_ns: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.stamp_ns = np.asarray(self.stamp_ns, dtype=np.int64)
        self.force_n = np.asarray(self.force_n, dtype=np.float64)
        if len(self.frame_id) != len(self.stamp_ns):
            self.frame_id = frame_ids("", len(self.stamp_ns)) if not len(self.frame_id) else self.frame_id
        self.frame_id = frame_ids(self.frame_id, len(self.stamp_ns))
        self.log_ns = self.stamp_ns.copy() if self.log_ns is None else np.asarray(self.log_ns, np.int64)
        if not (len(self.stamp_ns) == len(self.force_n) == len(self.frame_id) == len(self.log_ns)):
            raise ValueError("ForceSeries arrays must have equal length")

    def __len__(self) -> int:
        return len(self.stamp_ns)


@dataclass
class TemperatureSeries:
    """Air temperature at the bridge.

    Attributes:
        stamp_ns: (n,) int64, header stamp, ns since epoch (UTC).
        temp_c: (n,) float64, ``temperature`` in C (may hold NaN).
        variance: (n,) float64, C^2, 0 if unknown.
        frame_id: (n,) object array of str.
        log_ns: (n,) int64, bag log time (defaults to ``stamp_ns``).

    """

    stamp_ns: np.ndarray
    temp_c: np.ndarray
    variance: np.ndarray | None = None
    frame_id: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=object))
    log_ns: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.stamp_ns = np.asarray(self.stamp_ns, dtype=np.int64)
        self.temp_c = np.asarray(self.temp_c, dtype=np.float64)
        n = len(self.stamp_ns)
        self.variance = np.zeros(n) if self.variance is None else np.asarray(self.variance, float)
        self.frame_id = frame_ids(TEMPERATURE_FRAME if not len(self.frame_id) else self.frame_id, n)
        self.log_ns = self.stamp_ns.copy() if self.log_ns is None else np.asarray(self.log_ns, np.int64)
        if not (n == len(self.temp_c) == len(self.variance) == len(self.frame_id) == len(self.log_ns)):
            raise ValueError("TemperatureSeries arrays must have equal length")

    def __len__(self) -> int:
        return len(self.stamp_ns)

    def take(self, index: np.ndarray) -> TemperatureSeries:
        """Return the messages at ``index`` (a boolean mask, or positions in the order wanted)."""
        v, lg = self.variance[index], self.log_ns[index]  # type: ignore[index]  # set by __post_init__
        return TemperatureSeries(self.stamp_ns[index], self.temp_c[index], v, self.frame_id[index], lg)

    @staticmethod
    def concat(parts: Sequence[TemperatureSeries]) -> TemperatureSeries:
        """Return the messages of ``parts``, one part after the other."""
        if len(parts) == 1:
            return parts[0]
        cols = [np.concatenate([getattr(p, f) for p in parts]) for f in ("stamp_ns", "temp_c", "variance")]
        frames = np.concatenate([np.asarray(p.frame_id, dtype=object) for p in parts])
        return TemperatureSeries(*cols, frames, np.concatenate([p.log_ns for p in parts]))  # type: ignore[misc]


@dataclass
class MonitoringData:
    """The three input topics of the contract.

    Attributes:
        forces: ``{"frc_01": ForceSeries, "frc_02": ForceSeries}`` (south, north).
        temperature: the air temperature series.

    """

    forces: dict[str, ForceSeries]
    temperature: TemperatureSeries

    def __post_init__(self) -> None:
        missing = [ch for ch in CHANNELS if ch not in self.forces]
        if missing:
            raise ValueError(f"MonitoringData lacks force channels {missing}")

    @staticmethod
    def from_arrays(
        stamp_ns: np.ndarray,
        force_n: np.ndarray,
        temp_stamp_ns: np.ndarray,
        temp_c: np.ndarray,
    ) -> MonitoringData:
        """Build from a common force time base ``(n,)``, forces ``(n, 2)`` and a temperature series."""
        force_n = np.asarray(force_n, float)
        forces = {ch: ForceSeries(stamp_ns, force_n[:, i], FORCE_FRAMES[ch]) for i, ch in enumerate(CHANNELS)}
        return MonitoringData(forces, TemperatureSeries(temp_stamp_ns, temp_c))

    def select(self, keep: Callable[[np.ndarray], np.ndarray], by: str = "stamp_ns") -> MonitoringData:
        """Return the messages for which ``keep`` holds (a function of each topic's ``by`` stamps)."""
        forces = {}
        for ch, f in self.forces.items():
            m = keep(getattr(f, by))
            forces[ch] = ForceSeries(f.stamp_ns[m], f.force_n[m], f.frame_id[m], f.log_ns[m])
        t = self.temperature
        return MonitoringData(forces, t.take(keep(getattr(t, by))))

    @property
    def n_messages(self) -> int:
        """Total number of input messages."""
        return sum(len(s) for s in self.forces.values()) + len(self.temperature)

    def time_span_ns(self) -> tuple[int, int]:
        """First and last stamp over all topics (ns); (0, 0) when empty."""
        stamps = [s.stamp_ns for s in self.forces.values()] + [self.temperature.stamp_ns]
        stamps = [s for s in stamps if len(s)]
        if not stamps:
            return (0, 0)
        return (int(min(s.min() for s in stamps)), int(max(s.max() for s in stamps)))
