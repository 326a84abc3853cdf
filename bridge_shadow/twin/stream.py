"""Write long twin records in bounded memory: one bag, or an archive of bags per bridge and day.

``simulate`` holds a whole record (about 1 kB per force sample with its truth series: 8.6 GB for
a day at 100 Hz). Here a record is simulated in *segments* of at most ``SEGMENT_SAMPLES`` force
samples (``simulate(span=..., segment=k)``): the weather, the test-car crossings, the reference
temperature and the settlement path are the whole record's, so a segment boundary shows in
nothing but the sensors' random streams (each segment draws its own). Each segment is encoded and
written at once, in log-time order, so memory is one segment's whatever the record's length.

A record that fits one segment is simulated whole, exactly as ``simulate`` does (every bundled
bag does: their commands and bytes are unchanged).

``SEGMENT_SAMPLES`` = 250,000: about 250 MB per segment at 1 kB a sample (2.9 days at 1 Hz,
42 min at 100 Hz), and large enough that every bundled bag (at most 25,920 samples) and every
test record is one segment.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.series import MonitoringData
from bridge_shadow.twin.simulate import DAY_S, simulate

__all__ = [
    "BAGS_PER_CALL",
    "SEGMENT_SAMPLES",
    "merge_truths",
    "record_segments",
    "write_archive",
    "write_stream_bag",
]

SEGMENT_SAMPLES = 250_000


def record_samples(days: float, rate_hz: float) -> int:
    """Force samples per channel of a record (as ``simulate`` counts them)."""
    return int(np.floor(days * DAY_S * rate_hz + 1e-9))


def record_segments(
    days: float,
    rate_hz: float,
    *,
    span: tuple[int, int] | None = None,
    segment_samples: int = SEGMENT_SAMPLES,
    first_segment: int = 0,
    **kwargs: Any,
) -> Iterator[tuple[MonitoringData, dict[str, Any]]]:
    """Yield ``(data, truth)`` of consecutive segments of a record (or of its samples ``span``).

    ``kwargs`` go to ``simulate`` (seed, effects, start, temp_rate_hz, steps, surrogate, ...).
    Segments are numbered from ``first_segment``; the whole record in one segment is ``simulate``.
    """
    n = record_samples(days, rate_hz)
    lo, hi = (0, n) if span is None else span
    if span is None and n <= segment_samples:
        yield simulate(days, rate_hz, **kwargs)
        return
    k = first_segment
    for i0 in range(lo, hi, segment_samples):
        yield simulate(days, rate_hz, span=(i0, min(i0 + segment_samples, hi)), segment=k + 1, **kwargs)
        k += 1


def merge_truths(truths: list[dict[str, Any]]) -> dict[str, Any]:
    """Return one truth for consecutive segments: the first's, with counts added and the path joined."""
    if len(truths) == 1:
        return truths[0]
    out = {k: v for k, v in truths[0].items() if k not in ("series", "segment")}
    counts: dict[str, Any] = {}
    for t in truths:
        for key, value in t["counts"].items():
            if isinstance(value, dict):
                into = counts.setdefault(key, {})
                for ch, v in value.items():
                    into[ch] = into.get(ch, 0) + v
            elif key != "crossings":
                counts[key] = counts.get(key, 0) + value
    counts["crossings"] = truths[0]["counts"]["crossings"]  # drawn once for the whole record
    out["counts"] = counts
    weights = np.array([t["counts"]["force_samples"] for t in truths], float)
    means = np.array([t["settlement"]["mean_m"] for t in truths], float)
    out["settlement"] = {
        "mean_m": (weights @ means / max(weights.sum(), 1.0)).tolist(),
        "start_m": truths[0]["settlement"]["start_m"],
        "end_m": truths[-1]["settlement"]["end_m"],
    }
    out["segments"] = len(truths)
    return out


class _StreamWriter:
    """Append monitoring pieces (each wholly after the one before) to one open bag, in log order."""

    def __init__(self, bag: Any) -> None:
        from bridge_shadow.contract import (
            CHANNELS,
            FORCE_TOPICS,
            FORCE_TYPE,
            TEMPERATURE_TOPIC,
            TEMPERATURE_TYPE,
        )

        self.bag = bag
        self.channels = CHANNELS
        self.topics = [FORCE_TOPICS[ch] for ch in CHANNELS] + [TEMPERATURE_TOPIC]
        types = [FORCE_TYPE] * len(CHANNELS) + [TEMPERATURE_TYPE]
        self.conns = [bag._connection(t, m) for t, m in zip(self.topics, types, strict=True)]
        self.counts = [0] * len(self.topics)

    def write(self, data: MonitoringData) -> None:
        from bridge_shadow.bagio.cdr import encode_stamped_floats

        raws, logs = [], []
        for ch in self.channels:
            f = data.forces[ch]
            values = np.zeros((len(f), 6))
            values[:, 2] = f.force_n
            raws.append(encode_stamped_floats(f.stamp_ns, f.frame_id, values))
            logs.append(f.log_ns)
        t = data.temperature
        raws.append(encode_stamped_floats(t.stamp_ns, t.frame_id, np.column_stack([t.temp_c, t.variance])))
        logs.append(t.log_ns)
        topic = np.concatenate([np.full(len(x), k) for k, x in enumerate(logs)])
        pos = np.concatenate([np.arange(len(x)) for x in logs])
        log = np.concatenate(logs)
        order = np.argsort(log, kind="stable")  # ties: frc_01, frc_02, temperature (write_monitoring's)
        which, at = topic[order], pos[order]
        self.bag.write_merged(
            self.conns,
            which,
            log[order],
            [raws[k][i] for k, i in zip(which.tolist(), at.tolist(), strict=True)],
        )
        for k, x in enumerate(logs):
            self.counts[k] += len(x)

    def close(self) -> None:
        for topic, n in zip(self.topics, self.counts, strict=True):
            self.bag.counts[topic] = n


