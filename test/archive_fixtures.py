"""Archives for the tests: one twin record with bad input at its seams, cut into bags.

``seamed_record`` simulates a record with a settlement step and puts bad input where bags meet:
a wrong temperature frame, a NaN force and a duplicate stamp at the first seam; a 3 h outage of
every topic across the second; a wild stamp (25 min ahead) on the last force message before the
third; no air temperature between the third and fourth seams; a force stamp 2 h ahead (a clock
jump that the stream does not confirm) and two swapped stamps after the fourth; the step two
minutes before the fourth seam, so its confirmation runs over it. ``write_archive`` cuts the
record at the seams (log time, mid-window) into bags of both storages, so that the bags
concatenated are the record, and writes the record whole as the serial reference.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bridge_shadow.archive.reduce import split_log
from bridge_shadow.bagio import write_monitoring
from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

DAY_NS = 86_400 * 10**9
HOUR_NS = 3_600 * 10**9


def _keep(data: MonitoringData, drop_force: np.ndarray, drop_temp: np.ndarray) -> MonitoringData:
    forces = {}
    for ch, s in data.forces.items():
        k = ~drop_force(s.log_ns)
        forces[ch] = ForceSeries(s.stamp_ns[k], s.force_n[k], s.frame_id[k], s.log_ns[k])
    t = data.temperature
    k = ~drop_temp(t.log_ns)
    temp = TemperatureSeries(t.stamp_ns[k], t.temp_c[k], t.variance[k], t.frame_id[k], t.log_ns[k])
    return MonitoringData(forces, temp)


def seamed_record(days: float = 2.0, rate_hz: float = 0.1, seed: int = 5) -> tuple[MonitoringData, list[int]]:
    """Return a twin record with bad input at its seams and the seams' log times (ns)."""
    from bridge_shadow.model.surrogate_file import placeholder_surrogate
    from bridge_shadow.twin.simulate import simulate

    step_day = 1.5 - 2.0 / 1440.0
    data, _ = simulate(
        days=days,
        rate_hz=rate_hz,
        seed=seed,
        steps=[(step_day, -1e-3, -1e-3)],
        surrogate=placeholder_surrogate(),
    )
    t0 = int(data.forces["frc_01"].log_ns[0])
    seams = [t0 + int(f * DAY_NS) + 17_300_000_000 for f in (0.4, 0.8, 1.1, 1.5 - 1.0 / 1440.0)]
    s1, s2, s3, s4 = seams
    # 3 h outage across seam 2; no temperature between seams 3 and 4
    data = _keep(
        data,
        lambda log: (log >= s2 - HOUR_NS) & (log < s2 + 2 * HOUR_NS),
        lambda log: ((log >= s2 - HOUR_NS) & (log < s2 + 2 * HOUR_NS)) | ((log >= s3) & (log < s4)),
    )
    f1, f2, t = data.forces["frc_01"], data.forces["frc_02"], data.temperature
    i = int(np.searchsorted(t.log_ns, s1)) - 1
    t.frame_id = t.frame_id.copy()
    t.frame_id[i] = "wrong_frame"  # before seam 1
    j = int(np.searchsorted(f1.log_ns, s1))
    f1.force_n[j] = np.nan  # the first force message after seam 1
    f2.stamp_ns[j + 1] = f2.stamp_ns[j]  # a duplicate stamp
    j = int(np.searchsorted(f1.log_ns, s3)) - 1
    f1.stamp_ns[j] += 25 * 60 * 10**9  # a wild stamp, the last before seam 3
    j = int(np.searchsorted(f2.log_ns, s4))
    f2.stamp_ns[j] += 2 * HOUR_NS  # an unconfirmed clock jump, the first after seam 4
    f1.stamp_ns[[j + 3, j + 4]] = f1.stamp_ns[[j + 4, j + 3]]  # out of order
    return data, seams


def cut(data: MonitoringData, seams: list[int]) -> list[MonitoringData]:
    """Cut a record at log times into consecutive parts."""
    parts = []
    rest = data
    for s in seams:
        part, rest = split_log(rest, s)
        parts.append(part)
    return [*parts, rest]


def write_archive(
    folder: Path, data: MonitoringData, seams: list[int], storages: tuple[str, ...] = ("sqlite3", "mcap")
) -> tuple[list[Path], Path]:
    """Write the parts as bags ``folder/bridge/day_NN`` and the whole record as ``folder/whole``."""
    bags = []
    for n, part in enumerate(cut(data, seams)):
        bags.append(write_monitoring(folder / "bridge" / f"day_{n:02d}", part, storages[n % len(storages)]))
    return bags, write_monitoring(folder / "whole", data)


def corrupt_bag(path: Path) -> Path:
    """Write a directory that looks like a bag and is not (metadata of random bytes)."""
    path.mkdir(parents=True)
    (path / "metadata.yaml").write_bytes(np.random.default_rng(0).bytes(512))
    (path / "broken_0.db3").write_bytes(b"SQLite format 3\x00" + bytes(100))
    return path
