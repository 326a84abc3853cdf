"""``bridge-shadow replay``: JSON contract, outputs bag, plots, real records, errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from renamed_topics import RENAMED, renamed_bag

from bridge_shadow.cli import main
from bridge_shadow.contract import COVARIANCE_TOPIC, MEAN_TOPIC


def _replay_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict:
    assert main(["replay", *args, "--json"]) == 0
    out = capsys.readouterr().out
    return json.loads(out)


def test_replay_json_outputs_and_plots(
    root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from bridge_shadow.bagio import read_raw_topics
    from bridge_shadow.contract import FLOAT_ARRAY_TYPE

    bag = root / "bags" / "baseline_1d"
    js = _replay_json(
        capsys,
        str(bag),
        "--out",
        str(tmp_path / "out"),
        "--storage",
        "mcap",
        "--plots",
        str(tmp_path / "plots"),
    )
    mean = np.array(js["posterior"]["mean_m"])
    cov = np.array(js["posterior"]["covariance_m2"])
    assert mean.shape == (2,) and cov.shape == (2, 2)
    assert np.all(np.isfinite(mean)) and np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
    prior_sd = np.array(js["prior"]["sigma_m"])
    # the data were informative: the filter's part of the published covariance (without the
    # calibrated model's own uncertainty, mostly that of u0, which no data of the bag can narrow)
    from bridge_shadow.model.surrogate_file import load_surrogate

    data_part = cov - load_surrogate().model_covariance(mean)
    assert np.all(np.sqrt(np.diag(data_part)) < 0.2 * prior_sd)
    assert js["messages"]["used"] + js["messages"]["rejected"] == js["messages"]["total"]
    # the reasons apart: messages' add up to the rejected messages, windows' to the windows not used
    assert sum(js["messages"]["rejected_by_reason"].values()) == js["messages"]["rejected"]
    windows = js["windows"]
    assert sum(windows["rejected_by_reason"].values()) == windows["closed"] - windows["updates"]
    both = {**js["messages"]["rejected_by_reason"], **windows["rejected_by_reason"]}
    assert both == js["rejected"] and len(both) == len(js["messages"]["rejected_by_reason"]) + len(
        windows["rejected_by_reason"]
    )
    assert js["messages_per_s"] > 0 and js["windows"]["updates"] > 1000
    # end to end (bag read, start-up) is slower than the pipeline alone
    assert js["seconds"] > js["pipeline_seconds"] > 0 and js["pipeline_messages_per_s"] > js["messages_per_s"]
    for ch in ("frc_01", "frc_02"):
        assert js["spline"][ch]["edf"] >= 2.0 and js["spline"][ch]["lambda"] > 0
    # the outputs bag holds the window posteriors, the last equals the JSON
    raw = read_raw_topics(
        tmp_path / "out", {MEAN_TOPIC: FLOAT_ARRAY_TYPE, COVARIANCE_TOPIC: FLOAT_ARRAY_TYPE}
    )
    assert len(raw[MEAN_TOPIC][1]) == js["windows"]["closed"]
    from bridge_shadow.bagio import get_typestore

    last = get_typestore().deserialize_cdr(raw[MEAN_TOPIC][1][-1], FLOAT_ARRAY_TYPE)
    assert np.allclose(last.data, mean, rtol=1e-15)
    assert last.layout.dim[0].label == "support"
    # ``--storage mcap``: an integrator's MCAP tooling reads the outputs (always sqlite3 before)
    import yaml

    meta = yaml.safe_load((tmp_path / "out" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap" and len(list((tmp_path / "out").glob("*.mcap"))) == 1
    # every diagnostic value is a str meant as one or JSON another program reads (numpy reprs and
    # Python dicts went out before: ``[np.float64(-1.8e-06), ...]``, ``{'nonfinite': 7}``)
    from bridge_shadow.contract import DIAGNOSTICS_TOPIC, DIAGNOSTICS_TYPE

    diags = read_raw_topics(tmp_path / "out", {DIAGNOSTICS_TOPIC: DIAGNOSTICS_TYPE})[DIAGNOSTICS_TOPIC][1]
    statuses = [st for d in diags for st in get_typestore().deserialize_cdr(d, DIAGNOSTICS_TYPE).status]
    values = {kv.key: kv.value for st in statuses[:-1] for kv in st.values}
    final = {kv.key: kv.value for kv in statuses[-1].values}

    def strict(text: str) -> object:
        return json.loads(text, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))

    assert len(strict(values["mean_m"])) == 2 and len(strict(values["sigma_m"])) == 2
    assert isinstance(strict(values["window_end_ns"]), int) and strict(values["updated"]) in (True, False)
    assert strict(final["rejected"]) == {k: v for k, v in js["rejected"].items()}
    assert set(strict(final["spline"])) == {"frc_01", "frc_02"}
    pngs = sorted(p.name for p in (tmp_path / "plots").glob("*.png"))
    assert pngs == [
        "compensation_curve.png",
        "credible_ellipse.png",
        "posterior.png",
        "raw_vs_compensated.png",
    ]


def test_replay_same_as_pipeline_on_the_same_data(root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.estimate import Shadow, load_config
    from bridge_shadow.model.surrogate_file import load_surrogate

    bag = root / "bags" / "baseline_1d"
    js = _replay_json(capsys, str(bag))
    res = Shadow(load_config(), load_surrogate()).run(read_monitoring(bag), chunk=997)
    assert np.allclose(js["posterior"]["mean_m"], res.mean_m, rtol=1e-12, atol=0.0)
    assert np.allclose(js["posterior"]["covariance_m2"], res.covariance_m2, rtol=1e-12, atol=0.0)


def test_replay_summary_is_human_text(root: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(root / "bags" / "baseline_1d")]) == 0
    out = capsys.readouterr().out
    assert "mm" in out and "kN" in out and "south" in out and "north" in out


def test_replay_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("bridge_shadow:\n  ros__parameters:\n    window_s: -1\n")
    assert main(["replay", str(tmp_path / "nope"), "--params", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "window_s" in err and err.count("\n") == 1
    assert main(["replay", str(tmp_path / "nope"), "--rate", "2"]) == 2
    err = capsys.readouterr().err
    assert "--rate needs --live" in err and err.count("\n") == 1


def test_force_never_writes_over_the_bag_being_read(
    root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``replay BAG --out BAG --force`` replaced the records by the outputs and removed truth.yaml."""
    import hashlib
    import shutil

    bag = tmp_path / "bag"
    shutil.copytree(root / "bags" / "baseline_1d", bag)

    def digest() -> dict[str, str]:
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(bag.iterdir())}

    before = digest()
    places = ((bag, "is the input"), (bag / "out", "lies inside the input"), (tmp_path, "holds the input"))
    for out, how in places:
        for live in ([], ["--live"]):
            assert main(["replay", str(bag), "--out", str(out), "--force", *live]) == 2
            err = capsys.readouterr().err
            assert f"{out}: {how} {bag}" in err and err.count("\n") == 1, err
    assert digest() == before


