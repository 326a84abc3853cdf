"""The front end of a ``Shadow`` as plain data: its gates and window buffer, and its bookkeeping.

The front end is what turns messages into closed windows: one ``TopicGate`` per input topic and
the ``WindowBuffer`` (``estimate.inputs.gate``, ``estimate.inputs.windows``). Its *behaviour* on
later messages is a function of the gates' and the buffer's state alone (stamps, values and flags, never a
computed float), so two shadows whose front ends hold equal states close equal windows from
equal messages. The *bookkeeping* (rejections by reason, accepted messages per topic, the
per-topic ledgers) only adds up what the gates decided.

``FrontState`` is both: ``behaviour`` is compared exactly (``same_behaviour``), the bookkeeping
is carried over as a difference (``add_bookkeeping``). A parallel reduction of one bag records
it; the sequential join compares and loads it (``bridge_shadow.archive.join``).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["FrontState", "add_bookkeeping", "front_state", "load_behaviour", "same_behaviour"]


@dataclass
class FrontState:
    """A snapshot of a shadow's front end.

    Attributes:
        gates: per input topic (frc_01, frc_02, air temperature), ``TopicGate.state_dict()``.
        buffer: ``WindowBuffer.state_dict()`` (buffered samples of open windows, the temperature
            readings kept as brackets, the next window to close).
        counts: rejections by reason so far (message-level reasons and ``late``).
        used: accepted messages per topic key.
        ledgers: per topic, ``TopicLedger.state_dict()``.

    """

    gates: list[dict[str, Any]]
    buffer: dict[str, Any]
    counts: dict[str, int]
    used: dict[str, int]
    ledgers: list[dict[str, Any]]

    @property
    def never_accepted(self) -> bool:
        """Whether no gate has ever accepted a message (a fresh front end)."""
        return not any(bool(g["has_last"]) for g in self.gates)


def front_state(shadow: Any) -> FrontState:
    """Return a copy of the front end of ``shadow`` (an ``estimate.Shadow``)."""
    return FrontState(
        [g.state_dict() for g in shadow.gates],
        shadow.buffer.state_dict(),
        {k: int(v) for k, v in shadow.counts.items() if v},
        {k: int(v) for k, v in shadow.used.items()},
        [led.state_dict() for led in shadow.ledgers],
    )


def _equal(a: Any, b: Any) -> bool:
    """Exact equality of nested plain data (arrays element by element, dtypes of a kind)."""
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return isinstance(b, (list, tuple)) and len(a) == len(b) and all(map(_equal, a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        x, y = np.asarray(a), np.asarray(b)
        # stamps and raw values copied from the same messages: exactly equal or not the same
        return x.shape == y.shape and bool(np.array_equal(x, y, equal_nan=x.dtype.kind == "f"))
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
        return True
    return bool(a == b)


def same_behaviour(a: FrontState, b: FrontState, window_buffer: Any = None) -> bool:
    """Whether two front ends will close the same windows from the same messages (gates, buffer).

    ``window_buffer``: a ``WindowBuffer`` of the front ends' parameters; with it the buffers are
    compared less what no later window reads (``WindowBuffer.behaviour_state``: air readings
    older than the open windows' left bracket, when the first reading came once every open
    window sees it), which a front end forgets only when it closes a window. Without it, the
    whole state less the bookkeeping.
    """
    return _equal(a.gates, b.gates) and _equal(
        _behaviour(a.buffer, a.gates, window_buffer), _behaviour(b.buffer, b.gates, window_buffer)
    )


def _behaviour(
    buffer: dict[str, Any], gates: list[dict[str, Any]], window_buffer: Any = None
) -> dict[str, Any]:
    """Return the buffer's state less its bookkeeping (``released``: records passed unscreened)."""
    if window_buffer is not None:
        # a force gate accepts only stamps after its last accepted one
        floors = [
            int(g["last_ns"]) + 1 if bool(g["has_last"]) else None for g in gates[: len(window_buffer.force)]
        ]
        return window_buffer.behaviour_state(buffer, floors)
    return {k: v for k, v in buffer.items() if k != "released"}


def load_behaviour(shadow: Any, state: FrontState) -> None:
    """Set the gates and the window buffer of ``shadow`` to ``state`` (bookkeeping untouched)."""
    for gate, s in zip(shadow.gates, state.gates, strict=True):
        gate.load_state_dict(s)
    released = shadow.buffer.released  # bookkeeping: the shadow's own
    shadow.buffer.load_state_dict(state.buffer)
    shadow.buffer.released = released


def add_bookkeeping(shadow: Any, end: FrontState, start: FrontState) -> None:
    """Add to ``shadow`` what the gates decided between two snapshots of another front end.

    Rejections and accepted messages add up; a ledger's last wrong frame id or out-of-range value
    (what a warning quotes) is the later one when ``end`` saw a new one.
    """
    shadow.counts.update(Counter({k: v - start.counts.get(k, 0) for k, v in end.counts.items()}))
    before = len(start.buffer.get("released", []))
    shadow.buffer.released.extend([int(a), int(b)] for a, b in end.buffer.get("released", [])[before:])
    for key, n in end.used.items():
        shadow.used[key] += n - start.used.get(key, 0)
    for ledger, e, s in zip(shadow.ledgers, end.ledgers, start.ledgers, strict=True):
        ledger.used += int(e["used"]) - int(s["used"])
        before, after = _rejected(s), _rejected(e)
        for reason, n in after.items():
            if n - before.get(reason, 0):
                ledger.rejected[reason] += n - before.get(reason, 0)
        frame_e, frame_s = (e["has_frame"], e["last_frame"]), (s["has_frame"], s["last_frame"])
        if bool(e["has_frame"]) and not _equal(frame_e, frame_s):
            ledger.last_frame = str(e["last_frame"])
        value_e, value_s = float(e["last_value"]), float(s["last_value"])
        if not np.isnan(value_e) and not _equal(value_e, value_s):
            ledger.last_value = value_e
        _add_tail(ledger, e, s)


def _add_tail(ledger: Any, e: dict[str, Any], s: dict[str, Any]) -> None:
    """Carry the run of rejected messages since the last accepted one (``TopicLedger.tail_n``).

    A reduction that accepted a message ends with its own tail; one that accepted none adds its
    rejected messages to the tail before it (the other front end's tail at ``start`` is its own).
    """
    ok_e, ok_s = int(e.get("last_ok_ns", -1)), int(s.get("last_ok_ns", -1))
    n_e, n_s = int(e.get("tail_n", 0)), int(s.get("tail_n", 0))
    first_e, last_e = int(e.get("tail_first_ns", -1)), int(e.get("tail_last_ns", -1))
    if ok_e != ok_s:
        ledger.last_ok_ns, ledger.tail_n = ok_e, n_e
        ledger.tail_first_ns, ledger.tail_last_ns = first_e, last_e
        return
    if n_e <= n_s:
        return
    if not ledger.tail_n:
        ledger.tail_first_ns = first_e
    ledger.tail_n += n_e - n_s
    ledger.tail_last_ns = max(ledger.tail_last_ns, last_e)


def _rejected(ledger_state: dict[str, Any]) -> dict[str, int]:
    import json

    return {k: int(v) for k, v in json.loads(str(ledger_state["rejected"])).items()}
