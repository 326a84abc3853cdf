"""Real records of the bridge.

The 2022-04-11 reference record followed by the record after the first
10 mm lowering of the whole central support, imported as one stream.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.model.surrogate_file import load_surrogate

pytestmark = pytest.mark.realdata
W = 60 * 10**9


@pytest.fixture(scope="module")
def stream(munich_data: Path):
    from bridge_shadow.importers import import_csv

    folder = munich_data / "Settlements"
    data, _ = import_csv(
        [
            folder / "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
            folder / "UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip",
            folder / "TemperatureData2022-04-11.zip",
        ]
    )
    return data


def test_the_lowering_is_one_event_and_the_estimate_follows_it(stream) -> None:
    sur = load_surrogate()
    shadow = Shadow(load_config(), sur)
    res = shadow.run(stream)
    f = [stream.forces[ch] for ch in ("frc_01", "frc_02")]
    gap = int(np.argmax(np.diff(f[0].stamp_ns)))  # the 32 minutes between the records
    split = f[0].stamp_ns[gap + 1]
    # each record is 12 windows with a test car parked and driven about: no event inside a record
    assert len(res.events) == 1, [e.window for e in res.events]
    event = res.events[0]
    assert event.window == split // W
    # what the surrogate implies for the measured change of the reactions (record means)
    d_r = np.array([x.force_n[x.stamp_ns >= split].mean() - x.force_n[x.stamp_ns < split].mean() for x in f])
    implied = np.linalg.solve(sur.A, d_r)
    assert np.all(implied < -3e-3)  # the support went down
    np.testing.assert_allclose(event.size_m / implied, 1.0, atol=0.15)
    first = [o.mean_m for o in res.outputs if o.end_ns <= split][-1]  # the reference record's estimate
    np.testing.assert_allclose((res.mean_m - first) / implied, 1.0, atol=0.15)
    sd = np.sqrt(np.diag(res.covariance_m2))
    assert np.all(np.abs(res.mean_m - first - implied) < 1.96 * sd)
    # the default surrogate is the calibrated model of the real bridge: the change is the imposed
    # 10 mm, and so is the final estimate itself (issue: within 15 %, its interval holding it)
    assert "calibrat" in str(sur.provenance).lower()
    np.testing.assert_allclose(res.mean_m - first, -10e-3, rtol=0.15)
    assert np.all(np.abs(res.mean_m - first + 10e-3) < 1.96 * sd)
    np.testing.assert_allclose(res.mean_m, -10e-3, rtol=0.15)
    assert np.all(np.abs(res.mean_m + 10e-3) < 1.96 * sd)
