"""Text for people: replay's counts say what they count, the node says what it runs with, --watch."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest

from bridge_shadow.commands.replay import _summary
from bridge_shadow.estimate import REASONS, load_config


def _replay_json(rejected: dict[str, int]) -> dict:
    return {
        "posterior": {"mean_m": [7e-4, -7e-4], "covariance_m2": [[1e-10, 5e-11], [5e-11, 1e-10]]},
        "messages": {"total": 100, "used": 93, "rejected": 7},
        "messages_per_s": 1e5,
        "windows": {"closed": 40, "updates": 25},
        "rejected": {r: rejected.get(r, 0) for r in REASONS},
        "spline": {},
    }


def test_rejected_messages_and_unused_windows_are_counted_apart() -> None:
    text = _summary(_replay_json({"nonfinite": 7, "missing_topic": 6, "sparse_window": 4, "outlier": 5}))
    lines = text.splitlines()
    assert "rejected messages: nonfinite 7" in lines  # the 7 of "93 used, 7 rejected"
    assert "windows not used: missing_topic 6, sparse_window 4, outlier 5" in lines
    assert not any(line.startswith("rejected:") for line in lines)


def test_a_channel_with_no_window_used_says_so_and_prints_no_nan() -> None:
    """A bag of air temperature alone: no curve was fitted, and the text says that, not ``nan``."""
    js = _replay_json({"missing_topic": 30})
    empty = {
        "edf": None,
        "lambda": None,
        "mean_force_n": None,
        "windows": 0,
        "t_min_c": None,
        "t_max_c": None,
    }
    fitted = {
        "edf": 2.5,
        "lambda": 40.0,
        "mean_force_n": 211220.0,
        "windows": 7,
        "t_min_c": 4.0,
        "t_max_c": 9.0,
    }
    js["spline"] = {"frc_01": empty, "frc_02": fitted}
    lines = _summary(js).splitlines()
    assert "compensation frc_01: no window used, no curve fitted" in lines
    assert any(line.startswith("compensation frc_02: 2.50 effective degrees of freedom") for line in lines)
    assert "211.22 kN over 7 windows" in _summary(js)
    assert "nan" not in _summary(js).lower()


def test_node_start_up_lines_name_surrogate_parameter_files_topics_and_checkpoint(root) -> None:
    from bridge_shadow.model.surrogate_file import load_surrogate

    pytest.importorskip("rclpy")
    from bridge_shadow.ros.main import params_files
    from bridge_shadow.ros.node import startup_lines

    argv = ["--ros-args", "-p", "window_s:=30.0", "--params-file", "/etc/shadow.yaml"]
    assert params_files(argv) == ["/etc/shadow.yaml"]
    cfg = load_config(None, {"checkpoint_path": "/var/lib/shadow/state.npz", "topic_frc_01": "/site/south"})
    lines = startup_lines(cfg, load_surrogate(), params_files(argv))
    text = "\n".join(lines)
    assert f"surrogate: {root / 'config' / 'surrogate.yaml'}" in text
    assert "parameter files: /etc/shadow.yaml" in text
    assert "inputs: /site/south, /bridge/frc_02/force, /bridge/air_temperature" in text
    assert "/bridge_shadow/settlement/mean" in text and "/diagnostics" in text
    assert "checkpoint: /var/lib/shadow/state.npz" in text
    off = startup_lines(load_config(), load_surrogate(), [])
    assert "checkpoint: off" in "\n".join(off) and "parameter files: none" in "\n".join(off)


def test_a_parameter_file_for_another_node_is_a_warning(tmp_path) -> None:
    """A file copied under another node's name set nothing, checkpoint_path included, silently."""
    pytest.importorskip("rclpy")
    from bridge_shadow.ros.main import _check_params_file, node_sections

    other = tmp_path / "other.yaml"
    other.write_text("shadow_node:\n  ros__parameters:\n    window_s: 30.0\n")
    ours = tmp_path / "ours.yaml"
    ours.write_text("bridge_shadow:\n  ros__parameters:\n    window_s: 30.0\n")
    plain = ["--ros-args", "--params-file", "F"]
    renamed = ["--ros-args", "-r", "__node:=shadow_node", "-r", "__ns:=/site", "--params-file", "F"]
    warning = _check_params_file(str(other), node_sections(plain))
    assert warning == (
        f"{other}: no section for this node (/bridge_shadow, or /**): it sets nothing here "
        "(its sections: shadow_node)"
    )
    assert _check_params_file(str(ours), node_sections(plain)) is None
    assert _check_params_file(str(other), node_sections(renamed)) is None  # renamed to it
    assert "(/site/shadow_node, or /**)" in _check_params_file(str(ours), node_sections(renamed))


