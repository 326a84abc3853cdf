"""The gate's batch of regular messages (``TopicGate._regular``) decides as the general path does.

A live node gates a few dozen messages at a time, nearly all of them regular; ``_regular`` takes
such a batch in a handful of numpy calls, or up to ``REGULAR_FEW`` messages in one pass over Python
numbers (``_regular_few``). The general path is the definition: a stream with every
kind of message the gate knows (NaN, inf, out of range, wrong and empty frame ids, duplicates,
out of order, wild stamps, a clock jump, a gap, value repeats short and long), cut into random
chunks, must be decided the same message by message, with the same counts, the same held and
released messages and the same state, whether regular batches take the short way or not.
"""

from __future__ import annotations

from collections import Counter
from itertools import pairwise

import numpy as np
import pytest

from bridge_shadow.estimate.inputs import gate as gate_module
from bridge_shadow.estimate.inputs.gate import FROZEN_S, TopicGate

NS = 1_000_000_000
STEP = 10_000_000  # 100 Hz


def _stream(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return stamps, values and frame ids of a 100 Hz stream with every irregularity in it."""
    rng = np.random.default_rng(seed)
    n = 6000
    stamps = 1_650_000_000 * NS + np.arange(n, dtype=np.int64) * STEP
    stamps[3000:] += 40 * 60 * NS  # a gap of 40 min (held for one message, then taken)
    stamps[4500:] += 2 * 3600 * NS  # a clock jump beyond clock_jump_s, confirmed by the stream
    values = 2.2e5 + 60.0 * rng.standard_normal(n)
    frames = np.full(n, "frc_01", dtype=object)
    for k in rng.choice(np.arange(10, n - 10), 60, replace=False):
        kind = rng.integers(9)
        if kind == 0:
            values[k] = np.nan
        elif kind == 1:
            values[k] = np.inf
        elif kind == 2:
            values[k] = -5.0  # out of range
        elif kind == 3:
            frames[k] = "frc_02"
        elif kind == 4:
            frames[k] = ""  # unknown: accepted
        elif kind == 5:
            stamps[k] = stamps[k - 1]  # duplicate
        elif kind == 6:
            stamps[k] = stamps[k - 1] - STEP // 2  # out of order
        elif kind == 7:
            stamps[k] += 25 * 60 * NS  # one wild stamp ahead
        else:
            values[k : k + 3] = values[k]  # a short repeat (a logger's sample-and-hold)
    values[1500 : 1500 + 1500] = values[1500]  # a frozen channel for 15 s
    return stamps, values, frames


def _gate() -> TopicGate:
    return TopicGate("frc_01", 1.0, 5e6, 3600 * NS, 3, round(FROZEN_S * NS))


def _run(stamps, values, frames, cuts, regular: bool):
    gate = _gate()
    taken = 0
    if not regular:
        gate._regular = lambda *args: False  # the general path alone
    else:
        original = gate._regular

        def counted(*args):
            nonlocal taken
            took = original(*args)
            taken += took
            return took

        gate._regular = counted
    masks, released, counts = [], [], Counter()
    for a, b in pairwise(cuts):
        # some chunks give one frame id for all (the node's decode of a uniform block)
        uniform = len(set(frames[a:b])) == 1 and a % 2 == 0
        frame = frames[a] if uniform else frames[a:b]
        masks.append(gate(stamps[a:b], values[a:b], frame, (int(stamps[0]), int(stamps[a])), counts))
        released.append(gate.pop_released())
    gate.release_held()
    released.append(gate.pop_released())
    return np.concatenate(masks), released, counts, gate.state_dict(), taken


@pytest.mark.parametrize("few", [0, gate_module.REGULAR_FEW, 10**9], ids=["numpy", "default", "floats"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_regular_batches_decide_as_the_general_path(seed: int, few: int, monkeypatch) -> None:
    """Chunks of 1 to about 60 messages: up to ``REGULAR_FEW`` tested in floats, in numpy beyond."""
    monkeypatch.setattr(gate_module, "REGULAR_FEW", few)
    stamps, values, frames = _stream(seed)
    rng = np.random.default_rng(100 + seed)
    cuts = np.unique(np.concatenate([[0, len(stamps)], rng.integers(1, len(stamps), 400)]))
    fast = _run(stamps, values, frames, cuts, regular=True)
    slow = _run(stamps, values, frames, cuts, regular=False)
    np.testing.assert_array_equal(fast[0], slow[0])  # booleans
    assert len(fast[1]) == len(slow[1])
    for (s1, v1), (s2, v2) in zip(fast[1], slow[1], strict=True):
        np.testing.assert_array_equal(s1, s2)  # integer stamps
        np.testing.assert_allclose(v1, v2, rtol=0.0, atol=0.0)  # values passed through, not computed
    assert fast[2] == slow[2]
    assert set(fast[2]) >= {"nonfinite", "out_of_range", "frame_id", "duplicate", "out_of_order", "frozen"}
    assert fast[2]["clock_jump"] >= 1
    for key, value in slow[3].items():  # stamps, counts and values copied from the input: exact
        np.testing.assert_array_equal(np.asarray(fast[3][key]), np.asarray(value), err_msg=key)
    # the short way was taken for most chunks, and never where the general path rejects
    assert fast[4] > 0.5 * (len(cuts) - 1)
    assert slow[4] == 0


@pytest.mark.parametrize("few", [0, 10**9], ids=["numpy", "floats"])
def test_a_regular_batch_leaves_the_run_and_step_state_of_the_general_path(few: int, monkeypatch) -> None:
    monkeypatch.setattr(gate_module, "REGULAR_FEW", few)
    stamps = 1_650_000_000 * NS + np.arange(50, dtype=np.int64) * STEP
    values = 2.2e5 + np.arange(50.0)
    a, b = _gate(), _gate()
    b._regular = lambda *args: False
    for gate in (a, b):
        assert gate(stamps[:1], values[:1], "frc_01", None, Counter()).all()  # the first: general path
        assert gate(stamps[1:], values[1:], "frc_01", None, Counter()).all()
    for key, value in b.state_dict().items():  # stamps, counts, copied values: exact
        np.testing.assert_array_equal(np.asarray(a.state_dict()[key]), np.asarray(value), err_msg=key)
    assert (a.last_ns, a.last_step_ns, a.run_count) == (int(stamps[-1]), STEP, 1)


def test_a_shadow_takes_a_regular_batch_whole_as_its_general_path_does() -> None:
    """``Shadow._gate`` takes a regular batch without the mask (``take_regular``): the same state.

    Two shadows fed the irregular stream in the same random chunks, one with ``take_regular``
    off (the general path, the definition), keep the same counts, ledgers, buffered samples and
    clock, and close the same windows.
    """
    from bridge_shadow.estimate import Shadow, load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    stamps, values, frames = _stream(3)
    cfg = load_config().replace(window_s=1.0, traffic_hold_s=0.0)
    fast, slow = Shadow(cfg, load_surrogate()), Shadow(cfg, load_surrogate())
    for gate in slow.gates:
        gate.take_regular = lambda *args: False  # type: ignore[method-assign]
    rng = np.random.default_rng(7)
    cuts = np.unique(np.concatenate([[0, len(stamps)], rng.integers(1, len(stamps), 300)]))
    taken = [0]
    note_taken = fast.ledgers[0].note_taken

    def counted(*args: int) -> None:
        taken[0] += 1
        note_taken(*args)

    fast.ledgers[0].note_taken = counted  # type: ignore[method-assign]
    tested = [0]  # a batch is tested for regularity once, not again on the general path
    regular = fast.gates[0]._regular

    def counted_regular(*args: object) -> bool:
        tested[0] += 1
        return regular(*args)  # type: ignore[arg-type]

    fast.gates[0]._regular = counted_regular  # type: ignore[method-assign]
    outs: dict[int, list] = {0: [], 1: []}
    for a, b in pairwise(cuts):
        for s in (fast, slow):
            t = stamps[a:b][::10]
            s.ingest_temperature(t, 8.0 + np.zeros(len(t)), "air_temperature")
            s.ingest_forces(0, stamps[a:b], values[a:b], frames[a:b])
            s.ingest_forces(1, stamps[a:b], values[a:b] * 0.9, "frc_02")
            outs[s is slow].extend(s.poll())
    assert taken[0] > 0.5 * (len(cuts) - 1)  # most chunks were taken whole
    assert taken[0] < tested[0] <= len(cuts) - 1  # the others tested once each
    assert fast.counts == slow.counts and fast.used == slow.used and fast._first_ns == slow._first_ns
    for lf, ls in zip(fast.ledgers, slow.ledgers, strict=True):
        assert {k: v for k, v in vars(lf).items() if k != "note_taken"} == vars(ls)  # (the counter)
    for c in range(2):  # integer stamps and values copied from the input: exact
        for x, y in zip(fast.buffer.force[c].arrays(), slow.buffer.force[c].arrays(), strict=True):
            np.testing.assert_array_equal(x, y)
    assert len(outs[0]) == len(outs[1]) > 10
    for x, y in zip(outs[0], outs[1], strict=True):  # the same windows, the same arithmetic on them
        assert x.index == y.index and x.reason == y.reason
        np.testing.assert_array_equal(x.samples, y.samples)
        np.testing.assert_allclose(x.mean_m, y.mean_m, rtol=1e-12, atol=0.0)  # computed: to rounding


@pytest.mark.parametrize("few", [0, 10**9], ids=["numpy", "floats"])
def test_an_open_range_still_declines_infinite_values(few: int, monkeypatch) -> None:
    """With an infinite bound the range test lets inf through: the regular batch still declines it."""
    monkeypatch.setattr(gate_module, "REGULAR_FEW", few)
    stamps = 1_650_000_000 * NS + np.arange(20, dtype=np.int64) * STEP
    values = 2.2e5 + np.arange(20.0)
    values[7] = np.inf
    gate = TopicGate("frc_01", -np.inf, np.inf, 3600 * NS, 3, round(FROZEN_S * NS))
    counts: Counter = Counter()
    assert gate(stamps[:1], values[:1], "frc_01", None, counts).all()
    assert not gate._regular(stamps[1:], values[1:], "frc_01")
    ok = gate(stamps[1:], values[1:], "frc_01", None, counts)
    assert ok.sum() == 18 and not ok[6] and counts == Counter(nonfinite=1)


def test_a_record_given_twice_is_decided_as_message_by_message_in_linear_work(monkeypatch) -> None:
    """Every other message a duplicate (a record given twice, merged by stamp), or the record again.

    Found by a reviewing session: the general path looked ahead over the rest of the batch after
    every irregular message, so a stretch of them was quadratic (a 12-minute 100 Hz record given
    twice took 30-40 s in ``Shadow.run``, 14 s for 40,000 interleaved duplicates in the gate alone).
    The look-ahead is a block doubled while the run goes on: the same decisions, linear work.
    """
    n = 4000
    s = 1_650_000_000 * NS + np.arange(n, dtype=np.int64) * STEP
    v = 2.2e5 + 60.0 * np.random.default_rng(7).standard_normal(n)
    diff = np.diff
    diffed = 0

    def counted(a, *args, **kwargs):
        nonlocal diffed
        diffed += len(a)
        return diff(a, *args, **kwargs)

    twice = (
        (np.repeat(s, 2), np.repeat(v, 2)),
        (np.concatenate([s, s]), np.concatenate([v, v])),
    )
    for stamps, values in twice:
        one = _gate()
        by_one = np.concatenate(
            [one(stamps[k : k + 1], values[k : k + 1], "frc_01", None, Counter()) for k in range(len(stamps))]
        )
        diffed = 0
        monkeypatch.setattr(np, "diff", counted)
        counts: Counter = Counter()
        whole = _gate()(stamps, values, "frc_01", None, counts)
        monkeypatch.setattr(np, "diff", diff)
        np.testing.assert_array_equal(whole, by_one)
        assert int(whole.sum()) == n and sum(counts.values()) == n
        assert diffed < 200 * len(stamps)  # the whole rest of the batch after each: ~n^2