@pytest.mark.realdata
def test_replay_on_the_real_records(
    munich_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """2022-04-11 reference state (12 min at 100 Hz, a test car crossing) with that day's air temperature."""
    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.importers import import_csv

    files = [
        munich_data / "Settlements" / "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip",
        munich_data / "Settlements" / "TemperatureData2022-04-11.zip",
    ]
    data, _ = import_csv(files)
    write_monitoring(tmp_path / "real", data)
    js = _replay_json(capsys, str(tmp_path / "real"), "--out", str(tmp_path / "out"))
    mean = np.array(js["posterior"]["mean_m"])
    sd = np.sqrt(np.diag(js["posterior"]["covariance_m2"]))
    assert np.all(np.isfinite(mean)) and np.all(np.isfinite(sd))
    # about 234 / 234 kN against u0 of the surrogate: a settlement of the order of a millimetre
    assert np.all(np.abs(mean) < 5e-3)
    # the data narrowed the prior (the filter's part: the calibrated model's own uncertainty,
    # mostly that of u0, is published on top and no record narrows it)
    from bridge_shadow.model.surrogate_file import load_surrogate

    cov = np.array(js["posterior"]["covariance_m2"]) - load_surrogate().model_covariance(mean)
    data_sd = np.sqrt(np.diag(cov))
    assert np.all(sd > 0) and np.all(data_sd < 0.5 * np.array(js["prior"]["sigma_m"]))
    # the test car's excursions are cut (traffic screen): the car-free windows remain
    assert js["windows"]["updates"] >= 5 and js["traffic"]["windows_cut"] >= 8
    assert js["messages"]["used"] > 100_000
    # the bag's last posterior is the replay's answer: the day's air runs on past the record, so
    # its held windows were decided at the gap and the end-of-data refit (lambda reselected) came
    # with no window output; the bag ended at the posterior before it (-0.907 mm against -0.860 mm
    # south), as the node's topics did not (``OutputBag.write_final_posterior``)
    from bridge_shadow.bagio import get_typestore, read_raw_topics
    from bridge_shadow.contract import COVARIANCE_TOPIC, FLOAT_ARRAY_TYPE, MEAN_TOPIC

    topics = (MEAN_TOPIC, COVARIANCE_TOPIC)
    raw = read_raw_topics(tmp_path / "out", dict.fromkeys(topics, FLOAT_ARRAY_TYPE))
    last = [get_typestore().deserialize_cdr(raw[t][1][-1], FLOAT_ARRAY_TYPE).data for t in topics]
    np.testing.assert_allclose(last[0], mean, rtol=1e-12, atol=0)
    np.testing.assert_allclose(last[1].reshape(2, 2), js["posterior"]["covariance_m2"], rtol=1e-12, atol=0)
    assert len(raw[MEAN_TOPIC][1]) == js["windows"]["closed"] + 1  # the windows', then that posterior


def test_topic_parameters_rename_what_replay_reads_and_writes(
    root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bag with other topic names replays with topic_* parameters and gives the same posterior."""
    import yaml

    from bridge_shadow.bagio import read_raw_topics
    from bridge_shadow.contract import FLOAT_ARRAY_TYPE

    src = root / "bags" / "baseline_1d"
    bag = renamed_bag(src, tmp_path / "renamed")
    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump({"bridge_shadow": {"ros__parameters": RENAMED}}))
    ref = _replay_json(capsys, str(src))
    got = _replay_json(capsys, str(bag), "--params", str(params), "--out", str(tmp_path / "out"))
    for key in ("mean_m", "covariance_m2", "sigma_m"):  # two runs' floats: to rounding, not bit for bit
        np.testing.assert_allclose(got["posterior"][key], ref["posterior"][key], rtol=1e-12, atol=0)
    assert got["posterior"]["state"] == ref["posterior"]["state"] and got["messages"] == ref["messages"]
    out = read_raw_topics(
        tmp_path / "out", {RENAMED["topic_mean"]: FLOAT_ARRAY_TYPE, MEAN_TOPIC: FLOAT_ARRAY_TYPE}
    )
    assert MEAN_TOPIC not in out and len(out[RENAMED["topic_mean"]][1]) == ref["windows"]["closed"]
    # without the parameters the renamed bag lacks the contract topics: one line, exit 2
    assert main(["replay", str(bag)]) == 2
    assert "missing topic(s) /bridge/frc_01/force" in capsys.readouterr().err


def test_topic_parameters_are_validated() -> None:
    from bridge_shadow.errors import ConfigError
    from bridge_shadow.estimate import ShadowConfig

    with pytest.raises(ConfigError, match="not a valid ROS topic name"):
        ShadowConfig(topic_mean="/bridge shadow/mean")
    with pytest.raises(ConfigError, match="must all be different"):
        ShadowConfig(topic_covariance=ShadowConfig().topic_mean)


def test_replay_is_loud_about_what_it_lost(
    root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """No temperature topic: uncompensated with a WARN line; every force rejected: named, exit 1."""
    import yaml

    from bridge_shadow.bagio import read_monitoring, write_monitoring
    from bridge_shadow.series import ForceSeries, MonitoringData

    bag = root / "bags" / "baseline_1d"
    params = tmp_path / "p.yaml"
    no_temp = {"bridge_shadow": {"ros__parameters": {"topic_air_temperature": "/nowhere"}}}
    params.write_text(yaml.safe_dump(no_temp))
    assert main(["replay", str(bag), "--params", str(params), "--json"]) == 0
    captured = capsys.readouterr()
    js = json.loads(captured.out)
    assert "WARN: no air temperature" in captured.err
    assert js["windows"]["uncompensated"] == js["windows"]["updates"] > 1000
    assert any("no air temperature" in w for w in js["warnings"])
    data = read_monitoring(bag)
    wrong = {
        ch: ForceSeries(f.stamp_ns, f.force_n, np.full(len(f), "load_cell", dtype=object))
        for ch, f in data.forces.items()
    }
    write_monitoring(tmp_path / "wrong", MonitoringData(wrong, data.temperature))
    assert main(["replay", str(tmp_path / "wrong")]) == 1
    err = capsys.readouterr().err
    assert "WARN: topic frc_01: all" in err and "frame_id 'load_cell', expected 'frc_01'" in err
    assert "no window updated the estimate" in err and "Traceback" not in err


def test_an_empty_plot_says_why_it_is_empty(root: Path, tmp_path: Path, monkeypatch) -> None:
    """Plots of data without air temperature, or without a window, carry a note instead of blank axes."""
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.estimate import Shadow, load_config, plots
    from bridge_shadow.series import MonitoringData

    drawn: list[list[str]] = []
    png = plots._png

    def keep(fig):  # the figure's notes, in the order drawn
        drawn.append([t.get_text() for ax in fig.axes for t in ax.texts])
        return png(fig)

    monkeypatch.setattr(plots, "_png", keep)
    data = read_monitoring(root / "bags" / "baseline_1d")
    nothing = data.select(lambda stamps: np.zeros(len(stamps), bool))
    cases = {
        "no air": MonitoringData(data.forces, nothing.temperature),
        "no force": MonitoringData(nothing.forces, data.temperature),
        "both": data.select(lambda stamps: stamps < stamps.min() + 6 * 3600 * 10**9),
    }
    notes = {}
    for name, case in cases.items():
        shadow = Shadow(load_config())
        drawn.clear()
        paths = plots.write_plots(tmp_path / name.replace(" ", "_"), shadow.run(case), shadow)
        assert all(p.stat().st_size > 1000 for p in paths)  # written, whole PNGs
        notes[name] = {p.name: texts for p, texts in zip(paths, drawn, strict=True)}
    assert notes["no air"]["compensation_curve.png"] == ["no air temperature: windows used uncompensated"] * 2
    assert notes["no air"]["posterior.png"] == []  # the windows were used
    assert notes["no force"]["compensation_curve.png"] == ["no window used"] * 2
    assert notes["no force"]["posterior.png"] == ["no window closed: the prior"] * 2
    assert notes["no force"]["raw_vs_compensated.png"] == ["no window closed"] * 2
    assert not any(notes["both"].values())  # a record with both: no note anywhere


def test_an_interrupt_while_drawing_leaves_the_plot_folder_as_it_was(
    root: Path, tmp_path: Path, monkeypatch
) -> None:
    """Ctrl-C after two of the four figures left two new PNGs beside two old ones."""
    from bridge_shadow.bagio import read_monitoring
    from bridge_shadow.estimate import Shadow, load_config, plots

    data = read_monitoring(root / "bags" / "baseline_1d")
    first = Shadow(load_config())
    folder = tmp_path / "plots"
    part = first.run(data.select(lambda stamps: stamps < stamps.min() + 6 * 3600 * 10**9))
    before = {p.name: p.read_bytes() for p in plots.write_plots(folder, part, first)}
    shadow = Shadow(load_config())
    result = shadow.run(data)  # other plots: the whole day
    png, calls = plots._png, []

    def interrupted(fig):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return png(fig)

    monkeypatch.setattr(plots, "_png", interrupted)
    with pytest.raises(KeyboardInterrupt):
        plots.write_plots(folder, result, shadow)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    monkeypatch.setattr(plots, "_png", png)
    plots.write_plots(folder, result, shadow)  # and uninterrupted, every one of them new
    assert all(p.read_bytes() != before[p.name] for p in folder.iterdir())


def test_every_rejected_window_is_listed_with_or_without_plots(
    root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``rejected_windows`` lists every window not used, as the README says, whatever is kept for plots.

    The replay streams its window outputs to ``--out`` and keeps none unless ``--plots`` asks for
    a (decimated) history: the list came from that history and was empty without ``--plots``.
    """
    from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS

    bag = str(root / "bags" / "baseline_1d")
    plain = _replay_json(capsys, bag)
    plotted = _replay_json(capsys, bag, "--plots", str(tmp_path / "plots"))
    listed = plain["rejected_windows"]
    assert listed == plotted["rejected_windows"]
    assert len(listed) == plain["windows"]["closed"] - plain["windows"]["updates"] > 0
    by_reason: dict[str, int] = {}
    for w in listed:
        by_reason[w["reason"]] = by_reason.get(w["reason"], 0) + 1
    windows_rejected = {k: v for k, v in plain["rejected"].items() if k not in MESSAGE_REASONS and v}
    assert by_reason == windows_rejected
    assert [w["window"] for w in listed] == sorted({w["window"] for w in listed})


@pytest.mark.parametrize(("window_s", "said"), [(0.01, True), (1.0, False)])
def test_windows_too_short_for_the_data_rate_are_named(window_s: float, said: bool) -> None:
    """A window as long as the sample period holds one sample: the warning says why none was used.

    At 100 Hz a 0.01 s window has one sample of each load cell, fewer than ``window_min_samples``
    (3): every window is ``sparse_window`` and the counts alone did not say that ``window_s`` is the
    cause. A 1 s window (100 samples) gets no such line.
    """
    from bridge_shadow.estimate import Shadow, load_config
    from bridge_shadow.model.surrogate_file import load_surrogate
    from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

    t0 = 1_649_658_960_000_000_000  # 2022-04-11T06:36Z
    stamp = t0 + np.arange(2000, dtype=np.int64) * 10_000_000  # 20 s at 100 Hz
    rng = np.random.default_rng(3)
    forces = {
        ch: ForceSeries(stamp, level + rng.normal(0.0, 60.0, len(stamp)), ch)
        for ch, level in (("frc_01", 2.1e5), ("frc_02", 1.9e5))
    }
    temp = TemperatureSeries(stamp[::100], np.full(20, 3.0), np.zeros(20))
    shadow = Shadow(load_config().replace(window_s=window_s), load_surrogate())
    shadow.run(MonitoringData(forces, temp))
    lines = [w for w in shadow.warnings() if w.startswith("windows too short for the data")]
    assert bool(lines) is said
    if said:
        assert "window_min_samples (3)" in lines[0] and "about 1 per window of window_s 0.01 s" in lines[0]


def test_the_plots_break_their_lines_at_the_gaps_between_records() -> None:
    """Two records 4 h apart: one NaN row between them, none inside a record (``broken_at_gaps``).

    A line through the hours between records read as the settlement sliding from one state to
    the next over 8 h of a load-test day, where the shadow reports steps.
    """
    from bridge_shadow.estimate.plots import broken_at_gaps

    w = 60 * 10**9
    end = np.concatenate([np.arange(1, 13) * w, (4 * 60 + np.arange(1, 13)) * w, [(4 * 60 + 20) * w]])
    mean = np.arange(2 * len(end), dtype=float).reshape(-1, 2)
    cov = np.ones((len(end), 2, 2))
    t, m, c = broken_at_gaps(end, 600 * 10**9, mean, cov)
    assert len(t) == len(end) + 1 and np.flatnonzero(np.isnan(t)).tolist() == [12]
    assert np.isnan(m[12]).all() and np.isnan(c[12]).all() and m.shape == (len(end) + 1, 2)
    np.testing.assert_array_equal(m[np.isfinite(t)], mean)  # every window kept, in order (copies)
    np.testing.assert_array_equal(t[np.isfinite(t)], end.astype(float))  # copies, no arithmetic
    (t2,) = broken_at_gaps(end, 7 * 3600 * 10**9)
    assert np.isfinite(t2).all()  # no gap that long: nothing broken
