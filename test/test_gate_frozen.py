"""A load cell that stopped while its logger holds the last reading (``frozen``, ``inputs.gate``).

Checked on a synthetic 100 Hz channel (the run's first ``FROZEN_S`` taken, every later repeat
rejected, whatever the chunking or a checkpoint in the run; a few repeats and a live channel's
sample-and-hold untouched; the air's repeats never), and on the real records (their longest run
of repeats is 4 samples; a load cell frozen over the last minutes of the new state's record).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.estimate.inputs.gate import FROZEN_REPEATS, FROZEN_S, TopicGate
from bridge_shadow.importers import import_csv
from bridge_shadow.model.surrogate_file import load_surrogate
from bridge_shadow.series import ForceSeries, MonitoringData
from bridge_shadow.twin.loadtest_score import score_stream
from bridge_shadow.twin.real_records import Piece, build

NS = 10**9
T0 = 1_650_000_000 * NS


def _channel(
    seconds: float, frozen: tuple[float, float] | None, hold: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """100 Hz stamps and forces (60 N noise), each value held ``hold`` samples, frozen over ``frozen`` s."""
    n = round(seconds * 100)
    t = T0 + np.arange(n, dtype=np.int64) * (NS // 100)
    v = 2.3e5 + np.random.default_rng(0).normal(0.0, 60.0, n)
    v = np.repeat(v[::hold], hold)[:n]
    if frozen is not None:
        a, b = (round(x * 100) for x in frozen)
        v[a:b] = v[a]
    return t, v


def _gate() -> TopicGate:
    return TopicGate(None, 1.0, 5e6, 3600 * NS, 3, round(FROZEN_S * NS))


def _run(gate: TopicGate, t: np.ndarray, v: np.ndarray, cuts: list[int]) -> tuple[np.ndarray, Counter]:
    counts: Counter = Counter()
    kept = []
    for a, b in zip([0, *cuts], [*cuts, len(t)], strict=True):
        ok = gate(t[a:b], v[a:b], None, None, counts)
        kept.append(t[a:b][ok])
    return np.concatenate(kept), counts


def test_a_frozen_channel_keeps_its_first_seconds_whatever_the_chunking() -> None:
    t, v = _channel(60.0, (20.0, 50.0))
    want_kept, want = _run(_gate(), t, v, [])
    assert (
        want["frozen"] == round((30.0 - FROZEN_S) * 100) - 1
    )  # the run's first FROZEN_S (and 1 sample) kept
    gone = np.setdiff1d(t, want_kept)
    assert gone.min() > t[0] + round((20.0 + FROZEN_S) * NS) and gone.max() < t[0] + 50 * NS
    rng = np.random.default_rng(1)
    for _ in range(5):
        cuts = sorted(rng.choice(np.arange(1, len(t)), size=7, replace=False).tolist())
        kept, counts = _run(_gate(), t, v, cuts)
        np.testing.assert_array_equal(kept, want_kept)  # integer stamps kept
        assert counts == want


def test_a_checkpoint_inside_the_run_resumes_it() -> None:
    t, v = _channel(60.0, (20.0, 50.0))
    want_kept, want = _run(_gate(), t, v, [])
    first = _gate()
    kept_a, counts_a = _run(first, t[:3000], v[:3000], [])
    second = _gate()
    second.load_state_dict(first.state_dict())
    kept_b, counts_b = _run(second, t[3000:], v[3000:], [])
    np.testing.assert_array_equal(np.concatenate([kept_a, kept_b]), want_kept)  # integer stamps kept
    assert counts_a + counts_b == want


@pytest.mark.parametrize("hold", [1, 20, 100])
def test_a_live_channel_and_a_few_repeats_are_untouched(hold: int) -> None:
    """A slower channel's sample-and-hold (up to a second) and repeats across a jump of the stamps."""
    t, v = _channel(60.0, None, hold)
    kept, counts = _run(_gate(), t, v, [])
    assert counts["frozen"] == 0 and len(kept) == len(t)
    t, v = _channel(60.0, None)
    jumped = np.r_[t[:5], t[5:] + 3600 * NS]  # FROZEN_REPEATS readings of one value, across an hour
    v[:FROZEN_REPEATS] = v[0]
    _, counts = _run(_gate(), jumped, v, [])
    assert counts["frozen"] == 0
    v[: FROZEN_REPEATS + 1] = v[0]  # one more is a run of seconds: the last one goes
    _, counts = _run(_gate(), jumped, v, [])
    assert counts["frozen"] == 1


@pytest.mark.realdata
def test_the_real_records_never_repeat_a_value_for_long(munich_data: Path) -> None:
    for name in (
        "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
        "UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
    ):
        data = import_csv([munich_data / "Settlements" / name])[0]
        for s in data.forces.values():
            runs = np.diff(np.r_[-1, np.flatnonzero(np.diff(s.force_n) != 0), len(s.force_n) - 1])
            assert runs.max() < FROZEN_REPEATS  # at most 4 samples (40 ms)
        res = Shadow(load_config(), load_surrogate()).run(data)
        assert res.rejected["frozen"] == 0


@pytest.mark.realdata
@pytest.mark.parametrize("channel", [0, 1])
def test_a_load_cell_frozen_at_the_records_end_is_not_data(munich_data: Path, channel: int) -> None:
    """The reference record 10 mm lower 1.25 h on, one cell frozen over its minutes 9-12 (car gone).

    Taken as data, the frozen cell's reading (the car leaving, held) moved the state 0.9-1.4 mm.
    Rejected, the state keeps the windows before it (too few to confirm it: a likely change).
    """
    sur = load_surrogate()
    sc = build(munich_data / "Settlements", sur.A, [Piece("ref", 0.0), Piece("ref", 1.25, (-0.01, -0.01))])
    t1 = sc.starts_ns[1]
    forces = {}
    for c, (ch, s) in enumerate(sc.data.forces.items()):
        f = s.force_n.copy()
        if c == channel:
            idx = np.flatnonzero((s.stamp_ns >= t1 + 9 * 60 * NS) & (s.stamp_ns < t1 + 12 * 60 * NS))
            f[idx] = f[idx[0]]
        forces[ch] = ForceSeries(s.stamp_ns, f, s.frame_id)
    sc.data = MonitoringData(forces, sc.data.temperature)
    res = Shadow(load_config(), sur).run(sc.data)
    score = score_stream(sc, res)
    assert res.rejected["frozen"] > 0.9 * (3 * 60 - FROZEN_S) * 100
    assert score.within and score.covered and not score.lost_windows
    assert not score.spurious and not score.unreported
