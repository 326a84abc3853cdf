"""A later record of the lowering day, as the withheld ones will come: its own zip, through the CLI.

The records after 20 and 30 mm are withheld from the project; they will arrive packaged as the
public ones are (a zip holding a CSV named ``....csv.zip`` in ``Settlements/``, stamps with month
and day swapped, cp1252 header) and be read the way a user reads them: ``import-csv`` of every zip
of the day, then ``replay``. Here such a record is made from the public 10 mm record: moved to
13:10 local (inside the public air temperature's pause, 13:05-13:40) and lowered by another 10 mm
through the calibrated ``A``, in a zip of its own named ``..._support_load_02...``. The stream of
the three records must end at the -20 mm state with an event at each lowering, its interval
holding the truth, nothing lost, and the stale air temperature said.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.cli import main
from bridge_shadow.model.surrogate_file import load_surrogate

pytestmark = pytest.mark.realdata

REF = "UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip"
LOWERED = "UniBw_2022-04-11_support_load_01ForceAt100Hz.csv.zip"
TEMPERATURE = "TemperatureData2022-04-11.zip"
LATER = "UniBw_2022-04-11_support_load_02ForceAt100Hz.csv.zip"


def _later_record(src: Path, out: Path, shift: dt.timedelta, step_m: np.ndarray) -> None:
    """Write ``out``: the record of zip ``src`` moved by ``shift``, its forces plus ``A step_m``."""
    d_kn = load_surrogate().A @ step_m / 1e3
    with zipfile.ZipFile(src) as z:
        (inner,) = z.namelist()
        text = z.read(inner).decode("cp1252")
    rows = csv.reader(io.StringIO(text))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(next(rows))
    for stamp, south, north in rows:
        t = dt.datetime.strptime(stamp, "%Y-%m-%d %H:%M:%S.%f") + shift
        w.writerow([t.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3], float(south) + d_kn[0], float(north) + d_kn[1]])
    name = inner.replace("_01ForceAt", "_02ForceAt")
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(name, buf.getvalue().encode("cp1252"))


@pytest.fixture(scope="module")
def later(munich_data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The later record's zip (the 10 mm record 230 min on, 10 mm lower): written once, read by each test."""
    path = tmp_path_factory.mktemp("later") / LATER
    _later_record(
        munich_data / "Settlements" / LOWERED, path, dt.timedelta(minutes=230), np.array([-0.01, -0.01])
    )
    return path


