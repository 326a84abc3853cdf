"""Simulate and write a twin bag with its ``truth.yaml`` (what ``bridge-shadow synth`` does)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bridge_shadow.bagio import write_monitoring
from bridge_shadow.errors import InputError
from bridge_shadow.twin.simulate import simulate
from bridge_shadow.twin.truth import TRUTH_FILE, truth_text

__all__ = ["write_twin_bag"]


def write_twin_bag(
    out: str | Path,
    *,
    storage: str = "sqlite3",
    overwrite: bool = False,
    compress: bool = False,
    **simulate_kwargs: Any,
) -> tuple[Path, dict[str, Any]]:
    """Run ``simulate(**simulate_kwargs)``, write the bag to ``out`` and ``out/truth.yaml``.

    Returns the bag path and the truth (with its ``series`` arrays).
    """
    if compress and storage != "mcap":
        raise InputError("compression is available for mcap storage only")
    data, truth = simulate(**simulate_kwargs)
    # the truth goes into the bag directory with the bag: both appear together, or neither
    extra = {TRUTH_FILE: truth_text(truth)}
    path = write_monitoring(
        Path(out), data, storage, overwrite=overwrite, compress=compress, extra_files=extra
    )
    return path, truth
