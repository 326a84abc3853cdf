"""The reduction cache: a bag reduced once is not read again, under the same front-end parameters.

An entry is keyed by the bag's *content* (``bag_digest``: BLAKE2b over its ``metadata.yaml``
and storage files, never over other files beside them) and by the parameters that shape the
reduction (``front_key``: every shadow parameter except those that act only after the windows
are closed, ``ESTIMATOR_ONLY``, plus ``REDUCTION_VERSION``). So a new surrogate or a new event
threshold reuses every cached bag, and only the sequential part runs again; a changed window
length, gate or topic name reduces every bag anew. A renamed or moved bag is found by content.

Hashing a bag reads it whole, which costs a fraction of reducing it; a stat record per bag path
(size and modification time of each file) keeps a rerun from hashing an unchanged bag again.

Entries are pickles written atomically (``fileio.atomic_write``): an interrupted run leaves
whole entries or none. They are the archive's own intermediate files, read only by this module;
the cache folder must be reachable at the same path by every worker of a cluster.
"""

from __future__ import annotations

import hashlib
import json
import pickle
from pathlib import Path
from typing import Any

from bridge_shadow.bagio.identity import bag_files, stat_signature
from bridge_shadow.fileio import atomic_write

__all__ = ["ESTIMATOR_ONLY", "REDUCTION_VERSION", "ReductionCache", "bag_digest", "front_key"]

#: Bumped whenever ``archive.reduce`` or the front end (gate, window buffer) changes what a
#: reduction holds or means: older entries are then never read.
REDUCTION_VERSION = 11
#: Shadow parameters that act only after a window is closed (compensation, noise, prior, events,
#: outputs, checkpoint, node): they leave a bag's reduction as it is (test_archive.py
#: changes each one and compares the reductions). Every other parameter is in the key.
ESTIMATOR_ONLY: frozenset[str] = frozenset(
    {
        "smoothing",
        "spline_lambda",
        "spline_t_min_c",
        "spline_t_max_c",
        "spline_segments",
        "thermal_prior_sd_n_per_k",
        "sun_gradient",
        "sun_gradient_prior_mean_k",
        "sun_gradient_prior_sd_k",
        "sun_gradient_min_bayes_factor",
        "sun_gradient_fit",
        "relaxation_phi0",
        "relaxation_horizon_s",
        "warmup_windows",
        "refit_windows",
        "lambda_reselect_growth",
        "prior_sigma_m",
        "prior_rule",
        "process_noise_m2_per_s",
        "drift_block_s",
        "noise_sigma_n",
        "systematic_sigma_n",
        "noise_mode",
        "noise_phi_max",
        "noise_floor",
        "event_detection",
        "event_trigger_probability",
        "event_probability",
        "event_confirm_windows",
        "event_max_pending",
        "event_jump_rule",
        "mahalanobis_probability",
        "checkpoint_path",
        "checkpoint_period_s",
        "checkpoint_unusable",
        "surrogate_path",
        "qos_depth",
        "diagnostics_period_s",
        "topic_mean",
        "topic_covariance",
        "topic_compensated_frc_01",
        "topic_compensated_frc_02",
    }
)
_CHUNK = 1 << 22  # bytes read at a time while hashing (4 MiB)


def front_key(config: Any, continuing: bool = False) -> str:
    """Return the hex key of the parameters that shape a reduction (``ShadowConfig``, ``continuing``)."""
    params = {k: v for k, v in config.to_params().items() if k not in ESTIMATOR_ONLY}
    text = json.dumps(
        {"version": REDUCTION_VERSION, "params": params, "continuing": bool(continuing)}, sort_keys=True
    )
    return hashlib.blake2b(text.encode(), digest_size=16).hexdigest()


def bag_digest(bag: Path) -> str:
    """Return the BLAKE2b hex digest of a bag's content (file names and bytes, sorted by name)."""
    h = hashlib.blake2b(digest_size=20)
    for p in bag_files(bag):
        h.update(p.name.encode() + b"\0")
        with p.open("rb") as f:
            while block := f.read(_CHUNK):
                h.update(block)
        h.update(b"\0")
    return h.hexdigest()


class ReductionCache:
    """Reductions on disk under ``root``: ``<digest>-<front key>.pkl``, and stat records under ``stat/``."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)

    def digest(self, bag: Path) -> str:
        """Return the bag's content digest, hashing it only when its files changed since the last time."""
        files = bag_files(bag)
        sig = stat_signature(files)
        record = (
            self.root
            / "stat"
            / (hashlib.blake2b(str(bag.resolve()).encode(), digest_size=16).hexdigest() + ".json")
        )
        try:
            saved = json.loads(record.read_text(encoding="utf-8"))
            if saved.get("files") == sig and isinstance(saved.get("digest"), str):
                return saved["digest"]
        except (OSError, ValueError):
            pass
        digest = bag_digest(bag)
        with atomic_write(record, "archive cache stat record") as tmp:
            tmp.write_text(
                json.dumps({"bag": str(bag.resolve()), "files": sig, "digest": digest}), encoding="utf-8"
            )
        return digest

    def path(self, digest: str, key: str) -> Path:
        """Return where the reduction of a bag with ``digest`` under ``key`` lives."""
        return self.root / f"{digest}-{key}.pkl"

    def load(self, path: Path) -> Any:
        """Return a cached reduction (None when absent or unreadable: then it is made again)."""
        try:
            with path.open("rb") as f:
                return pickle.load(f)
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError, ValueError):
            return None

    def store(self, path: Path, reduction: Any) -> None:
        """Write a reduction atomically."""
        with atomic_write(path, "archive cache entry") as tmp, tmp.open("wb") as f:
            pickle.dump(reduction, f, protocol=pickle.HIGHEST_PROTOCOL)