def test_the_node_logs_its_start_up_lines(capfd) -> None:
    rclpy = pytest.importorskip("rclpy")
    from bridge_shadow.ros.node import ShadowNode

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        ShadowNode(context=context).destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    err = capfd.readouterr().err
    for what in ("surrogate:", "parameters:", "inputs:", "outputs:", "checkpoint:"):
        assert f"[bridge_shadow]: {what}" in err, what


def test_the_node_logs_each_load_cells_warning_once(capfd) -> None:
    """One warning per load cell reaches the log, each only once.

    The numbers blanked to tell a new warning from a recount blanked the cells' own digits too, and
    frc_02's warning never appeared.
    """
    rclpy = pytest.importorskip("rclpy")
    from bridge_shadow.ros.node import ShadowNode

    lines = [
        f"topic {t}: all {n} messages rejected (wrong_frame: frame_id 'x', expected 'frc_0{i}')"
        for n in (40, 120)
        for i, t in ((1, "frc_01"), (2, "frc_02"))
    ]
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = ShadowNode(context=context)
        real = node.shadow.diagnostics
        for some in (lines[:2], lines[2:]):
            node.shadow.diagnostics = lambda some=some, **kw: {**real(**kw), "warnings": some}
            node.publish_diagnostics()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    err = capfd.readouterr().err
    assert err.count("topic frc_01: all 40 messages rejected") == 1, err
    assert err.count("topic frc_02: all 40 messages rejected") == 1, err
    assert "120 messages" not in err  # the same warnings recounted


def test_watch_line_shows_the_latest_outputs() -> None:
    pytest.importorskip("rclpy")
    from rclpy.serialization import serialize_message

    from bridge_shadow.contract import COMPENSATED_TOPICS, COVARIANCE_TOPIC, DIAGNOSTICS_TOPIC, MEAN_TOPIC
    from bridge_shadow.ros import convert
    from bridge_shadow.ros.diagnostics import Status, diagnostic_array
    from bridge_shadow.ros.watch import TopicWatch, watch_line

    end_ns = 1_647_241_200 * 10**9  # 2022-03-14 07:00 UTC
    records: dict[str, list] = {}
    assert watch_line(records, 0.0) == "[  0%] no window closed yet"

    def put(topic: str, msg) -> None:
        records.setdefault(topic, []).append((0, serialize_message(msg)))

    put(MEAN_TOPIC, convert.mean_msg(np.array([1e-4, -1e-4])))  # an older window
    put(MEAN_TOPIC, convert.mean_msg(np.array([7.0e-4, -6.9e-4])))
    put(COVARIANCE_TOPIC, convert.covariance_msg(np.diag([(1e-5) ** 2, (2e-5) ** 2])))
    put(COMPENSATED_TOPICS["frc_01"], convert.wrench_msg(end_ns, "frc_01", 238_910.0))
    put(COMPENSATED_TOPICS["frc_02"], convert.wrench_msg(end_ns, "frc_02", 238_870.0))
    put(DIAGNOSTICS_TOPIC, diagnostic_array([Status("bridge_shadow: settlement", 1, "warming up")], end_ns))
    line = watch_line(records, 0.42)
    assert line == (
        "[ 42%] window to 2022-03-14T07:00Z: south +0.700 ± 0.020 mm, north -0.690 ± 0.039 mm"
        " | compensated 238.91 / 238.87 kN | settlement WARN | 2 windows"
    )
    import io

    out = io.StringIO()
    watch = TopicWatch(records, period_s=3600.0, stream=out)
    watch(0.1)
    watch(0.2)  # within the period: not shown
    watch(1.0)  # the end: always shown
    assert len(out.getvalue().splitlines()) == 2


