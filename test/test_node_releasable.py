"""``ShadowNode._releasable`` (how many pending messages of a topic are in step) equals its definition.

The definition (the code before the shortcut, kept here): the messages before the first one ahead
of the horizon (the newest stamp of every other topic still delivering), or more where messages
have waited ``REORDER_HOLD_S``; while a topic has delivered nothing and the node started less
than that ago, only the aged ones. A stamp more than ``clock_jump_s`` past the horizon is not
ahead (a clock glitch, for the gate: held, it held its topic back while the others closed its
windows). The node returns all of them at once when every pending stamp is within the horizon;
on random pending states, some with such a stamp, both give the same count.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from bridge_shadow.ros.node import REORDER_HOLD_S, ShadowNode


def _definition(node: SimpleNamespace, i: int, now: float) -> int:
    stamp, _, _, t_dec = node._pending[i]
    n_aged = int(np.searchsorted(t_dec, now - REORDER_HOLD_S, side="right"))
    horizon = None
    for j in range(3):
        if j == i:
            continue
        if node._latest[j] is None:
            if now - node._started < REORDER_HOLD_S:
                return n_aged
            continue
        if now - node._arrival[j] < REORDER_HOLD_S:
            horizon = node._latest[j] if horizon is None else min(horizon, node._latest[j])
    if horizon is None:
        return len(stamp)
    jump = round(node.config.clock_jump_s * 1e9)
    ahead = np.flatnonzero((stamp > horizon) & (stamp <= horizon + jump))
    n_horizon = int(ahead[0]) if len(ahead) else len(stamp)
    return max(n_horizon, n_aged)


def test_the_in_step_count_is_its_definition() -> None:
    rng = np.random.default_rng(0)
    hold = REORDER_HOLD_S
    kinds = {"all": 0, "some": 0}
    for _ in range(3000):
        now = 100.0
        n = int(rng.integers(1, 40))
        base = 10**18
        stamp = base + np.cumsum(rng.integers(1, 3, n)) * 10**6
        if rng.random() < 0.2:  # arrival order is not stamp order everywhere
            stamp = rng.permutation(stamp)
        if rng.random() < 0.2:  # a clock glitch: a stamp two hours ahead
            stamp[int(rng.integers(0, n))] += 7200 * 10**9
        t_dec = np.sort(now - rng.uniform(0.0, 2.5 * hold, n))
        latest = [None if rng.random() < 0.1 else int(base + rng.integers(0, 45) * 10**6) for _ in range(3)]
        node = SimpleNamespace(
            _pending=[None, None, None],
            _latest=latest,
            _arrival=[now - rng.uniform(0.0, 2.0 * hold) for _ in range(3)],
            _started=now - rng.choice([0.5 * hold, 10.0 * hold]),
            config=SimpleNamespace(clock_jump_s=3600.0),
        )
        i = int(rng.integers(0, 3))
        node._pending[i] = (stamp, np.zeros(n), np.full(n, "f", dtype=object), t_dec)
        got = ShadowNode._releasable(node, i, now)  # type: ignore[arg-type]
        assert got == _definition(node, i, now)
        kinds["all" if got == n else "some"] += 1
    assert min(kinds.values()) > 300  # both outcomes drawn often