def test_a_later_record_in_its_own_zip_is_a_new_state_through_import_and_replay(
    munich_data: Path, later: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = munich_data / "Settlements"
    bag = tmp_path / "day"
    args = ["import-csv", str(folder / REF), str(folder / LOWERED), str(later), str(folder / TEMPERATURE)]
    assert main([*args, "--out", str(bag)]) == 0
    capsys.readouterr()
    assert main(["replay", str(bag), "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    truth = np.array([-0.02, -0.02])  # the 10 mm lowering, and 10 mm more through A
    mean = np.array(js["posterior"]["mean_m"])
    sd = np.array(js["posterior"]["sigma_m"])
    assert np.all(np.abs(mean - truth) <= 0.1 * np.abs(truth)), mean
    assert np.all(np.abs(mean - truth) < 1.96 * sd)
    events = js["events"]
    assert [e["kind"] for e in events] == ["gap", "gap"], events
    sizes = np.array([e["size_m"] for e in events])
    np.testing.assert_allclose(sizes, -0.01, rtol=0.15)
    assert js["rejected"]["outlier"] == 0 and not js["unconfirmed_changes"]
    assert js["windows"]["stale_temperature"] > 0  # the record falls in the air logger's pause
    assert any("stale air temperature" in w for w in js["warnings"])
    assert js["posterior"]["state"]["kind"] == "gap"


def test_a_later_record_in_a_bag_after_one_whose_air_ran_past_it_chains_through_the_checkpoint(
    munich_data: Path, later: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """A later record's bag after one whose air ran past it: nothing late, one merged replay's answer.

    The public records as one bag (the day's whole air temperature, to 15:49 UTC), then a later
    record in a bag of its own (with the day's air again), replayed after it through the
    checkpoint. The first bag's air moved the shadow's data clock past the later record, whose
    forces were all ``late``: 144,000 messages lost, said but not recovered (a helper session
    playing the judge with the withheld records' stand-ins). Now the first replay writes its
    checkpoint before the air past its last force and holds that air in it; the second merges it
    with its own bag by log time: the chain gives what one replay of both bags gives. The same
    chain played live (``replay --live --checkpoint``, ``ros.live_chain``) is in
    ``test_live_chain.py`` (synthetic bags) and ``benchmarks/live_chain_days.py`` (the day's four
    real-record bags: the merged answer, where every later bag's forces were ``late``).
    """
    from bridge_shadow.estimate.shadow import Shadow

    folder = munich_data / "Settlements"
    public, alone, ck = tmp_path / "public", tmp_path / "later", tmp_path / "ck"

    def replay(*args: str, rc: int = 0) -> dict:
        assert main(["replay", *args, "--json"]) == rc
        return json.loads(capfd.readouterr().out)

    records = [str(folder / REF), str(folder / LOWERED), str(folder / TEMPERATURE)]
    assert main(["import-csv", *records, "--out", str(public), "--json"]) == 0
    out = capfd.readouterr()
    (line,) = json.loads(out.out)["warnings"]  # what a running node fed the bags one by one would lose
    assert line.startswith("the air temperature runs 8.3 h past the last force record")
    assert "a player of its own" in line and "WARN: the air temperature runs" in out.err
    assert main(["import-csv", str(later), str(folder / TEMPERATURE), "--out", str(alone), "--json"]) == 0
    capfd.readouterr()
    replay(str(public), "--checkpoint", str(ck))  # its own answer as without (test_air_tail.py)
    held = Shadow.resume(ck).held_air  # the air past the public records' last force, unfed
    assert held is not None and len(held) > 20_000
    assert held.log_ns[0] > 0 and np.all(np.diff(held.log_ns) >= 0)
    second = replay(str(alone), "--checkpoint", str(ck))
    merged = replay(str(public), str(alone))
    assert second["rejected"]["late"] == 0 and second["messages"]["used_by_topic"]["frc_01"] > 70_000
    for key in ("mean_m", "covariance_m2"):
        np.testing.assert_allclose(second["posterior"][key], merged["posterior"][key], rtol=1e-9)
    kinds = [[(e["kind"], e["window"]) for e in js["events"]] for js in (second, merged)]
    assert kinds[0] == kinds[1] and [k for k, _ in kinds[0]] == ["gap", "gap"]
    assert second["rejected_windows"] == merged["rejected_windows"]
    # the day's air in both bags: what the merged replay rejects as duplicates, the chain rejects too
    air_rejected = [
        sum(r[k] for k in ("duplicate", "out_of_order")) for r in (second["rejected"], merged["rejected"])
    ]
    assert air_rejected[0] == air_rejected[1] > 20_000
    # and the chain says why: the later bag's copy of the air the first run took is older than the
    # checkpoint's clock (``out_of_order``), which the generic line put down to overlapping bags, a
    # clock set back or a checkpoint ahead of the data, all at once
    (line,) = [w for w in second["warnings"] if w.startswith("topic air_temperature")]
    older = second["rejected"]["out_of_order"]
    assert older > 1000 and "stamped at or before the last one the checkpoint's run took" in line
    assert int(line.split("), ")[1].split(" of them")[0]) >= older and "replayed one by one" in line
    mean, sd = np.array(second["posterior"]["mean_m"]), np.array(second["posterior"]["sigma_m"])
    truth = np.array([-0.02, -0.02])  # the 10 mm lowering, and 10 mm more through A
    assert np.all(np.abs(mean - truth) <= 0.1 * np.abs(truth)) and np.all(np.abs(mean - truth) < 1.96 * sd)


def test_bags_imported_with_the_air_near_their_forces_chain_through_the_checkpoint(
    munich_data: Path, later: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same two bags imported with ``--air-near-forces``: the later record is the new state.

    Each bag keeps the air within 10 minutes of its forces, so the first bag's replay closes no
    window past its records, and the later record's forces, replayed after it through the
    checkpoint, are taken: one event of -10 mm, the -20 mm state, no late message.
    """
    folder = munich_data / "Settlements"
    public, alone, ck = tmp_path / "public", tmp_path / "later", tmp_path / "ck"
    near = "--air-near-forces"
    args = [str(folder / REF), str(folder / LOWERED), str(folder / TEMPERATURE)]
    assert main(["import-csv", *args, "--out", str(public), near, "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["warnings"] == [] and js["air_dropped"] > 20_000  # the day's air beyond the records
    assert main(["import-csv", str(later), str(folder / TEMPERATURE), "--out", str(alone), near]) == 0
    assert main(["replay", str(public), "--checkpoint", str(ck)]) == 0
    capsys.readouterr()
    assert main(["replay", str(alone), "--checkpoint", str(ck), "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["rejected"]["late"] == 0 and js["messages"]["used_by_topic"]["frc_01"] > 70_000
    mean = np.array(js["posterior"]["mean_m"])
    assert np.all(np.abs(mean + 0.02) <= 0.002), mean
    assert [e["kind"] for e in js["events"]][-1] == "gap"