def test_a_resumed_replay_counts_this_run(root, tmp_path) -> None:
    """Resume, then replay: the counts add up (used + rejected = messages read), the rest is ``resumed``."""
    import json
    import shutil

    from bridge_shadow.cli import main

    bag, ckpt = str(root / "bags" / "baseline_1d"), str(tmp_path / "state.npz")
    first = tmp_path / "first.json"
    with first.open("w") as fh, contextlib.redirect_stdout(fh):
        assert main(["replay", bag, "--checkpoint", ckpt, "--json"]) == 0
    fresh = json.loads(first.read_text())
    assert "resumed" not in fresh
    out = io.StringIO()
    # the same recording again: every message is old news now (a copy: the bag itself is known as
    # taken and not read at all, ``test_taken_bags.py``)
    copy = shutil.copytree(bag, tmp_path / "copy")
    with contextlib.redirect_stdout(out):
        assert main(["replay", str(copy), "--checkpoint", ckpt, "--json"]) in (0, 1)
    again = json.loads(out.getvalue())
    msgs = again["messages"]
    assert msgs["used"] + msgs["rejected"] == msgs["total"] == fresh["messages"]["total"]
    # the checkpoint holds the state before the end-of-bag close: this run closes the window(s)
    # left open then, from the data the checkpoint holds; the rest is the checkpoint's
    closed, updates = again["windows"]["closed"], again["windows"]["updates"]
    assert msgs["used"] == 0 and closed <= 2 and updates <= closed
    assert again["resumed"] == {
        "windows": fresh["windows"]["closed"] - closed,
        "updates": fresh["windows"]["updates"] - updates,
        "messages_used": fresh["messages"]["used"],
        "held_air": fresh["windows"]["at_end"]["held_air"],
    }
    # the posterior is the checkpoint's (the end-of-record refit runs once more: rounding)
    np.testing.assert_allclose(again["posterior"]["mean_m"], fresh["posterior"]["mean_m"], rtol=1e-9)
    text = _summary(again)
    assert text.startswith(f"resumed from a checkpoint of {fresh['windows']['closed'] - closed} windows")
    assert f"messages: {msgs['total']} in, 0 used, {msgs['total']} rejected" in text


def test_the_gap_texts_fitted_values_are_in_mm_and_kn() -> None:
    """Text for people in mm and kN (the JSON's in SI): it printed 'v_south -0.0002002' unitless."""
    from bridge_shadow.gap.si import params_text as _fmt_params

    params = {
        "v_south [m/s]": -2.002e-4 / 86400.0,
        "d [N/s]": -2305.0 / 86400.0,
        "tau [s]": 3.0 * 3600.0,
        "k_south [N/m]": 1.83e6,
        "k_north [N/m]": None,
        "g [K]": -3.0,
        "r [1]": 0.5,
        "dx_south [m]": -4.357e-4,
    }
    assert _fmt_params(params) == (
        "v_south -0.2002 mm/day, d -2.305 kN/day, tau 3 h, k_south 1.83 kN/mm, k_north rigid, g -3 K, r 0.5, "
        "dx_south -0.4357 mm"
    )


def test_forces_far_below_the_dead_load_are_said_out_loud(root) -> None:
    """Forces in kN sent as N: a confident -70 mm with no word but 'the noise model has seen 0.3 h'."""
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.estimate import Shadow
    from bridge_shadow.estimate.report import LOW_LOAD_SHARE
    from bridge_shadow.series import MonitoringData
    from bridge_shadow.twin.real_records import SWEEP_MIN_LOAD_SHARE

    assert LOW_LOAD_SHARE == SWEEP_MIN_LOAD_SHARE  # where the linear model's studies stop
    data = read_monitoring(root / "bags" / "baseline_1d")
    forces = np.column_stack([data.forces[ch].force_n for ch in data.forces])
    stamps, temp = data.forces["frc_01"].stamp_ns, data.temperature
    for scale, said in ((1e-3, True), (0.15, True), (1.0, False)):
        shadow = Shadow(load_config())
        shadow.run(MonitoringData.from_arrays(stamps, scale * forces, temp.stamp_ns, temp.temp_c))
        lines = [w for w in shadow.warnings() if w.startswith("force level far below the dead load")]
        assert bool(lines) == said, lines
        if said and scale < 0.01:
            assert "frc_01 0.235 kN of 235 kN (0.1 %)" in lines[0] and "kN where N" in lines[0]
        elif said:  # a bearing near lift-off, not a unit mix-up: no word of kN
            assert "(15 %)" in lines[0] and "kN where N" not in lines[0]


