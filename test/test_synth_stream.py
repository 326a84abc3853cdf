"""``synth`` in bounded memory: long records segment by segment, archives of bridges and days.

A record longer than a segment is simulated in segments (``twin.stream``) whose world (weather,
settlement path) is the whole record's: so the segmented record's air temperature equals the
whole record's up to the sensor noise, and its stamps run on without a seam. Segments here are
made small (``segment_samples``) so the test stays lean; the sizes are what changes, not the code.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import read_monitoring
from bridge_shadow.model.surrogate_file import placeholder_surrogate
from bridge_shadow.twin.config import TwinConfig
from bridge_shadow.twin.simulate import simulate
from bridge_shadow.twin.stream import merge_truths, record_segments, write_stream_bag

DAYS, RATE = 2.0, 0.05  # 8,640 force samples per channel


def test_segments_tile_the_record_and_keep_its_world(tmp_path: Path) -> None:
    """Stamps of the segments tile the whole record's; the weather is continuous across segments."""
    sur = placeholder_surrogate()
    whole, _ = simulate(DAYS, RATE, seed=3, surrogate=sur)
    bag, truth = write_stream_bag(
        tmp_path / "bag", record_segments(DAYS, RATE, segment_samples=1000, seed=3, surrogate=sur)
    )
    assert truth["segments"] == 9
    data = read_monitoring(bag)
    t_whole, t_seg = whole.temperature, data.temperature
    # every temperature stamp of the record, once, in order (dropouts differ: other random streams)
    assert np.all(np.diff(t_seg.stamp_ns) > 0)
    common, iw, iseg = np.intersect1d(t_whole.stamp_ns, t_seg.stamp_ns, return_indices=True)
    assert len(common) > 0.9 * len(t_whole)
    diff = t_whole.temp_c[iw] - t_seg.temp_c[iseg]
    sd = TwinConfig().temp_sensor_sd_k
    ok = np.isfinite(diff)
    # the same weather: only the two sensors' noise differs (sd * sqrt(2)); a restarted weather would not
    assert np.max(np.abs(diff[ok])) < 6 * np.sqrt(2) * sd
    assert truth["counts"]["temperature_messages"] == len(t_seg)
    assert truth["counts"]["force_messages"]["frc_01"] == len(data.forces["frc_01"])
    # the force grid runs on over segment boundaries (every stamp is on the record's grid)
    step = round(1e9 / RATE)
    s = data.forces["frc_01"].stamp_ns
    assert np.all((s - s[0]) % step == 0)


def test_a_record_that_fits_one_segment_is_simulate_itself() -> None:
    """One segment: exactly ``simulate`` (so the bundled bags and their commands are unchanged)."""
    sur = placeholder_surrogate()
    ((data, truth),) = list(record_segments(DAYS, RATE, seed=4, surrogate=sur))
    ref, _ = simulate(DAYS, RATE, seed=4, surrogate=sur)
    np.testing.assert_array_equal(data.forces["frc_02"].stamp_ns, ref.forces["frc_02"].stamp_ns)
    np.testing.assert_allclose(data.forces["frc_02"].force_n, ref.forces["frc_02"].force_n, rtol=1e-12)
    assert merge_truths([truth]) is truth


def test_a_drift_runs_on_over_segments() -> None:
    """The settlement path is the record's: the last segment's drift is the record's, not restarted."""
    sur = placeholder_surrogate()
    segs = list(
        record_segments(
            DAYS, RATE, segment_samples=3000, seed=1, surrogate=sur, effects={"settlement_drift": 1e-4}
        )
    )
    truths = [t for _, t in segs]
    assert truths[-1]["settlement"]["end_m"][0] == pytest.approx(-1e-4 * DAYS, rel=1e-3)
    assert merge_truths(truths)["settlement"]["start_m"][0] == pytest.approx(0.0, abs=1e-12)


def test_synth_archive_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``synth --archive``: bridges x daily bags, a truth per bridge; refuses to overwrite silently."""
    from bridge_shadow.cli import main

    out = tmp_path / "fleet"
    argv = ["synth", "--archive", str(out), "--bridges", "2", "--days", "1.5", "--rate", "0.02", "--json"]
    assert main(argv) == 0
    js = json.loads(capsys.readouterr().out)
    assert [b["bridge"] for b in js["bridges"]] == ["bridge_00", "bridge_01"]
    assert sorted(p.name for p in (out / "bridge_01").iterdir()) == ["day_0000", "day_0001", "truth.yaml"]
    day0 = read_monitoring(out / "bridge_00" / "day_0000")
    day1 = read_monitoring(out / "bridge_00" / "day_0001")
    assert day0.forces["frc_01"].stamp_ns[-1] < day1.forces["frc_01"].stamp_ns[0]
    assert main(argv) == 2  # exists: one line, nothing touched
    assert "exists already" in capsys.readouterr().err
