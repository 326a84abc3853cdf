"""Detection over more twin seeds than ``test_gap_twin``: no false alarm, and every effect found.

A short check: the clean record at three seeds must give ``none``, and every effect at its
``realistic`` magnitude must be found (``best`` or its indistinguishable group) at one more seed.
The full table at realistic and edge magnitudes is ``benchmarks/gap_detection.py``.
"""

from __future__ import annotations

import pytest

from bridge_shadow.effects import EFFECT_NAMES, EFFECTS
from bridge_shadow.gap.diagnose import diagnose

twin = pytest.importorskip("bridge_shadow.twin.simulate")


@pytest.mark.parametrize("seed", [200, 201, 202])
def test_clean_records_give_none(seed: int):
    data, _ = twin.simulate(3.0, 0.1, seed, {})
    s = diagnose(data).summary
    assert s["best"] == "none", s["statement"]


@pytest.mark.slow
def test_every_effect_is_found_at_another_seed():
    missed = {}
    for name in EFFECT_NAMES:
        data, _ = twin.simulate(3.0, 0.1, 201, {name: EFFECTS[name].realistic})
        s = diagnose(data).summary
        if name not in [s["best"], *s["indistinguishable_from"]]:
            missed[name] = s["statement"]
    assert not missed, missed