def test_imposed_steps_are_read_at_their_exact_time_and_add_up_at_one_instant() -> None:
    """09:00:00.897 was read a second late; two entries of one time crashed the level pairs."""
    import datetime as dt

    from bridge_shadow.commands.gap import parse_imposed
    from bridge_shadow.errors import InputError

    def ns(text: str) -> int:
        return round(dt.datetime.fromisoformat(text).timestamp() * 1e6) * 1000

    first, last = ns("2022-04-11T06:36:24.897+00:00"), ns("2022-04-11T07:32:05.365+00:00")
    steps = parse_imposed(
        ["2022-04-11T09:00:00.897=-0.01,0", "2022-04-11T07:00:00.897Z=0,-0.01", "+0.01=-0.002,-0.002"],
        first,
        last,
    )
    at = ns("2022-04-11T07:00:00.897+00:00")  # 09:00 in Munich's summer time is 07:00 UTC
    # stamps are integers (exact); the sizes are float sums of the entries given (a tolerance)
    assert steps[0][0] - first == round(864e11 * 0.01)
    assert steps[0][1:] == pytest.approx((-0.002, -0.002), rel=1e-12, abs=1e-15)
    assert steps[1][0] == at  # south and north given apart, at one instant
    assert steps[1][1:] == pytest.approx((-0.01, -0.01), rel=1e-12, abs=1e-15)
    for edge in ("+0=-0.01,-0.01", "2022-04-11T07:32:05.365Z=-0.01,-0.01"):
        with pytest.raises(InputError, match="is outside the record"):
            parse_imposed([edge], first, last)


def test_an_imposed_step_given_twice_is_refused_not_doubled() -> None:
    """A copied ``--imposed`` line doubled the step: 'imposed -20 mm', a stiffness at its bound, exit 0."""
    from bridge_shadow.commands.gap import parse_imposed
    from bridge_shadow.errors import InputError

    first, last = 1_649_658_984 * 10**9, 1_649_662_325 * 10**9
    twice = ["2022-04-11T09:00=-0.01,-0.01", "2022-04-11T09:00=-0.01,-0.01"]
    with pytest.raises(InputError, match=r"is given twice \(entry 1 and 2\)"):
        parse_imposed(twice, first, last)
    # the same time in two notations is the same step given twice
    with pytest.raises(InputError, match="given twice"):
        parse_imposed(["2022-04-11T09:00=-0.01,-0.01", "2022-04-11T07:00Z=-0.01,-0.01"], first, last)
    # the bearings apart at one instant still add up
    (step,) = parse_imposed(["2022-04-11T09:00=-0.01,0", "2022-04-11T09:00=0,-0.01"], first, last)
    assert step[1:] == pytest.approx((-0.01, -0.01), rel=1e-12, abs=1e-15)


