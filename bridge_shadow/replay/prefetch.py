"""Read ahead in a background thread while the main thread works (bounded, errors handed over)."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterable, Iterator
from typing import Any

__all__ = ["Prefetch"]


class Prefetch:
    """Iterate ``items`` in a background thread, at most ``depth`` items ahead (a context manager).

    Reading and decoding a slice spends most of its time in SQLite, zstd and numpy, which release
    the GIL, so a reader thread overlaps them with the shadow's work in the main thread. Memory
    stays bounded: ``depth`` items wait at most. An exception of the reader is raised in the
    consumer; leaving the block stops the reader and waits for it.

    Attributes:
        busy_s: wall seconds the reader spent producing items.

    """

    _END = object()

    def __init__(self, items: Iterable[Any], depth: int = 2) -> None:
        self._items = items
        self._queue: queue.Queue[tuple[Any, BaseException | None]] = queue.Queue(maxsize=max(int(depth), 1))
        self._stop = threading.Event()
        self.busy_s = 0.0
        self._thread = threading.Thread(target=self._work, name="bridge_shadow-reader", daemon=True)

    def _put(self, item: Any, err: BaseException | None = None) -> bool:
        while not self._stop.is_set():
            try:
                self._queue.put((item, err), timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _work(self) -> None:
        it = iter(self._items)
        try:
            while True:
                t0 = time.perf_counter()
                item = next(it, self._END)
                self.busy_s += time.perf_counter() - t0
                if not self._put(item) or item is self._END:
                    return
        except BaseException as err:  # handed to the consumer, raised there
            self._put(None, err)

    def __enter__(self) -> Prefetch:
        self._thread.start()
        return self

    def __iter__(self) -> Iterator[Any]:
        while True:
            item, err = self._queue.get()
            if err is not None:
                raise err
            if item is self._END:
                return
            yield item

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
