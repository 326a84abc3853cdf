"""``bridge-shadow archive``: the same answer as one serial replay of the bags concatenated.

The archive is a twin record with a settlement step and bad input at every seam (see
``archive_fixtures``), cut into bags of both storages, plus a bag that cannot be read. The
reference is ``replay`` of the record written whole (without the unreadable bag). Compared:
the posterior mean and covariance (rtol 1e-10: the same floats in the same order, so only a
reordered sum could move them), every count exactly, the events, the warnings, the spline.
"""

from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from archive_fixtures import HOUR_NS, _keep, corrupt_bag, seamed_record, write_archive

from bridge_shadow.archive.join import join_bags
from bridge_shadow.archive.reduce import HEAD_WINDOWS, head_windows, reduce_bag
from bridge_shadow.estimate import load_config
from bridge_shadow.estimate.shadow import Shadow
from bridge_shadow.jsonvalues import jsonable
from bridge_shadow.model.surrogate_file import load_surrogate, placeholder_surrogate, save_surrogate
from bridge_shadow.replay import replay_bag
from bridge_shadow.series import MonitoringData, TemperatureSeries

RTOL = 1e-10


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The seamed archive (bags, the whole record, a surrogate file) and the serial reference."""
    folder = tmp_path_factory.mktemp("archive")
    data, seams = seamed_record(days=1.6)
    bags, whole = write_archive(folder, data, seams)
    bad = corrupt_bag(folder / "bridge" / "day_99_broken")
    surrogate = placeholder_surrogate()  # the twin's model: the bridge folder names it
    save_surrogate(surrogate, folder / "bridge" / "surrogate.yaml")
    config = load_config()
    ref, _ = replay_bag(whole, Shadow(config, surrogate))
    return {"folder": folder, "bags": bags, "whole": whole, "bad": bad, "ref": ref.to_json()}


def assert_same_result(got: dict[str, Any], ref: dict[str, Any]) -> None:
    """Assert that an archive's result is the serial replay's (floats to RTOL, counts exactly)."""
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(got["posterior"][key], ref["posterior"][key], rtol=RTOL, atol=0)
    assert got["messages"]["total"] == ref["messages"]["total"]
    assert got["messages"]["used_by_topic"] == ref["messages"]["used_by_topic"]
    assert got["rejected"] == ref["rejected"]
    assert got["windows"] == ref["windows"]
    assert got["warnings"] == ref["warnings"]
    assert [e["window"] for e in got["events"]] == [e["window"] for e in ref["events"]]
    for e, r in zip(got["events"], ref["events"], strict=True):
        np.testing.assert_allclose(e["size_m"], r["size_m"], rtol=RTOL, atol=0)
    for ch, sp in ref["spline"].items():
        for k, v in sp.items():
            if isinstance(v, str | bool):  # (the sun term's fit and whether the last fit used it)
                assert got["spline"][ch][k] == v, k
            else:
                np.testing.assert_allclose(got["spline"][ch][k], v, rtol=RTOL, atol=0)


def test_the_reference_holds_what_the_archive_must_survive(archive: dict[str, Any]) -> None:
    """The serial reference sees the bad input and the step (else the comparison proves little)."""
    ref = archive["ref"]
    rejected = ref["rejected"]
    for reason in ("nonfinite", "frame_id", "duplicate", "out_of_order", "clock_jump"):
        assert rejected[reason] > 0, reason
    assert ref["windows"]["stale_temperature"] > 0  # a day without temperature: used, widened
    assert len(ref["events"]) == 1
    assert ref["events"][0]["size_m"] == pytest.approx([-1e-3, -1e-3], abs=3e-4)


def test_join_of_reduced_bags_equals_serial_replay(archive: dict[str, Any]) -> None:
    """Reduced bag by bag, joined in order: the serial replay's result; which seams were re-fed and why."""
    config, surrogate = load_config(), placeholder_surrogate()
    reductions = [reduce_bag(b, config, surrogate) for b in archive["bags"]]
    shadow = Shadow(config, surrogate)
    stats = join_bags(shadow, reductions)
    assert_same_result(shadow.result([], stats.messages, 1.0).to_json(), archive["ref"])
    # day_03 has no air temperature (a fresh front end cannot know one was seen before: its windows
    # would be uncompensated, not stale): fed whole. The other seams settle in their head, day_04's
    # too once its clock jump is decided (a gate's value of a message it held and took is no state).
    assert [Path(b).name for b in stats.fed_whole] == ["day_03"]
    assert stats.windows_taken > 0.5 * archive["ref"]["windows"]["closed"]


def test_a_seam_settles_within_the_head(archive: dict[str, Any]) -> None:
    """On clean seams (mid-window, a wrong frame, a NaN, a duplicate, an outage) the head suffices.

    The records run through the seams, so each bag's fresh front end holds the first
    ``traffic_hold_s`` for the traffic screen and releases it as the archive's did: a seam
    settles a handful of windows after that hold, and without the screen a handful after the seam.
    """
    config, surrogate = load_config(), placeholder_surrogate()
    for cfg, extra in ((config.replace(traffic_hold_s=1800.0), 30), (config.replace(traffic_hold_s=0.0), 0)):
        reductions = [reduce_bag(b, cfg, surrogate) for b in archive["bags"][:3]]
        stats = join_bags(Shadow(cfg, surrogate), reductions)
        assert not stats.fed_whole
        assert stats.head_chunks < 3 * (extra + 5)  # a handful of windows per seam