def test_a_day_whose_imposed_steps_cannot_decide_does_not_say_the_model_explains_them() -> None:
    """The imposed steps cannot decide: the statement must not say the model explains them.

    The step given at the later gap of a day read by the as-built model: the step as given came
    fourth (probability 0.09) and the statement said "The model explains the response".
    """
    from types import SimpleNamespace

    from bridge_shadow.gap.explain import level_statement

    def analysis(weights: dict[str, float]) -> SimpleNamespace:
        rows = [{"effect": k, "parameters": {}, "delta_log_evidence": 0.0} for k in weights]
        best = max(weights, key=weights.__getitem__)
        return SimpleNamespace(
            named=False, best=best, group=[best], weights=weights, table=lambda: rows, misfit=lambda *a: None
        )

    def text(weights: dict[str, float]) -> str:
        lv = SimpleNamespace(records=[1, 2, 3], imposed=analysis(weights), steps=[], blind=[])
        return level_statement(lv, "nothing.")

    unsure = text({"slab_joint_opening": 0.42, "support_spring": 0.24, "settlement_step": 0.09})
    assert "The model explains" not in unsure
    assert "cannot tell whether the model explains them: slab_joint_opening is likelier" in unsure
    assert "(probability 0.42) than the model as given (settlement_step, 0.09)" in unsure
    sure = text({"settlement_step": 0.71, "support_spring": 0.29})
    assert "The model explains the response to the imposed step(s) within the jacks' accuracy" in sure


def test_the_imposed_steps_explanations_give_stiffnesses_in_kn_per_mm() -> None:
    """They printed ``support_spring_south 5.91e+06`` (N/m, no unit) and a bare joint fraction."""
    from bridge_shadow.commands.gap import _levels_lines

    rows = [
        {"effect": "slab_joint_opening", "probability": 0.82, "delta_log_evidence": 0.0},
        {"effect": "connector_stiffness", "probability": 0.13, "delta_log_evidence": -1.84},
        {"effect": "support_spring", "probability": 0.05, "delta_log_evidence": -2.85},
        {"effect": "settlement_step", "probability": 0.0, "delta_log_evidence": -35.25},
    ]
    params = [
        {"slab_joint_opening": 4.779e-4},
        {"connector_stiffness": 1.861e7},
        {"support_spring_south": 5.908e6, "support_spring_north": 1.205e7},
        {},
    ]
    levels = {
        "records": [0, 1],
        "pairs": [],
        "not_measured": [],
        "imposed": {
            "validation": "one imposed pair",
            "explanations": [{**r, "parameters": p} for r, p in zip(rows, params, strict=True)],
        },
        "steps_between_records": [],
    }
    text = "\n".join(_levels_lines(levels))
    assert "support_spring_south 5.908 kN/mm, support_spring_north 12.05 kN/mm" in text
    assert "connector_stiffness 18.61 kN/mm per m" in text
    assert "slab_joint_opening 0.0004779" in text and "1 = closed as built" in text
    assert "settlement_step" in text and "as given" in text


def test_a_long_job_off_a_terminal_says_how_far_it_is_now_and_then(monkeypatch) -> None:
    """Off a terminal ``progress`` was silent: calibrate with a day's pairs ran 5.6 minutes unsaid.

    Now a plain line once ``PLAIN_EVERY_S`` have passed since the job began or its last line, and
    "done" at the end of a job that said anything; a job done sooner says nothing.
    """
    import io

    from bridge_shadow.commands import output

    clock = [1000.0]
    monkeypatch.setattr(output.time, "monotonic", lambda: clock[0])
    monkeypatch.setattr(output, "_plain", {})  # jobs of earlier tests in this process (real clock)
    err = io.StringIO()
    monkeypatch.setattr(output.sys, "stderr", err)
    for k in range(11):  # a call every 10 s for 100 s
        output.progress(k / 10, "calibrate")
        clock[0] += 10.0
    lines = err.getvalue().splitlines()
    assert lines == [
        "calibrate: 30 % (30 s)",
        "calibrate: 60 % (60 s)",
        "calibrate: 90 % (90 s)",
        "calibrate: done (100 s)",
    ]
    err.truncate(0)
    err.seek(0)
    for k in range(3):  # 20 s in all: nothing
        output.progress(k / 2, "surrogate")
        clock[0] += 10.0
    assert err.getvalue() == ""
    # a job that never reported its end, then the same job again: it counts from its new start
    for k in range(4):
        output.progress(k / 10, "verify")
        clock[0] += 10.0
    err.truncate(0)
    err.seek(0)
    clock[0] += 1000.0
    output.progress(0.0, "verify")
    clock[0] += 40.0
    output.progress(0.5, "verify")
    assert err.getvalue().splitlines() == ["verify: 50 % (40 s)"]
