"""Where window outputs go during a streamed replay: the ``--out`` bag and the ``--plots`` history.

Neither holds every window: ``OutputBag`` writes each batch as it closes, ``WindowHistory`` keeps
at most ``capacity`` windows, evenly spaced over the record.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.contract import CHANNELS

__all__ = ["HISTORY_CAPACITY", "OutputBag", "WindowHistory"]

#: Window outputs kept for ``--plots`` (a year of 60 s windows is decimated 64-fold to 8,213).
HISTORY_CAPACITY = 10_000


class WindowHistory:
    """Window outputs for plots, evenly decimated to at most ``capacity``.

    Keeps every ``stride``-th window (``stride`` starts at 1); when more than ``capacity`` are
    kept, every second one is dropped and ``stride`` doubles. So memory is bounded whatever the
    bag's length, and the kept windows stay evenly spaced over the whole record (a year of 60 s
    windows keeps every 64th: one per hour).
    """

    def __init__(self, capacity: int = HISTORY_CAPACITY) -> None:
        self.capacity = max(int(capacity), 2)
        self.stride = 1
        self.seen = 0
        self.kept: list[Any] = []

    def extend(self, outputs: Iterable[Any]) -> None:
        """Offer closed-window outputs in order."""
        for out in outputs:
            if self.seen % self.stride == 0:
                self.kept.append(out)
                if len(self.kept) > self.capacity:
                    self.kept = self.kept[::2]
                    self.stride *= 2
            self.seen += 1


class OutputBag:
    """Write window outputs to a bag as they close: mean, covariance, compensated forces, diagnostics.

    Topic names are the shadow's ``topic_*`` parameters (the contract's by default). ``finish``
    adds the final diagnostics (rejections, spline) at the last window's stamp. A context manager:
    the bag is staged beside ``path`` and moved there when the block ends normally; an error or an
    interruption (Ctrl-C, SIGTERM) removes the unfinished bag and leaves ``path`` as it was.
    ``overwrite`` (``--force``) replaces an existing bag there, once the new one is complete.
    """

    def __init__(
        self, path: str | Path, shadow: Any, *, overwrite: bool = False, storage: str = "sqlite3"
    ) -> None:
        from bridge_shadow.bagio import BagOutputWriter

        self.path = Path(path)
        self.shadow = shadow
        self.names = shadow.config.output_topics()
        self.writer = BagOutputWriter(self.path, storage, overwrite=overwrite)
        self.last_end_ns: int | None = None
        self.last_posterior: tuple[np.ndarray, np.ndarray] | None = None

    def __enter__(self) -> OutputBag:
        self.writer.__enter__()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        if exc_type is None:
            self.writer.close()
        else:
            self.writer.abort()

    def write(self, outputs: Iterable[Any]) -> None:
        """Write the messages of each window output (stamp and log time = window end).

        The float arrays and compensated forces of a batch of windows are serialized at once
        (``float64_array_raws``, ``encode_stamped_floats``); messages are written window by
        window: mean, covariance, compensated frc_01 and frc_02 (when finite), diagnostics.
        """
        from bridge_shadow.bagio.cdr import encode_stamped_floats
        from bridge_shadow.contract import (
            COMPENSATED_TOPICS,
            COVARIANCE_LAYOUT_LABELS,
            COVARIANCE_TOPIC,
            DIAGNOSTICS_TOPIC,
            FLOAT_ARRAY_TYPE,
            FORCE_FRAMES,
            FORCE_TYPE,
            MEAN_LAYOUT_LABEL,
            MEAN_TOPIC,
            NODE_NAME,
        )

        outs = list(outputs)
        if not outs:
            return
        names, writer = self.names, self.writer
        end = np.array([int(o.end_ns) for o in outs], dtype=np.int64)
        means = writer.float64_array_raws(np.array([o.mean_m for o in outs]), [MEAN_LAYOUT_LABEL])
        covs = writer.float64_array_raws(
            np.array([o.covariance_m2 for o in outs]), list(COVARIANCE_LAYOUT_LABELS)
        )
        comp = np.array([o.compensated_n for o in outs], dtype=float).reshape(-1, 2)
        finite = np.flatnonzero(np.all(np.isfinite(comp), axis=1))
        wrench = np.zeros((len(finite), 6))
        forces: list[dict[int, bytes]] = []
        for c, ch in enumerate(CHANNELS):
            wrench[:, 2] = comp[finite, c]
            raws = encode_stamped_floats(end[finite], FORCE_FRAMES[ch], wrench)
            forces.append(dict(zip(finite.tolist(), raws, strict=True)))
        for i, out in enumerate(outs):
            t = int(end[i])
            writer.write_raw(names[MEAN_TOPIC], FLOAT_ARRAY_TYPE, t, means[i])
            writer.write_raw(names[COVARIANCE_TOPIC], FLOAT_ARRAY_TYPE, t, covs[i])
            if i in forces[0]:
                for c, ch in enumerate(CHANNELS):
                    writer.write_raw(names[COMPENSATED_TOPICS[ch]], FORCE_TYPE, t, forces[c][i])
            values = {
                "window_end_ns": t,
                "updated": out.updated,
                "reason": out.reason,
                "mean_m": list(out.mean_m),
                "sigma_m": list(np.sqrt(np.diag(out.covariance_m2))),
                "force_n": list(out.force_n),
                "temp_c": list(out.temp_c),
            }
            status = {
                "name": f"{NODE_NAME}: window",
                "level": 0 if out.updated else 1,
                "message": out.reason or "updated",
                "values": values,
            }
            writer.write_diagnostics(names[DIAGNOSTICS_TOPIC], t, t, [status])
            self.last_end_ns = t
        self.last_posterior = (np.array(outs[-1].mean_m), np.array(outs[-1].covariance_m2))

    def write_final_posterior(self, mean_m: np.ndarray, covariance_m2: np.ndarray) -> bool:
        """Write the end-of-data posterior once more when no window output carried it; return whether.

        ``Shadow.flush`` refits with lambda reselected and puts the result on its last output;
        when every window was decided before (a record followed by air only, its held windows
        decided once the gap was certain), no output carries it, and the bag's last mean and
        covariance were not the replay's answer (the public pair: -9.438 mm published, -9.433 mm
        in the JSON). The node publishes it on its own then (``ShadowNode.close_open_windows``);
        so does the bag, at the last window's stamp, mean and covariance only.
        """
        from bridge_shadow.contract import (
            COVARIANCE_LAYOUT_LABELS,
            COVARIANCE_TOPIC,
            MEAN_LAYOUT_LABEL,
            MEAN_TOPIC,
        )

        last = self.last_posterior
        if self.last_end_ns is None or last is None:
            return False
        if all(np.array_equal(a, b) for a, b in zip((mean_m, covariance_m2), last, strict=True)):
            return False
        t = self.last_end_ns
        self.writer.write_float64_array(self.names[MEAN_TOPIC], t, mean_m, [MEAN_LAYOUT_LABEL])
        self.writer.write_float64_array(
            self.names[COVARIANCE_TOPIC], t, covariance_m2, list(COVARIANCE_LAYOUT_LABELS)
        )
        self.last_posterior = (np.array(mean_m), np.array(covariance_m2))
        return True

    def finish(self) -> Path:
        """Write the final diagnostics (after the last window) and return the bag path."""
        from bridge_shadow.contract import DIAGNOSTICS_TOPIC, NODE_NAME

        if self.last_end_ns is not None:
            diag = self.shadow.diagnostics()
            levels = {"OK": 0, "WARN": 1, "ERROR": 2}
            t = self.last_end_ns
            status = {
                "name": f"{NODE_NAME}: final",
                "level": levels[diag["level"]],
                "message": diag["summary"],
                "values": {"rejected": diag["rejected"], "spline": diag["spline"]},
            }
            self.writer.write_diagnostics(self.names[DIAGNOSTICS_TOPIC], t, t, [status])
        return self.path