def test_a_record_held_on_after_a_silence_near_a_seam_still_settles(tmp_path: Path) -> None:
    """Forces silent for 4 min, 20 min after a seam: the head follows the record the bag holds on.

    The bag's fresh front end takes the silence for a recording that started again and holds the
    record for a hold after it (``_Record.resume``), 54 min in all; the archive's front end,
    continuing a long record, does not. The head goes on while the bag's front end holds, the seam
    settles (no bag fed whole), and the result is the serial replay's.
    """
    data, seams = seamed_record(days=1.6)
    s1 = seams[0]
    minute = 60 * 10**9
    data = _keep(data, lambda log: (log >= s1 + 20 * minute) & (log < s1 + 24 * minute), lambda log: log < 0)
    bags, whole = write_archive(tmp_path, data, [s1])
    config, surrogate = load_config(), placeholder_surrogate()
    ref, _ = replay_bag(whole, Shadow(config, surrogate))
    reductions = [reduce_bag(b, config, surrogate) for b in bags]
    assert len(reductions[1].head) > head_windows(config) + 10  # the fixed head would not reach
    shadow = Shadow(config, surrogate)
    stats = join_bags(shadow, reductions)
    assert not stats.fed_whole
    assert_same_result(shadow.result([], stats.messages, 1.0).to_json(), ref.to_json())


def test_continuing_flags_follow_the_bags_log_times() -> None:
    """A bag goes on from the one before when it starts within ``gap_s`` after that one's end."""
    from bridge_shadow.archive.run import continuing_flags

    s = 10**9
    spans = [
        (0, 100 * s),
        (150 * s, 200 * s),
        (900 * s, 950 * s),
        (None, None),
        (960 * s, 990 * s),
        (980 * s, 999 * s),
    ]
    # the first never; 50 s after: yes; 700 s after: no (gap_s 600); after an unreadable bag: no;
    # overlapping the one before (starts before its end): no
    assert continuing_flags(spans, 600.0) == [False, True, False, False, False, False]
    assert continuing_flags(spans, 60.0)[1] and not continuing_flags(spans, 40.0)[1]


def test_overlapping_spans_make_units_of_bags() -> None:
    """Bags in time order that overlap (connected, through the latest end so far) are one unit."""
    from bridge_shadow.archive.tasks import overlap_units

    s = 10**9
    spans = [
        (0, 100 * s),  # a long air bag ...
        (10 * s, 20 * s),  # ... overlaps this one
        (50 * s, 60 * s),  # ... and this one, though not the one before it
        (100 * s, 150 * s),  # begins at the very end: not an overlap
        (120 * s, 130 * s),
        (200 * s, 300 * s),
        (None, None),  # unreadable: on its own
    ]
    assert overlap_units(spans) == [[0, 1, 2], [3, 4], [5], [6]]
    assert overlap_units([]) == []


def test_a_bag_that_goes_on_from_the_one_before_settles_before_the_hold(archive: dict[str, Any]) -> None:
    """A long record runs through seam 1: a bag reduced as continuing settles within ``HEAD_WINDOWS``.

    Its front end starts in a released record (``reduce_bag(continuing=True)``, what the bags' log
    times say: ``continuing_flags``), as the archive's is there, instead of holding the hold's 30
    windows; a wrong guess (seam 2, after a 3 h outage) settles as a fresh bag would, later.
    """
    from bridge_shadow.archive.run import continuing_flags
    from bridge_shadow.archive.tasks import bag_span_task

    config, surrogate = load_config(), placeholder_surrogate()
    bags = archive["bags"][:3]
    flags = continuing_flags([bag_span_task(str(b), config) for b in bags], config.gap_s)
    assert flags == [False, True, False]
    seam1, seam2 = {}, {}
    for guess in (False, True):  # bags 1 and 2 reduced as continuing, or not
        reductions = [
            reduce_bag(b, config, surrogate, continuing=guess and i > 0) for i, b in enumerate(bags)
        ]
        n = [join_bags(Shadow(config, surrogate), reductions[:k]) for k in (1, 2, 3)]
        assert not any(st.fed_whole for st in n)  # a wrong guess (seam 2) settles too
        seam1[guess] = n[1].head_chunks - n[0].head_chunks
        seam2[guess] = n[2].head_chunks - n[1].head_chunks
    hold = head_windows(config) - HEAD_WINDOWS
    assert seam1[True] <= HEAD_WINDOWS < hold < seam1[False]
    assert seam2[True] > hold  # seam 2 starts a record: the guess is wrong, and only costs time


@pytest.mark.parametrize("workers", [1, 2, 4])
def test_archive_on_dask_equals_serial_replay(archive: dict[str, Any], tmp_path: Path, workers: int) -> None:
    """On 1, 2 and 4 workers (threads here), with an unreadable bag named and skipped."""
    from bridge_shadow.archive.run import plan_bridges, run_archive
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.engine import dask_client

    plans = plan_bridges(archive_sources(str(archive["folder"] / "bridge")))
    with dask_client(workers=workers, processes=False) as client:
        run = run_archive(client, plans, tmp_path / "cache")
    (bridge,) = run.bridges
    assert_same_result(bridge.result, archive["ref"])
    assert [Path(b).name for b, _ in bridge.failed] == ["day_99_broken"]
    assert "day_99_broken" in bridge.failed[0][1]
    assert run.workers == workers
    rows = bridge.rows
    assert rows[-1]["mean_south_m"] == pytest.approx(archive["ref"]["posterior"]["mean_m"][0], rel=RTOL)
    ends = [r["end_ns"] for r in rows]
    assert ends == sorted(ends) and len(ends) > 24  # one row an hour over 1.6 days, less the outage


