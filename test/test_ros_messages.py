"""Message conversion and /diagnostics content, without a DDS graph (rclpy message types only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from bridge_shadow.bagio import encode_stamped_floats, read_monitoring
from bridge_shadow.estimate import Shadow, load_config
from bridge_shadow.ros.convert import (
    array_from_msg,
    covariance_msg,
    covariance_raw,
    decode_forces,
    decode_temperatures,
    mean_msg,
    mean_raw,
    wrench_msg,
    wrench_raw,
)
from bridge_shadow.ros.diagnostics import diagnostic_array, statuses
from bridge_shadow.series import MonitoringData


def test_mean_and_covariance_layout_round_trip() -> None:
    mean = np.array([7.0e-4, -6.9e-4])
    cov = np.array([[1.0e-9, -4.0e-10], [-4.0e-10, 2.0e-9]])
    m, c = mean_msg(mean), covariance_msg(cov)
    assert [(d.label, d.size, d.stride) for d in m.layout.dim] == [("support", 2, 2)]
    assert [(d.label, d.size, d.stride) for d in c.layout.dim] == [("row", 2, 4), ("col", 2, 2)]
    back_m, _ = array_from_msg(m)
    back_c, labels = array_from_msg(c)
    np.testing.assert_array_equal(back_m, mean)  # exact: copied into the message and out
    np.testing.assert_array_equal(back_c, cov)  # row-major
    assert labels == ("row", "col")


def test_wrench_msg_stamp_and_force() -> None:
    msg = wrench_msg(1_647_212_400_123_456_789, "frc_02", 2.34e5)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_647_212_400, 123_456_789)
    assert msg.header.frame_id == "frc_02"
    assert msg.wrench.force.z == 2.34e5


def test_serialized_outputs_are_what_rclpy_makes_of_the_typed_messages() -> None:
    """The node publishes CDR bytes packed into templates: rclpy reads them as the typed messages.

    Every field compared (the generated messages' ``==``), and the length of rclpy's own
    serialization; not the bytes themselves: CDR's alignment padding is unspecified, and rclpy's
    serializer leaves whatever was in memory there (seen differing from one call to the next).
    """
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from std_msgs.msg import Float64MultiArray

    rng = np.random.default_rng(3)
    for _ in range(5):
        mean = rng.normal(0.0, 1e-2, 2)
        a = rng.normal(0.0, 1e-3, (2, 2))
        cov = a @ a.T
        for raw, typed in ((mean_raw(mean), mean_msg(mean)), (covariance_raw(cov), covariance_msg(cov))):
            assert len(raw) == len(serialize_message(typed))
            assert deserialize_message(raw, Float64MultiArray) == typed
        back, labels = array_from_msg(deserialize_message(covariance_raw(cov), Float64MultiArray))
        np.testing.assert_array_equal(back, cov)  # the same floats, copied
        assert labels == ("row", "col")
    for stamp, frame, force in ((1_647_212_400_123_456_789, "frc_02", 2.34e5), (-5, "frc_01_long", -1.5)):
        raw = wrench_raw(stamp, frame, force)
        typed = wrench_msg(stamp, frame, force)
        assert len(raw) == len(serialize_message(typed))
        msg = deserialize_message(raw, WrenchStamped)
        assert msg == typed
        assert (msg.header.frame_id, msg.wrench.force.z) == (frame, force)


def test_decode_drops_and_counts_malformed() -> None:
    stamps = np.array([1, 2, 3], dtype=np.int64) * 1_000_000_000
    values = np.zeros((3, 6))
    values[:, 2] = [2.6e5, np.nan, 2.2e5]
    raws = encode_stamped_floats(stamps, "frc_01", values)
    stamp, force, frame, bad = decode_forces([raws[0], raws[1][:20], raws[2]])
    assert bad == 1
    np.testing.assert_array_equal(stamp, stamps[[0, 2]])  # exact: encoded and decoded, no arithmetic
    np.testing.assert_array_equal(force, [2.6e5, 2.2e5])
    assert list(frame) == ["frc_01", "frc_01"]
    temp = encode_stamped_floats(stamps, "air_temperature", np.array([[5.0, 0.0], [6.5, 0.1], [7.0, 0.0]]))
    _, t_c, _, bad = decode_temperatures(temp)
    assert bad == 0
    np.testing.assert_array_equal(t_c, [5.0, 6.5, 7.0])  # exact: encoded and decoded


@pytest.fixture(scope="module")
def diag(root: Path) -> dict:
    shadow = Shadow(load_config(None, {"window_min_samples": 2}))
    shadow.run(read_monitoring(root / "bags" / "baseline_1d"))
    return shadow.diagnostics()


def test_statuses_carry_posterior_in_mm_and_counts(diag: dict, root: Path) -> None:
    ages = {"frc_01": 0.1, "frc_02": 0.1, "air_temperature": 0.5}
    est, inputs, comp, events = statuses(diag, ages, malformed=3, timeout_s=60.0)
    mean, sigma = np.array(diag["mean_m"]), np.array(diag["sigma_m"])
    assert est.values["south settlement [mm]"] == f"{1e3 * mean[0]:+.4f}"
    assert est.values["north sigma [mm]"] == f"{1e3 * sigma[1]:.4f}"
    assert est.level == {"OK": 0, "WARN": 1, "ERROR": 2}[diag["level"]]
    assert inputs.level == 0
    assert inputs.values["rejected nonfinite"] == str(diag["rejected"]["nonfinite"]) != "0"
    assert inputs.values["rejected malformed"] == "3"
    assert comp.values["frc_02 lambda [C^3]"] == f"{diag['spline']['frc_02']['lambda']:.4g}"
    sp = diag["spline"]["frc_02"]
    assert comp.values["frc_02 temperature range [C]"] == f"{sp['t_min_c']:.1f} .. {sp['t_max_c']:.1f}"
    # windows without an air temperature: n/a, not 'lambda inf' and 'inf .. -inf'
    data = read_monitoring(root / "bags" / "baseline_1d")
    forces = np.column_stack([data.forces[ch].force_n for ch in data.forces])
    stamps = data.forces["frc_01"].stamp_ns
    no_air = MonitoringData.from_arrays(stamps, forces, stamps[:0], np.zeros(0))
    shadow = Shadow(load_config(None, {"window_min_samples": 2}))
    shadow.run(no_air)
    comp = statuses(shadow.diagnostics(), ages, timeout_s=60.0)[2]
    assert comp.values["frc_01 windows"] != "0"
    assert comp.values["frc_01 lambda [C^3]"] == comp.values["frc_01 temperature range [C]"] == "n/a"
    assert events.level == 0 and events.values["events"] == "0"
    msg = diagnostic_array([est, inputs, comp, events], 5_000_000_001)
    assert [s.level for s in msg.status] == [bytes([est.level]), b"\x00", bytes([comp.level]), b"\x00"]
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (5, 1)


def test_input_levels_follow_arrival_age(diag: dict) -> None:
    quiet_one = {"frc_01": 0.1, "frc_02": None, "air_temperature": 0.1}
    assert statuses(diag, quiet_one, timeout_s=60.0)[1].level == 1
    stale_all = {"frc_01": 61.0, "frc_02": 120.0, "air_temperature": 61.0}
    inputs = statuses(diag, stale_all, timeout_s=60.0)[1]
    assert inputs.level == 2
    assert inputs.message.startswith("no input for 60 s on any topic")
    # a node 5 s old that has heard nothing yet is waiting, not an ERROR of 60 s without input
    never = dict.fromkeys(stale_all)
    inputs = statuses(diag, never, timeout_s=60.0, running_s=5.0)[1]
    assert inputs.level == 0 and inputs.message.startswith("waiting for input (started 5 s ago)")
    assert statuses(diag, never, timeout_s=60.0, running_s=61.0)[1].level == 2
    assert statuses(diag, quiet_one, timeout_s=60.0, running_s=5.0)[1].level == 0
    assert statuses(diag, quiet_one, timeout_s=60.0, running_s=61.0)[1].level == 1


def test_events_and_lost_topics_reach_diagnostics() -> None:
    """A detected step is a WARN status naming its time and size; a topic lost to its frame id too."""
    from bridge_shadow.model.surrogate_file import placeholder_surrogate
    from bridge_shadow.series import MonitoringData, TemperatureSeries

    sur = placeholder_surrogate()
    t0 = 1_700_000_040 * 10**9
    n = 60 * 60  # one hour at 1 Hz
    stamps = t0 + np.arange(n, dtype=np.int64) * 10**9
    rng = np.random.default_rng(0)
    x = np.where(np.arange(n)[:, None] >= 2400, [-1e-3, 0.0], [0.0, 0.0])
    forces = sur.reactions(x) + rng.normal(0.0, 60.0, (n, 2))
    data = MonitoringData.from_arrays(stamps, forces, stamps[::10], np.full(n // 10, 8.0))
    t = data.temperature
    data = MonitoringData(
        data.forces, TemperatureSeries(t.stamp_ns, t.temp_c, None, np.full(len(t), "roof", dtype=object))
    )
    shadow = Shadow(load_config(None, {"temperature_frame_id": "air_temperature"}), sur)
    shadow.run(data)
    diag = shadow.diagnostics()
    _, inputs, comp, events = statuses(diag, {"frc_01": 0.1, "frc_02": 0.1, "air_temperature": 0.1})
    assert events.level == 1 and events.values["events"] == "1"
    from bridge_shadow.timefmt import iso_utc

    # the time of the step in ISO 8601 (2023-11-14T22:54Z), not a window index
    assert "south -1.00" in events.values["event 1"] and "window" not in events.values["event 1"]
    assert f"at {iso_utc(diag['events'][0]['time_ns'])}:" in events.values["event 1"]
    assert "holds zero" not in events.values["event 1"]  # 1 mm is far outside its interval
    assert inputs.level == 1 and "topic air_temperature: all" in inputs.message and "'roof'" in inputs.message
    assert comp.level == 1 and "no air temperature" in comp.message


def test_an_unconfirmed_change_no_window_has_measured_says_so_not_nan(diag: dict) -> None:
    """A gap whose record is still held has no size yet: the events status says so (it read "+nan ± nan")."""
    nan = float("nan")
    base = {"time": "2022-04-11T07:20Z", "change_probability": 0.5, "likely": True, "kind": "gap"}
    held = {**base, "size_m": [nan, nan], "sigma_m": [nan, nan]}
    measured = {**base, "size_m": [-0.01, -0.0101], "sigma_m": [0.001, 0.001]}
    ages = {"frc_01": 0.1, "frc_02": 0.1, "air_temperature": 0.1}
    for change, text in ((held, "size not measured yet"), (measured, "south -10.000 ± 1.960, north -10.100")):
        events = statuses({**diag, "unconfirmed_changes": [change]}, ages, timeout_s=60.0)[3]
        value = events.values["unconfirmed 1"]
        assert text in value and "nan" not in value and "probability 0.5" in value, value
