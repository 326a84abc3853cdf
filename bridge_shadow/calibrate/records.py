"""Read one record (a bag, or munich-bridge-data CSV/zip files) as ``MonitoringData`` (no ROS import).

A record is a list of paths: one rosbag2 directory (or ``.db3``/``.mcap`` file), or force and
temperature CSVs / zips of them (``bridge-shadow import-csv`` format). Relative paths resolve
against the calibration file's directory first, then the shared data directory
(``bridge_shadow.paths.shared_data_dir``, ``../shared/data/munich-bridge-data``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.contract import FORCE_TOPICS
from bridge_shadow.paths import data_candidates
from bridge_shadow.series import MonitoringData

__all__ = ["load_record", "resolve_path"]


def resolve_path(path: str | Path, base: Path | None = None) -> Path:
    """Absolute path of ``path``: as is, else under ``base``, else under the shared data directory."""
    candidates = data_candidates(Path(path).expanduser(), base)
    for c in candidates:
        if c.exists():
            return c.resolve()
    tried = ", ".join(str(c) for c in candidates)
    raise CalibrationError(f"record {path}: not found (tried {tried})")


def _is_bag(path: Path) -> bool:
    return path.is_dir() or path.suffix in (".db3", ".mcap")


def load_record(
    paths: Sequence[str | Path], base: Path | None = None, *, dated: bool = True
) -> MonitoringData:
    """Read a record given as one bag or as CSV/zip files (forces and, optionally, temperature).

    ``dated``: the record's calendar date matters (a pair's records: the time between them); a
    force file whose month and day could be swapped, with nothing to settle it, is then refused
    (``import_csv``). False reads it as written (a reference record: only its levels enter).
    """
    files = [resolve_path(p, base) for p in paths]
    if not files:
        raise CalibrationError("a record needs at least one file or bag")
    bags = [f for f in files if _is_bag(f)]
    if bags:
        if len(files) != 1:
            raise CalibrationError(
                f"a record is one bag or a list of CSV/zip files, got {len(files)} paths with a bag"
            )
        from bridge_shadow.bagio import read_monitoring

        return read_monitoring(bags[0], required=list(FORCE_TOPICS.values()))
    from bridge_shadow.errors import InputError
    from bridge_shadow.importers import import_csv

    try:
        data, _ = import_csv(list(files), ambiguous="refuse" if dated else "as_written")
    except InputError as err:
        hint = "convert the record with `bridge-shadow import-csv --date ...` and list the bag instead"
        raise CalibrationError(f"{err}; {hint}") from None
    return data