def write_stream_bag(
    out: str | Path,
    segments: Iterator[tuple[MonitoringData, dict[str, Any]]],
    *,
    storage: str = "sqlite3",
    overwrite: bool = False,
    compress: bool = False,
    truth_file: bool = True,
) -> tuple[Path, dict[str, Any]]:
    """Write segments into one bag (and its ``truth.yaml``); return the path and the merged truth.

    The bag appears complete, with its truth, or not at all (``BagOutputWriter`` stages it).
    """
    from bridge_shadow.bagio import BagOutputWriter
    from bridge_shadow.twin.truth import TRUTH_FILE, truth_text

    path = Path(out)
    truths = []
    with BagOutputWriter(path, storage, overwrite=overwrite, compress=compress) as bag:
        writer = _StreamWriter(bag)
        for data, truth in segments:
            writer.write(data)
            truth.pop("series", None)  # the per-sample truth: not kept
            truths.append(truth)
        writer.close()
        merged = merge_truths(truths)
        if truth_file:
            (bag.staged_path / TRUTH_FILE).write_text(truth_text(merged), encoding="utf-8")
    return path, merged


#: Bags per call of the mapper in ``write_archive``: progress is reported after each call.
BAGS_PER_CALL = 8


def _write_archive_bag(
    job: tuple[Path, tuple[int, int], int, int, str, bool, dict[str, Any]],
) -> dict[str, Any]:
    """Write one bag of an archive (a mapper's task); return its truth (without the series)."""
    bag, span, first, seed, storage, compress, world = job
    kwargs = dict(world)
    days, rate_hz = kwargs.pop("days"), kwargs.pop("rate_hz")
    segs = record_segments(days, rate_hz, span=span, first_segment=first, seed=seed, **kwargs)
    _, truth = write_stream_bag(bag, segs, storage=storage, compress=compress, truth_file=False)
    return truth


def write_archive(
    folder: str | Path,
    *,
    bridges: int,
    days: float,
    rate_hz: float,
    seed: int,
    bag_days: float = 1.0,
    storage: str = "sqlite3",
    compress: bool = False,
    progress: Any = None,
    mapper: Any = None,
    **kwargs: Any,
) -> list[dict[str, Any]]:
    """Write an archive: ``folder/bridge_NN/day_DDDD`` bags of ``bag_days`` each, per bridge a record.

    Bridge ``b`` is the twin record of seed ``seed + b`` (its own weather, sensors and crossings;
    the same effects and steps), cut at every ``bag_days`` into bags; its truth (the whole
    record's) goes to ``folder/bridge_NN/truth.yaml``, for scoring only. Every bag is written on
    its own (its samples' span of the record), so ``mapper`` (``engine.client_mapper``: Dask
    workers; default: one after the other here) writes them in parallel, ``BAGS_PER_CALL`` at a
    time; the bytes do not depend on it. ``progress`` is called with the fraction of bags written.
    Returns one summary per bridge.
    """
    from bridge_shadow.fileio import atomic_write_text
    from bridge_shadow.twin.truth import truth_text

    mapper = mapper or (lambda fn, items: [fn(x) for x in items])
    root = Path(folder)
    n = record_samples(days, rate_hz)
    per_bag = max(record_samples(bag_days, rate_hz), 1)
    n_bags = -(-n // per_bag)
    jobs = []
    for b in range(bridges):
        for d in range(n_bags):
            span = (d * per_bag, min((d + 1) * per_bag, n))
            first = d * (-(-per_bag // SEGMENT_SAMPLES))
            world = {**kwargs, "days": days, "rate_hz": rate_hz}
            jobs.append(
                (root / f"bridge_{b:02d}" / f"day_{d:04d}", span, first, seed + b, storage, compress, world)
            )
    truths: list[dict[str, Any]] = []
    for i in range(0, len(jobs), BAGS_PER_CALL):
        truths += mapper(_write_archive_bag, jobs[i : i + BAGS_PER_CALL])
        if progress is not None:
            progress(len(truths) / len(jobs))
    out = []
    for b in range(bridges):
        bridge = root / f"bridge_{b:02d}"
        merged = merge_truths(truths[b * n_bags : (b + 1) * n_bags])
        atomic_write_text(bridge / "truth.yaml", truth_text(merged), "truth file")
        out.append({"bridge": bridge.name, "bags": n_bags, "seed": seed + b, "counts": merged["counts"]})
    return out
