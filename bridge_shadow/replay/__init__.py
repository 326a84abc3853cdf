"""Offline replay in bounded memory: bag pieces -> ``Shadow`` -> window outputs, chunk by chunk.

``replay_bag`` is what ``bridge-shadow replay BAG`` does without ``--live``. It reads the bag as
``MonitoringData`` pieces in arrival order (``bagio.stream``), re-cuts them into chunks of
exactly ``chunk`` messages, and feeds each chunk through the shadow's public methods the way
``Shadow.run`` feeds in-memory data: per chunk ``ingest_forces`` (frc_01, then frc_02),
``ingest_temperature``, then ``poll``; ``flush`` at the end. With the same ``chunk`` the calls,
and so the results, are those of ``Shadow.run(read_monitoring(bag), chunk)``.

Nothing grows with the bag's length: one read piece and one chunk are held at a time, window
outputs go to the ``--out`` bag as they close (``OutputBag``), and what ``--plots`` draws is kept
decimated (``WindowHistory``: at most ``capacity`` windows, evenly spaced). The shadow keeps its
own state bounded (its refilter log is capped).
"""

from __future__ import annotations

from bridge_shadow.replay.bag import replay_bag
from bridge_shadow.replay.chunks import DEFAULT_CHUNK, FeedChunk, arrival_chunks
from bridge_shadow.replay.feed import StreamReplay, feed_shadow
from bridge_shadow.replay.outputs import HISTORY_CAPACITY, OutputBag, WindowHistory
from bridge_shadow.replay.prefetch import Prefetch

__all__ = [
    "DEFAULT_CHUNK",
    "HISTORY_CAPACITY",
    "FeedChunk",
    "OutputBag",
    "Prefetch",
    "StreamReplay",
    "WindowHistory",
    "arrival_chunks",
    "feed_shadow",
    "replay_bag",
]