def test_cli_reruns_from_the_cache_and_names_the_broken_bag(
    archive: dict[str, Any], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The command on a local process cluster, then on a running scheduler, where the rerun reads no bag."""
    from bridge_shadow.cli import main
    from bridge_shadow.engine import dask_client

    out = tmp_path / "out"
    argv = ["archive", str(archive["folder"] / "bridge"), "--out", str(out), "--json"]
    assert main([*argv, "--workers", "2"]) == 0  # the default engine: a local cluster of processes
    first = capsys.readouterr()
    with dask_client(workers=2, processes=False) as client:  # a running scheduler, as on a cluster
        # a rerun: every readable bag from the cache
        assert main([*argv, "--scheduler", client.scheduler.address]) == 0
        again = json.loads(capsys.readouterr().out)
    js = json.loads(first.out)
    assert_same_result(js["bridges"]["bridge"], archive["ref"])
    assert js["bags"] == {"reduced": 5, "cached": 0, "failed": 1}
    # the surrogate block as replay's (its condition number was missing)
    got, want = js["bridges"]["bridge"]["surrogate"], jsonable(placeholder_surrogate().summary())
    assert set(got) == set(want) and got["A"] == want["A"] and got["u0"] == want["u0"]  # as the file holds
    assert got["condition_number"] == pytest.approx(want["condition_number"], rel=1e-12)
    assert "skipped bag" in first.err and "day_99_broken" in first.err
    index = json.loads((out / "index.json").read_text())
    assert index["failed_bags"][0]["bag"].endswith("day_99_broken")
    assert (out / "summary.png").stat().st_size > 0
    header = (out / "summary.csv").read_text().splitlines()[0]
    assert header.startswith("bridge,time_utc,end_ns")
    saved = json.loads((out / "bridges" / "bridge.json").read_text())
    assert_same_result(saved, archive["ref"])
    assert again["bags"] == {"reduced": 0, "cached": 5, "failed": 1}
    assert_same_result(again["bridges"]["bridge"], archive["ref"])
    assert not list(out.rglob("*.tmp"))


def test_a_changed_bag_is_reduced_again(archive: dict[str, Any], tmp_path: Path) -> None:
    """The cache is keyed by content: a bag rewritten with other data is not taken from it."""
    from bridge_shadow.archive.tasks import reduce_task

    config, surrogate = load_config(), placeholder_surrogate()
    bag = tmp_path / "bag"
    shutil.copytree(archive["bags"][0], bag)
    assert reduce_task(str(bag), config, surrogate, str(tmp_path / "c")).status == "reduced"
    assert reduce_task(str(bag), config, surrogate, str(tmp_path / "c")).status == "cached"
    shutil.rmtree(bag)
    shutil.copytree(archive["bags"][1], bag)
    assert reduce_task(str(bag), config, surrogate, str(tmp_path / "c")).status == "reduced"
    # other front-end parameters: a new key
    other = config.replace(window_s=30.0)
    assert reduce_task(str(bag), other, surrogate, str(tmp_path / "c")).status == "reduced"
    # a surrogate or an event threshold acts after the windows: the same entry
    later = config.replace(event_probability=0.99)
    assert reduce_task(str(bag), later, surrogate, str(tmp_path / "c")).status == "cached"


def _listening() -> list[str]:
    """The addresses this process listens on (TCP)."""
    import psutil

    return [c.laddr.ip for c in psutil.Process().net_connections(kind="tcp") if c.status == "LISTEN"]


@pytest.mark.parametrize("processes", [True, False])
def test_the_engine_listens_on_loopback_only(processes: bool) -> None:
    """The local cluster (processes by default): workers, scheduler and their HTTP servers on 127.0.0.1."""
    import os

    from bridge_shadow.engine import dask_client

    with dask_client(workers=2, processes=processes) as client:
        assert set(client.nthreads().values()) == {1}
        addresses = _listening() + [a for ips in client.run(_listening).values() for a in ips]
        assert addresses and set(addresses) == {"127.0.0.1"}, addresses
        if processes:
            workers = client.scheduler_info()["workers"]
            assert len(workers) == 2 and all(a.startswith("tcp://127.0.0.1:") for a in workers)
            pids = set(client.run(os.getpid).values())
            assert len(pids) == 2 and os.getpid() not in pids


def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A missing archive, an empty folder, a broken manifest, an unreachable scheduler: exit 2, one line."""
    from bridge_shadow import engine
    from bridge_shadow.cli import main

    (tmp_path / "empty").mkdir()
    (tmp_path / "m.yaml").write_text("bridges: [1, 2]\n")
    cases = [
        [str(tmp_path / "missing")],
        [str(tmp_path / "empty")],
        [str(tmp_path / "m.yaml")],
        [str(tmp_path / "nothing_*")],
    ]
    for case in cases:
        assert main(["archive", *case, "--out", str(tmp_path / "o")]) == 2, case
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("bridge-shadow archive: error:"), (case, err)
    engine.CONNECT_TIMEOUT_S = 0.5
    try:
        bag = Path(__file__).parent.parent / "bags" / "baseline_1d"
        assert (
            main(["archive", str(bag), "--out", str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:9"]) == 2
        )
    finally:
        engine.CONNECT_TIMEOUT_S = 10.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot reach the Dask scheduler" in err[0]
    assert not (tmp_path / "o").exists()


def _concatenated(bags: list[Path], out: Path) -> Path:
    """Write the bags' messages, bag after bag, as one bag (the serial reference of an archive)."""
    from bridge_shadow.bagio import read_monitoring, write_monitoring
    from bridge_shadow.series import ForceSeries, MonitoringData, TemperatureSeries

    parts = [read_monitoring(b) for b in bags]
    forces = {
        ch: ForceSeries(
            *(
                np.concatenate([getattr(p.forces[ch], f) for p in parts])
                for f in ("stamp_ns", "force_n", "frame_id", "log_ns")
            )
        )
        for ch in parts[0].forces
    }
    fields = ("stamp_ns", "temp_c", "variance", "frame_id", "log_ns")
    temp = TemperatureSeries(*(np.concatenate([getattr(p.temperature, f) for p in parts]) for f in fields))
    return write_monitoring(out, MonitoringData(forces, temp))


def test_bundled_bags_as_bridges_equal_their_replays(root: Path, tmp_path: Path) -> None:
    """A manifest of the bundled bags, one bridge each: every bridge's result is ``replay`` of its bag."""
    from bridge_shadow.archive.run import plan_bridges, run_archive
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.engine import dask_client

    names = ["demo_3d", "baseline_1d"]  # MCAP zstd and sqlite3; scour_3d adds nothing new
    manifest = tmp_path / "bundled.yaml"
    manifest.write_text("bridges:\n" + "".join(f"  {n}:\n    bags: [{root / 'bags' / n}]\n" for n in names))
    plans = plan_bridges(archive_sources(str(manifest)))
    with dask_client(workers=2, processes=False) as client:
        run = run_archive(client, plans, tmp_path / "cache")
    for bridge, name in zip(run.bridges, names, strict=True):
        ref, _ = replay_bag(root / "bags" / name, Shadow(load_config(), load_surrogate()))
        assert_same_result(bridge.result, ref.to_json())


def test_a_synth_fleet_equals_serial_replay_per_bridge(tmp_path: Path) -> None:
    """``synth --archive``, two bridges in daily bags: each is the replay of its bags concatenated."""
    from bridge_shadow.archive.run import plan_bridges, run_archive
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.cli import main
    from bridge_shadow.engine import dask_client

    fleet = tmp_path / "fleet"
    argv = ["synth", "--archive", str(fleet), "--bridges", "2", "--days", "1.5", "--rate", "0.05"]
    assert main([*argv, "--step", "0.8:-0.001:-0.0005"]) == 0
    # the second bridge runs without the (shipped) sun term; the first with it: its covariate's
    # state crosses the daily seams too
    sun = fleet / "bridge_01" / "shadow.yaml"
    sun.write_text("bridge_shadow:\n  ros__parameters:\n    sun_gradient: false\n")
    plans = plan_bridges(archive_sources(str(fleet)))
    assert [p.source.name for p in plans] == ["bridge_00", "bridge_01"]
    with dask_client(workers=2, processes=False) as client:
        run = run_archive(client, plans, tmp_path / "cache")
    for bridge, plan in zip(run.bridges, plans, strict=True):
        whole = _concatenated(sorted(plan.source.bags), tmp_path / f"whole_{bridge.name}")
        config = load_config(sun) if bridge.name == "bridge_01" else load_config()
        assert config.sun_gradient == (bridge.name == "bridge_00")
        ref, _ = replay_bag(whole, Shadow(config, load_surrogate()))
        assert_same_result(bridge.result, ref.to_json())
        assert len(bridge.result["events"]) >= 1  # the step, through a seam-free day
        assert not bridge.fed_whole
        assert ("sun_gradient_k" in bridge.result["spline"]["frc_01"]) == config.sun_gradient


def test_a_wrong_expected_order_is_caught(
    archive: dict[str, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The join takes bags in the expected order as they come; a bag found earlier makes it start over."""
    from bridge_shadow.archive import run as run_module
    from bridge_shadow.archive.run import plan_bridges, run_archive
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.archive.tasks import bag_span_task
    from bridge_shadow.engine import dask_client

    def reversed_span(bag: str, config: Any) -> tuple[int | None, int | None]:
        first, last = bag_span_task(bag, config)
        return (None, None) if first is None or last is None else (-last, -first)

    monkeypatch.setattr(run_module, "bag_span_task", reversed_span)
    plans = plan_bridges(archive_sources(str(archive["folder"] / "bridge")))
    with dask_client(workers=2, processes=False) as client:
        run = run_archive(client, plans, tmp_path / "cache")
    assert_same_result(run.bridges[0].result, archive["ref"])


def test_ctrl_c_leaves_whole_files_only(
    archive: dict[str, Any],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Interrupted while writing its outputs: exit 130, no temporary file, every cache entry readable."""
    import pickle

    from bridge_shadow.archive import summary
    from bridge_shadow.cli import main
    from bridge_shadow.engine import dask_client

    def interrupted(path: Path, rows: list) -> Path:
        raise KeyboardInterrupt

    monkeypatch.setattr(summary, "plot_summary", interrupted)
    out = tmp_path / "out"
    with dask_client(workers=2, processes=False) as client:
        argv = ["archive", str(archive["folder"] / "bridge"), "--out", str(out), "--json"]
        assert main([*argv, "--scheduler", client.scheduler.address]) == 130
    assert capsys.readouterr().err.strip().endswith("interrupted")
    assert not list(out.rglob("*.tmp")) and not (out / "index.json").exists()
    entries = list((out / "cache").glob("*.pkl"))
    assert len(entries) == 5
    for entry in entries:
        with entry.open("rb") as f:
            assert pickle.load(f).end is not None


@pytest.mark.parametrize("bag", ["baseline_1d", "demo_3d"])
def test_a_truncated_bag_is_named_not_raised(root: Path, tmp_path: Path, bag: str) -> None:
    """A bag cut short (sqlite3 or MCAP) fails its own task with one line naming it; the cache stays empty."""
    from bridge_shadow.archive.tasks import reduce_task

    copy = tmp_path / bag
    shutil.copytree(root / "bags" / bag, copy)
    storage = next(p for p in copy.iterdir() if p.suffix in (".db3", ".mcap"))
    with storage.open("r+b") as f:
        f.truncate(storage.stat().st_size // 3)
    out = reduce_task(str(copy), load_config(), load_surrogate(), str(tmp_path / "cache"))
    assert out.status == "failed" and out.error.startswith(str(copy)) and "\n" not in out.error
    assert not list((tmp_path / "cache").glob("*.pkl"))


def test_sources_folder_glob_and_manifest(archive: dict[str, Any], tmp_path: Path) -> None:
    """The three ways to name an archive give the same bridge and bags (the broken one included)."""
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.errors import InputError

    folder = archive["folder"] / "bridge"
    (by_folder,) = archive_sources(str(folder))
    (by_glob,) = archive_sources(str(folder / "day_*"))
    manifest = tmp_path / "m.yaml"
    manifest.write_text(
        f"bridges:\n  bridge:\n    bags: ['{folder}/day_*']\n    surrogate: {folder}/surrogate.yaml\n"
    )
    (by_manifest,) = archive_sources(str(manifest))
    names = sorted(p.name for p in by_folder.bags)
    assert names == [f"day_{i:02d}" for i in range(5)] + ["day_99_broken"]
    for src in (by_glob, by_manifest):
        assert src.name == "bridge" and sorted(p.name for p in src.bags) == names
    assert by_folder.surrogate == folder / "surrogate.yaml" == by_manifest.surrogate
    # a manifest's name names the output files: '/abs' and '../x' wrote outside --out before
    for name in ("/tmp/abs", "../x", "a/b", ".hidden", ""):
        manifest.write_text(f"bridges:\n  '{name}':\n    bags: ['{folder}/day_*']\n")
        with pytest.raises(InputError, match="a bridge's name names its output files"):
            archive_sources(str(manifest))
    manifest.write_text(f"bridges:\n  2022.b-1_x:\n    bags: ['{folder}/day_*']\n")
    assert archive_sources(str(manifest))[0].name == "2022.b-1_x"
    # a bag named twice (a glob and the bag itself, or a relative and an absolute path) is taken
    # once, in the order first named: fed twice, its messages were rejected and a dead cell warned of
    manifest.write_text(
        f"bridges:\n  b:\n    bags: ['{folder}/day_03', '{folder}/day_*', '{folder}/../bridge/day_01']\n"
    )
    (twice,) = archive_sources(str(manifest))
    assert [p.name for p in twice.bags] == ["day_03", "day_00", "day_01", "day_02", "day_04", "day_99_broken"]


#: A valid other value for every parameter the cache key leaves out (``cache.ESTIMATOR_ONLY``).
OTHER_VALUES: dict[str, Any] = {
    "smoothing": "gcv",
    "spline_lambda": 3.0,
    "spline_t_min_c": -25.0,
    "spline_t_max_c": 40.0,
    "spline_segments": 9,
    "thermal_prior_sd_n_per_k": 300.0,
    "sun_gradient": True,
    "sun_gradient_prior_mean_k": 2.0,
    "sun_gradient_prior_sd_k": 5.0,
    "sun_gradient_min_bayes_factor": 0.0,
    "sun_gradient_fit": "deck",
    "relaxation_phi0": 1.5,
    "relaxation_horizon_s": 600.0,
    "warmup_windows": 4,
    "refit_windows": 30,
    "lambda_reselect_growth": 1.5,
    "prior_sigma_m": [1e-3, 2e-3],
    "prior_rule": "both",
    "process_noise_m2_per_s": [1e-13, 1e-13],
    "drift_block_s": 3600.0,
    "noise_sigma_n": [50.0, 70.0],
    "systematic_sigma_n": [10.0, 10.0],
    "noise_mode": "fixed",
    "noise_phi_max": 0.99,
    "noise_floor": False,
    "event_detection": False,
    "event_trigger_probability": 0.99,
    "event_probability": 0.9999,
    "event_confirm_windows": 3,
    "event_max_pending": 10,
    "event_jump_rule": "prior",
    "mahalanobis_probability": 0.9999,
    "checkpoint_path": "",
    "checkpoint_period_s": 60.0,
    "checkpoint_unusable": "fresh",
    "surrogate_path": "",
    "qos_depth": 10,
    "diagnostics_period_s": 2.0,
    "topic_mean": "/other/mean",
    "topic_covariance": "/other/covariance",
    "topic_compensated_frc_01": "/other/c1",
    "topic_compensated_frc_02": "/other/c2",
}


def test_what_the_cache_key_leaves_out_leaves_the_reduction_as_it_is(root: Path) -> None:
    """Any parameter outside the key, changed alone: the same windows and front end (cache hits are right)."""
    from bridge_shadow.archive.cache import ESTIMATOR_ONLY, front_key
    from bridge_shadow.archive.frontstate import same_behaviour

    assert set(OTHER_VALUES) == ESTIMATOR_ONLY
    config, surrogate = load_config(), load_surrogate()
    bag = root / "bags" / "baseline_1d"
    ref = reduce_bag(bag, config, surrogate)
    for name, value in OTHER_VALUES.items():
        other = config.replace(**{name: value})
        assert front_key(other) == front_key(config), name
        red = reduce_bag(bag, other, surrogate)
        assert same_behaviour(red.end, ref.end) and red.end.counts == ref.end.counts, name
        np.testing.assert_array_equal(red.windows.k, ref.windows.k, err_msg=name)  # integer indices
        # window means, computed again: to rounding (another CPU or numpy build differs by an ulp)
        np.testing.assert_allclose(red.windows.force_n, ref.windows.force_n, rtol=1e-12, atol=0, err_msg=name)
        np.testing.assert_allclose(red.windows.temp_c, ref.windows.temp_c, rtol=1e-12, atol=0, err_msg=name)
        assert red.windows.reason.tolist() == ref.windows.reason.tolist(), name


def test_a_bag_rewritten_with_its_size_and_mtime_kept_is_hashed_again(tmp_path: Path, monkeypatch) -> None:
    """``cp -p``, ``tar -x`` or a restore: new bytes, the same size, the old mtime.

    The cache's stat record (name, size, mtime) took the file for unchanged and served the old
    reduction, joined to the new file's rest: a posterior of neither version. The record now holds
    the change time and the inode too, which a rewrite moves and no user tool sets back.
    """
    import os

    from bridge_shadow.archive import cache as cache_mod

    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    data = bag / "bag_0.db3"
    data.write_bytes(b"a" * 4096)
    cache = cache_mod.ReductionCache(tmp_path / "cache")
    hashed = []
    real = cache_mod.bag_digest
    monkeypatch.setattr(cache_mod, "bag_digest", lambda b: hashed.append(b) or real(b))
    first = cache.digest(bag)
    assert cache.digest(bag) == first and len(hashed) == 1  # unchanged: the stat record serves it
    st = data.stat()
    data.write_bytes(b"b" * 4096)  # the same size ...
    os.utime(data, ns=(st.st_atime_ns, st.st_mtime_ns))  # ... and the old mtime
    assert data.stat().st_size == st.st_size and data.stat().st_mtime_ns == st.st_mtime_ns
    again = cache.digest(bag)
    assert again != first and again == real(bag) and len(hashed) == 2


def test_bags_that_overlap_in_time_are_read_merged(
    root: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A day's forces and its air temperature as two bags of one bridge: read merged, nothing lost.

    The join took a bridge's bags one after the other, so the later bag's messages before the
    earlier one's end were rejected (this day: 8586 of 10050 late, 3 window updates instead of
    1429, exit 1). Bags that overlap in time are now one unit read merged by log time: the result
    is ``replay`` of the one bag holding everything, exit 0, and the overlap is named as
    information (``overlapping_bags`` with ``merged``, an info line, not a warning).
    """
    from bridge_shadow.bagio import read_monitoring, write_monitoring
    from bridge_shadow.cli import main
    from bridge_shadow.engine import dask_client
    from bridge_shadow.series import MonitoringData

    whole = root / "bags" / "baseline_1d"
    data = read_monitoring(whole)
    nothing = data.select(lambda stamps: np.zeros(len(stamps), bool))
    bridge = tmp_path / "bridge"
    write_monitoring(bridge / "forces", MonitoringData(data.forces, nothing.temperature))
    write_monitoring(bridge / "air", MonitoringData(nothing.forces, data.temperature), "mcap")
    ref, _ = replay_bag(whole, Shadow(load_config(), load_surrogate()))
    argv = ["archive", str(bridge), "--out", str(tmp_path / "out"), "--json"]
    with dask_client(workers=1, processes=False) as client:  # a scheduler of this process
        assert main([*argv, "--scheduler", client.scheduler.address]) == 0
    out = capsys.readouterr()
    assert "error" not in out.err and "WARN: bridge: bags overlap" not in out.err
    assert "info: bridge: bags overlap in time" in out.err and "read together" in out.err
    js = json.loads(out.out)["bridges"]["bridge"]
    (overlap,) = js["overlapping_bags"]
    assert overlap["merged"] is True
    assert {Path(overlap["bag"]).name, Path(overlap["before"]).name} == {"forces", "air"}
    assert [sorted(Path(b).name for b in unit) for unit in js["merged_bags"]] == [["air", "forces"]]
    assert js["rejected"]["late"] == 0 and js["rejected"]["out_of_order"] == 0
    assert_same_result(js, ref.to_json())
    assert js["windows"]["updates"] > 1000


def test_an_air_bag_spanning_several_records_is_merged_with_them(
    archive: dict[str, Any], tmp_path: Path
) -> None:
    """The seamed archive with the air temperature of two records (9.6 h) in a bag of its own.

    Its bag overlaps the two force bags, which overlap nothing else: the three are one unit read
    merged; the bags before and after go as before. The result is the serial replay's (rtol
    1e-10, counts exactly, nothing late for the overlap); a rerun takes the unit from the cache,
    and a change to any bag of the unit (the air's) reduces it again.
    """
    from archive_fixtures import cut

    from bridge_shadow.archive.run import plan_bridges, run_archive
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.engine import dask_client
    from bridge_shadow.series import MonitoringData

    data, seams = seamed_record(days=1.6)
    parts = cut(data, seams)
    bridge = tmp_path / "bridge"
    none = data.select(lambda stamps: np.zeros(len(stamps), bool))

    def air_of(*ps: MonitoringData) -> MonitoringData:
        keep = np.isin(data.temperature.log_ns, np.concatenate([p.temperature.log_ns for p in ps]))
        return _only_air(data, keep, none)

    write_monitoring(bridge / "day_00", parts[0])
    write_monitoring(bridge / "day_01_forces", MonitoringData(parts[1].forces, none.temperature), "mcap")
    write_monitoring(bridge / "day_02_forces", MonitoringData(parts[2].forces, none.temperature))
    write_monitoring(bridge / "air_01_02", air_of(parts[1], parts[2]), "mcap")
    write_monitoring(bridge / "day_03", parts[3], "mcap")
    write_monitoring(bridge / "day_04", parts[4])
    save_surrogate(placeholder_surrogate(), bridge / "surrogate.yaml")
    plans = plan_bridges(archive_sources(str(bridge)))
    with dask_client(workers=2, processes=False) as client:
        run = run_archive(client, plans, tmp_path / "cache")
        (b,) = run.bridges
        assert_same_result(b.result, archive["ref"])
        (unit,) = b.result["merged_bags"]
        assert sorted(Path(x).name for x in unit) == ["air_01_02", "day_01_forces", "day_02_forces"]
        assert len(b.result["overlapping_bags"]) == 2 and all(
            o["merged"] for o in b.result["overlapping_bags"]
        )
        assert not [w for w in b.result["warnings"] if "overlap" in w]
        assert len(b.result["bags"]) == 6
        statuses = {Path(o.bag).name: o.status for o in run.bags["bridge"]}
        assert len(statuses) == 4 and set(statuses.values()) == {"reduced"}
        # a rerun: every unit from the cache; the air changed: its unit again, the others cached
        again = run_archive(client, plans, tmp_path / "cache")
        assert {o.status for o in again.bags["bridge"]} == {"cached"}
        air = air_of(parts[1], parts[2])
        air.temperature.temp_c = air.temperature.temp_c + 0.5
        write_monitoring(bridge / "air_01_02", air, "mcap", overwrite=True)
        third = run_archive(client, plans, tmp_path / "cache")
    changed = {Path(x).name for o in third.bags["bridge"] if o.status == "reduced" for x in o.members}
    assert changed == {"air_01_02", "day_01_forces", "day_02_forces"}
    assert [o.status for o in third.bags["bridge"] if not o.merged] == ["cached"] * 3


def test_a_corrupt_bag_among_overlapping_ones_costs_only_itself(tmp_path: Path) -> None:
    """A record whose chunks are corrupt (it opens, its messages do not decompress) is dropped alone.

    The air of two records in a bag of its own joins them into one unit; one of the two force
    bags is a compressed MCAP with bytes overwritten in its middle. The whole unit was skipped
    (the good record and the air lost, 0 of their messages used) and the good first bag named as
    the failed one. Now the unit is reduced again without the corrupt bag: it alone is named and
    counted failed, the other record's forces and the air are used.
    """
    from archive_fixtures import cut

    from bridge_shadow.archive.run import plan_bridges, run_archive, write_outputs
    from bridge_shadow.archive.sources import archive_sources
    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.engine import dask_client
    from bridge_shadow.series import MonitoringData

    data, seams = seamed_record(days=1.6)
    parts = cut(data, seams)
    bridge = tmp_path / "bridge"
    none = data.select(lambda stamps: np.zeros(len(stamps), bool))
    keep = np.isin(
        data.temperature.log_ns, np.concatenate([parts[1].temperature.log_ns, parts[2].temperature.log_ns])
    )
    write_monitoring(bridge / "day_01_forces", MonitoringData(parts[1].forces, none.temperature))
    broken = write_monitoring(
        bridge / "day_02_forces", MonitoringData(parts[2].forces, none.temperature), "mcap", compress=True
    )
    write_monitoring(bridge / "air_01_02", _only_air(data, keep, none), "mcap")
    mcap = next(Path(broken).glob("*.mcap"))
    raw = bytearray(mcap.read_bytes())
    rng = np.random.default_rng(1)
    for off in range(len(raw) // 3, 2 * len(raw) // 3, 997):
        raw[off : off + 16] = rng.bytes(16)
    mcap.write_bytes(bytes(raw))
    save_surrogate(placeholder_surrogate(), bridge / "surrogate.yaml")
    plans = plan_bridges(archive_sources(str(bridge)))
    with dask_client(workers=1, processes=False) as client:
        run = run_archive(client, plans, tmp_path / "cache")
    (b,) = run.bridges
    assert [Path(f).name for f, _ in b.failed] == ["day_02_forces"]
    assert "corrupt" in b.failed[0][1]
    read = sum(len(f.log_ns) for f in parts[1].forces.values()) + int(keep.sum())
    assert b.result["messages"]["total"] == read  # the good record and the air, every message read
    assert b.result["windows"]["updates"] > 100
    assert sorted(Path(x).name for x in b.result["bags"]) == ["air_01_02", "day_01_forces"]
    assert not [o for o in b.result["overlapping_bags"] if "day_02_forces" in (o["bag"], o["before"])]
    index = write_outputs(tmp_path / "out", run, plans, tmp_path / "cache")
    assert index["bags"] == {"reduced": 2, "cached": 0, "failed": 1}  # per bag, not per unit


def _only_air(data: Any, keep: np.ndarray, none: Any) -> Any:
    from bridge_shadow.series import MonitoringData, TemperatureSeries

    t = data.temperature
    air = TemperatureSeries(
        t.stamp_ns[keep], t.temp_c[keep], t.variance[keep], t.frame_id[keep], t.log_ns[keep]
    )
    return MonitoringData(none.forces, air)


@pytest.mark.realdata
def test_the_summary_counts_the_events_confirmed_across_a_gap(munich_data: Path) -> None:
    """The real pair: its one event is a change across the gap, which marks no window output.

    The summary's ``events`` column counted marked outputs and read 0 on every row of a load-test
    day; it counts the shadow's events that began up to each row.
    """
    from bridge_shadow.archive.summary import PeriodicRows
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    sc = build(munich_data / "Settlements", sur.A, [Piece("ref", 0.0), Piece("lowered", 0.733)])
    shadow = Shadow(load_config(), sur)
    result = shadow.run(sc.data)
    (event,) = shadow.event_records()
    assert event.kind == "gap" and not any(out.event for out in result.outputs)
    rows = PeriodicRows("bridge", 600.0)
    rows.add(result.outputs)
    table = rows.finish(shadow)
    assert [r["events"] for r in table] == [int(r["end_ns"] >= event.time_ns) for r in table]
    assert table[0]["events"] == 0 and table[-1]["events"] == 1


def _records_hours_apart(tmp_path: Path) -> tuple[list[Path], Path]:
    """Four 12-minute records hours apart, one bag each, as a load-test day's real records come.

    Each bag holds its record's forces and the air only near them (``import-csv
    --air-near-forces``): the first from the forces' first sample; the second from 25 s before
    them, after the start of their first window (a reading the previous record's last one
    brackets in a serial replay); the third from 50 s before them, before that start; the fourth
    from 15 s *after* them (its first forces rest on the third record's last reading in a serial
    replay, which the bag's own front end never saw). Every record is shorter than
    ``traffic_hold_s``: its own front end closes no window before the record ends.
    """
    from bridge_shadow.twin.simulate import simulate

    data, _ = simulate(
        days=0.5, rate_hz=2.0, seed=3, steps=[(0.2, -1e-3, -1e-3)], surrogate=placeholder_surrogate()
    )
    t = data.temperature
    minute = 60 * 10**9
    shift = 20 * 10**9 - int(t.stamp_ns[0]) % minute  # the air logger's readings 20 s past the minute
    data = MonitoringData(
        data.forces, TemperatureSeries(t.stamp_ns + shift, t.temp_c, t.variance, t.frame_id, t.log_ns + shift)
    )
    t0 = -(-int(data.forces["frc_01"].log_ns[0]) // minute) * minute
    spans = [
        (t0 + h * HOUR_NS + off * 10**9, lead * 10**9)
        for h, off, lead in ((1, 0, 0), (3, 40, 25), (7, 10, 50), (8.5, 30, -15))
    ]
    force_in = lambda log: np.any([(log >= a) & (log < a + 12 * minute) for a, _ in spans], axis=0)  # noqa: E731
    air_in = lambda log: np.any([(log >= a - lead) & (log < a + 12 * minute) for a, lead in spans], axis=0)  # noqa: E731
    data = _keep(data, lambda log: ~force_in(log), lambda log: ~air_in(log))
    seams = [a - lead - 30 * minute for a, lead in spans[1:]]
    bags, whole = write_archive(tmp_path, data, seams)
    return bags, whole


def test_records_hours_apart_are_joined_from_their_windows(tmp_path: Path) -> None:
    """Bags of records hours apart settle at their seams, and the result is the serial replay's.

    The archive's front end holds the previous record's last air reading and knows it saw a
    reading before; each bag's own holds neither (it closed no window, so forgot nothing). Neither
    is read by a window still to close: the seam compares the buffers less those
    (``WindowBuffer.behaviour_state``). Only the bag whose forces start before its air is fed
    whole: the serial replay matches its first forces to the previous record's last reading.
    """
    bags, whole = _records_hours_apart(tmp_path)
    config, surrogate = load_config(), placeholder_surrogate()
    assert config.traffic_hold_s > 12 * 60
    ref, _ = replay_bag(whole, Shadow(config, surrogate), keep_all=True)
    reductions = [reduce_bag(b, config, surrogate) for b in bags]
    shadow = Shadow(config, surrogate)
    outputs: list[Any] = []
    stats = join_bags(shadow, reductions, on_outputs=outputs.extend)
    assert [Path(b).name for b in stats.fed_whole] == ["day_03"]
    # each other seam settles within a few chunks of the bag's head (the bag is read once)
    assert stats.head_chunks - len(reductions[3].head) <= 3 * len(bags) < sum(len(r.head) for r in reductions)
    assert_same_result(shadow.result([], stats.messages, 1.0).to_json(), ref.to_json())
    assert_same_outputs(outputs, ref.outputs)


def assert_same_outputs(got: list[Any], ref: list[Any]) -> None:
    """Assert that the archive's window outputs are the serial replay's, window by window.

    The archive's join took each bag's windows in one batch and decided a record that ends in its
    bag only when the next record's first window came (``Shadow._process``): the whole first
    record of a judge's four-record day published the jump prior's width (+-18.5 mm, where replay's
    polls had said +-1.9 mm) though the final answers agreed. Now both decide at the gap.
    """
    assert [o.index for o in got] == [o.index for o in ref]
    for g, r in zip(got, ref, strict=True):
        assert (g.updated, g.reason, g.event) == (r.updated, r.reason, r.event), g.index
        at = f"window {g.index}"
        np.testing.assert_allclose(g.mean_m, r.mean_m, rtol=RTOL, atol=1e-15, err_msg=at)
        np.testing.assert_allclose(g.covariance_m2, r.covariance_m2, rtol=RTOL, atol=1e-21, err_msg=at)


@pytest.mark.realdata
def test_a_load_test_day_in_one_unit_gives_replays_window_outputs(munich_data: Path, tmp_path: Path) -> None:
    """Four real records hours apart in one merged unit (the day's air in a bag of its own).

    The unit's windows went to the shadow in one batch, across the records' gaps: the first
    record, whose windows were held when it ended, was decided only at the next record's first
    window, so its 13 outputs published the jump prior's width (+-18.5 / 14.8 mm, where replay's
    polls said +-1.9 / 1.8 mm); a replay whose chunk spanned the gap did the same. The final
    answers agreed, the published ones did not. The shadow now decides a held record at the first
    window after the gap whatever the batch (``Shadow._process``), the join's batches too:
    outputs, window by window, are the replay's at any chunk.
    """
    from archive_fixtures import cut

    from bridge_shadow.bagio import write_monitoring
    from bridge_shadow.twin.real_records import Piece, build

    sur = load_surrogate()
    pieces = [  # the records after the first cut to 6 minutes (the first's outputs are the case)
        Piece("ref", 0.0),
        Piece("lowered", 0.733, cut_min=(0.0, 6.0)),
        Piece("lowered", 4.0, (-0.01, -0.01), temp_at_h=2.0, cut_min=(0.0, 6.0)),
        Piece("lowered", 6.0, (-0.02, -0.02), cut_min=(0.0, 6.0)),
    ]
    sc = build(munich_data / "Settlements", sur.A, pieces)
    seams = [(a + b) // 2 for a, b in itertools.pairwise(sc.starts_ns)]
    none = sc.data.select(lambda stamps: np.zeros(len(stamps), bool))
    unit = [
        write_monitoring(tmp_path / f"record_{n}", MonitoringData(part.forces, none.temperature))
        for n, part in enumerate(cut(sc.data, seams))
    ]
    unit.append(write_monitoring(tmp_path / "air", MonitoringData(none.forces, sc.data.temperature), "mcap"))
    config = load_config()
    ref, _ = replay_bag(unit, Shadow(config, sur), keep_all=True)
    shadow = Shadow(config, sur)
    outputs: list[Any] = []
    stats = join_bags(shadow, [reduce_bag(unit, config, sur)], on_outputs=outputs.extend)
    assert not stats.fed_whole and stats.windows_taken > 20
    first = [o for o in ref.outputs if o.end_ns <= sc.starts_ns[1]]
    assert len(first) > 10 and all(np.sqrt(np.diag(o.covariance_m2)).max() < 3e-3 for o in first[3:])
    assert_same_outputs(outputs, ref.outputs)
    assert_same_result(shadow.result([], stats.messages, 1.0).to_json(), ref.to_json())
    whole, _ = replay_bag(unit, Shadow(config, sur), keep_all=True, chunk=10**7)  # one chunk: all
    assert_same_outputs(whole.outputs, ref.outputs)
    events = [e["kind"] for e in ref.to_json()["events"]]
    assert len(events) == 3, events
