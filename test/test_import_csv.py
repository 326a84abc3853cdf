"""import-csv on the real munich-bridge-data records: values, dates, time zones, quirks, round trip."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import zipfile
from datetime import date
from pathlib import Path

import numpy as np
import pytest

from bridge_shadow.bagio import get_typestore, iter_raw, read_monitoring
from bridge_shadow.cli import main
from bridge_shadow.contract import FORCE_TOPICS, TEMPERATURE_TOPIC
from bridge_shadow.errors import InputError
from bridge_shadow.importers import import_csv, local_to_utc_ns
from bridge_shadow.series import MonitoringData

pytestmark = pytest.mark.realdata

REF = "ReferenceState/ReferenceStateForceAt100Hz.csv.zip"
APR_FORCE = "Settlements/UniBw_2022-04-11_ref_support_load_01ForceAt100Hz.csv.zip"
APR_TEMP = "Settlements/TemperatureData2022-04-11.zip"


def _ns(iso: str) -> int:
    return int(np.datetime64(iso, "ns").astype(np.int64))


def _only_member(zip_path: Path) -> bytes:
    with zipfile.ZipFile(zip_path) as z:
        (info,) = z.infolist()
        return z.read(info)


def _csv_rows(content: bytes) -> list[list[str]]:
    return [r for r in csv.reader(io.StringIO(content.decode("cp1252")))][1:]


@pytest.fixture(scope="module")
def april(munich_data: Path) -> tuple[list[str], MonitoringData]:
    """The 2022-04-11 force and temperature files and their import (done once)."""
    files = [str(munich_data / APR_FORCE), str(munich_data / APR_TEMP)]
    return files, import_csv(files)[0]


def test_reference_record_first_sample_si_and_utc(munich_data: Path) -> None:
    # 2022-03-07 could be 2022-07-03 swapped, and nothing in the file says which: the date is given
    with pytest.raises(InputError, match=r"could also be 2022-07-03 .*--date 2022-03-07 or --date 2022-07"):
        import_csv([munich_data / REF])
    data, report = import_csv([munich_data / REF], date_hint=date(2022, 3, 7))
    f1, f2 = data.forces["frc_01"], data.forces["frc_02"]
    assert f1.force_n[0] == pytest.approx(2.6023853125e5, rel=1e-15)
    assert f2.force_n[0] == pytest.approx(2.20779578125e5, rel=1e-15)
    assert f1.stamp_ns[0] == _ns("2022-03-07T15:35:15.601")  # 16:35:15.601 CET = UTC+1
    assert report.utc_offsets_s == [3600.0] and report.date_fixes == []
    rows = _csv_rows(_only_member(munich_data / REF))
    assert len(f1) == len(f2) == len(rows) == report.rows["frc_01"]
    np.testing.assert_allclose(f2.force_n, [float(r[2]) * 1e3 for r in rows], rtol=1e-15)
    # sample-and-hold repeats, counted by a plain loop over the CSV cells (text equality)
    for ch, col in (("frc_01", 1), ("frc_02", 2)):
        assert report.repeats[ch] == sum(rows[i][col] == rows[i - 1][col] for i in range(1, len(rows)))
    assert report.repeats["frc_02"] > 0.9 * len(rows)  # FRC-02 is the held channel in this record
    assert list(np.unique(f1.frame_id)) == ["frc_01"] and list(np.unique(f2.frame_id)) == ["frc_02"]
    # the real central reactions of DESIGN 3: about 260 / 221 kN
    assert np.mean(f1.force_n) == pytest.approx(260e3, rel=0.03)
    assert np.mean(f2.force_n) == pytest.approx(221e3, rel=0.03)


def test_april_force_date_swap_fixed_from_file_name(munich_data: Path) -> None:
    data, report = import_csv([munich_data / APR_FORCE])
    (fix,) = report.date_fixes
    assert (fix["written"], fix["used"], fix["evidence"]) == (
        "2022-11-04",
        "2022-04-11",
        "date in the file name",
    )
    assert data.forces["frc_01"].stamp_ns[0] == _ns("2022-04-11T06:36:24.897")  # 08:36 CEST = UTC+2
    assert data.forces["frc_01"].force_n[0] == pytest.approx(233.92928125e3, rel=1e-15)
    assert report.utc_offsets_s == [7200.0]  # whole seconds of the zone table, converted, not computed
    np.testing.assert_allclose(
        np.mean([s.force_n[:1000] for s in data.forces.values()], axis=1), 234e3, rtol=0.01
    )


def test_date_swap_evidence_without_a_dated_name(munich_data: Path, tmp_path: Path) -> None:
    content = _only_member(munich_data / APR_FORCE)
    plain = tmp_path / "force.csv"
    plain.write_bytes(content)
    # the temperature files' unambiguous day-first dates
    _, report = import_csv([plain, munich_data / APR_TEMP])
    assert [(f["used"], f["evidence"]) for f in report.date_fixes] == [
        ("2022-04-11", "date of the temperature files")
    ]
    # a zip member written before the date the stamps claim
    archive = tmp_path / "force.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr(zipfile.ZipInfo("force.csv", date_time=(2022, 6, 27, 16, 38, 16)), content)
    _, report = import_csv([archive])
    assert report.date_fixes[0]["evidence"].startswith("recording after the file was written")
    # a stamp date in the future
    _, report = import_csv([plain], today=date(2022, 6, 1))
    assert report.date_fixes[0]["evidence"] == "date in the future"
    # no evidence: refused with the hint, or kept as written when asked; --date fixes it; a
    # contradicting --date is an error
    with pytest.raises(InputError, match=r"could also be 2022-04-11 .*--date 2022-11-04 or --date 2022-04"):
        import_csv([plain])
    data, report = import_csv([plain], ambiguous="as_written")
    assert report.date_fixes == [] and data.forces["frc_01"].stamp_ns[0] == _ns("2022-11-04T07:36:24.897")
    # a file date settles it the other way too: stamps 2022-03-07 in a file written on 2022-04-01
    # cannot be 2022-07-03
    march = tmp_path / "march.zip"
    rows = "Time (-),FRC-01 (kN),FRC-02 (kN)\n2022-03-07 16:35:00.000,260.1,221.2\n"
    with zipfile.ZipFile(march, "w") as z:
        z.writestr(zipfile.ZipInfo("force.csv", date_time=(2022, 4, 1, 9, 0, 0)), rows)
    data, report = import_csv([march])
    assert report.date_fixes == [] and data.forces["frc_01"].stamp_ns[0] == _ns("2022-03-07T15:35:00")
    data, report = import_csv([plain], date_hint=date(2022, 4, 11))
    assert data.forces["frc_01"].stamp_ns[0] == _ns("2022-04-11T06:36:24.897")
    with pytest.raises(InputError, match="--date 2022-04-12"):
        import_csv([plain], date_hint=date(2022, 4, 12))


def test_temperature_files_merged_day_first_and_deduplicated(munich_data: Path, tmp_path: Path) -> None:
    data, report = import_csv([munich_data / APR_TEMP])
    with zipfile.ZipFile(munich_data / APR_TEMP) as z:
        members = {i.filename: z.read(i) for i in z.infolist()}
    rows = [r for content in members.values() for r in _csv_rows(content)]
    t = data.temperature
    assert len(members) == 10 and len(t) == len(rows) == report.rows["air_temperature"]
    assert np.all(np.diff(t.stamp_ns) > 0)
    assert t.stamp_ns[0] == _ns("2022-04-11T06:36:25.984") and t.stamp_ns[-1] == _ns(
        "2022-04-11T15:49:48.486"
    )
    np.testing.assert_allclose(np.sort(t.temp_c), np.sort([float(r[1]) for r in rows]))
    assert t.temp_c.min() >= 1.0 and t.temp_c.max() <= 16.0  # an April morning to afternoon
    np.testing.assert_array_equal(t.variance, 0.0)  # set, not computed: the files carry no variance
    # one file given twice (inside the zip and on its own): its stamps are dropped once
    name = "UniBw_2022-04-11_support_load_02.csv"
    (tmp_path / name).write_bytes(members[name])
    data2, report2 = import_csv([munich_data / APR_TEMP, tmp_path / name])
    assert report2.duplicates_dropped["air_temperature"] == len(_csv_rows(members[name]))
    np.testing.assert_array_equal(data2.temperature.stamp_ns, t.stamp_ns)  # integer ns


def test_rejected_rows_cp1252_crlf_trailing_comma(tmp_path: Path) -> None:
    text = (
        "Time (-),Air Temperature (°C),\r\n"
        "07.03.2022 16:35:00.000,5.5\r\n"
        "07.03.2022 16:35:01.000,5.5,\r\n"
        "07.03.2022 16:35:02.000,oops\r\n"
        "2022-03-07 16:35:03.000,5.6\r\n"
        "31.02.2022 16:35:04.000,5.6\r\n"
        "07.03.2022 16:35:05.000,5.7,1,2\r\n"
        "07.03.2022 16:35:06.000,NaN\r\n"
        "\r\n"
    )
    path = tmp_path / "t.csv"
    path.write_bytes(text.encode("cp1252"))
    data, report = import_csv([path])
    # parsed text (float() of a decimal string rounds correctly), with a tolerance all the same: a
    # NaN reading is kept
    np.testing.assert_allclose(data.temperature.temp_c, [5.5, 5.5, np.nan], rtol=1e-12, atol=0)
    assert data.temperature.stamp_ns[0] == _ns("2022-03-07T15:35:00")
    assert report.repeats["air_temperature"] == 1 and report.non_finite["air_temperature"] == 1
    reasons = {(r["line"], r["reason"]) for r in report.rejected}
    assert reasons == {
        (4, "unreadable value of air_temperature"),
        (5, "unreadable time stamp"),
        (6, "impossible date or time"),
        (7, "expected 2 fields, found 4"),
    }


def test_local_time_to_utc_across_dst() -> None:
    local = np.array(
        [
            "2022-03-07T16:35",
            "2022-03-27T01:30",
            "2022-03-27T02:30",
            "2022-03-27T03:30",
            "2022-04-11T08:36",
            "2022-10-30T02:30",
            "2022-10-30T03:30",
        ],
        dtype="datetime64[ns]",
    ).astype(np.int64)
    utc, offset_s, odd = local_to_utc_ns(local)
    expected = [
        "2022-03-07T15:35",
        "2022-03-27T00:30",
        "2022-03-27T01:30",
        "2022-03-27T01:30",
        "2022-04-11T06:36",
        "2022-10-30T00:30",
        "2022-10-30T02:30",
    ]
    # integer ns and whole-hour offsets: exact
    np.testing.assert_array_equal(utc, np.array(expected, dtype="datetime64[ns]").astype(np.int64))
    np.testing.assert_array_equal(offset_s // 3600, [1, 1, 1, 2, 2, 2, 1])
    assert odd == 2  # the missing spring hour and the doubled autumn hour


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_cli_round_trip_both_storages(april, tmp_path: Path, storage: str, capsys) -> None:
    files, expected = april
    out = tmp_path / "apr11"
    assert main(["import-csv", *files, "--out", str(out), "--storage", storage, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["rows"] == {"frc_01": 72000, "frc_02": 72000, "air_temperature": 28330}
    assert summary["time_span"]["frc_01"]["start"] == "2022-04-11T06:36:24.897Z"
    assert summary["date_fix"][0]["used"] == "2022-04-11" and summary["rejected"]["count"] == 0
    got = read_monitoring(out)
    for ch in ("frc_01", "frc_02"):  # a storage round trip of the same imported floats: a copy
        np.testing.assert_array_equal(got.forces[ch].stamp_ns, expected.forces[ch].stamp_ns)
        np.testing.assert_array_equal(got.forces[ch].force_n, expected.forces[ch].force_n)
    np.testing.assert_array_equal(got.temperature.temp_c, expected.temperature.temp_c)  # a copy too
    assert got.temperature.frame_id[0] == "air_temperature"
    # the vectorized decode equals rosbags' deserialization on this real bag (every 11th message)
    ts = get_typestore()
    index = dict.fromkeys([*FORCE_TOPICS.values(), TEMPERATURE_TOPIC], -1)
    checked = 0
    for topic, msgtype, log_ns, raw in iter_raw(out):
        index[topic] += 1
        i = index[topic]
        if i % 11:
            continue
        msg = ts.deserialize_cdr(raw, msgtype)
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        if topic == TEMPERATURE_TOPIC:
            series, value = got.temperature, got.temperature.temp_c[i]
            assert (msg.temperature, msg.variance) == (value, got.temperature.variance[i])
        else:
            series = got.forces[topic.split("/")[2]]
            assert msg.wrench.force.z == series.force_n[i] and msg.wrench.torque.z == 0.0
        assert (stamp, log_ns, msg.header.frame_id) == (
            series.stamp_ns[i],
            series.log_ns[i],
            series.frame_id[i],
        )
        checked += 1
    assert checked > (72000 * 2 + 28330) // 11
    # a second run without --force is a one-line user error
    assert main(["import-csv", *files, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "pass --force to replace it" in err and err.count("\n") == 1


def test_cli_rejects_foreign_csv(munich_data: Path, tmp_path: Path, capsys) -> None:
    code = main(
        [
            "import-csv",
            str(munich_data / "Weather/TemperatureComparisonMUC.csv"),
            "--out",
            str(tmp_path / "b"),
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "not a munich-bridge-data" in err and err.count("\n") == 1
    assert not (tmp_path / "b").exists()


def test_cli_compress_needs_mcap(munich_data: Path, tmp_path: Path, capsys) -> None:
    args = ["import-csv", str(munich_data / APR_TEMP), "--out", str(tmp_path / "b"), "--compress"]
    assert main(args) == 2 and "--storage mcap" in capsys.readouterr().err
    assert main([*args, "--storage", "mcap", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["time_span"]["all"] == {
        "start": "2022-04-11T06:36:25.984Z",
        "end": "2022-04-11T15:49:48.486Z",
    }
    assert (
        len(read_monitoring(tmp_path / "b", required=False).temperature) == summary["rows"]["air_temperature"]
    )


def test_swap_decided_per_file_across_midnight(tmp_path: Path) -> None:
    path = tmp_path / "UniBw_2022-04-11_night.csv"
    path.write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n"
        "2022-11-04 23:59:59.990,1.5,2.5\n"
        "2022-12-04 00:00:00.000,1.5,2.75\n"
    )
    data, report = import_csv([path])
    assert [(f["written"], f["used"]) for f in report.date_fixes] == [
        ("2022-11-04", "2022-04-11"),
        ("2022-12-04", "2022-04-12"),
    ]
    np.testing.assert_array_equal(  # integer ns
        data.forces["frc_02"].stamp_ns, [_ns("2022-04-11T21:59:59.990"), _ns("2022-04-11T22:00:00")]
    )
    np.testing.assert_allclose(data.forces["frc_02"].force_n, [2500.0, 2750.0], rtol=1e-12)  # kN -> N
    assert report.repeats == {"frc_01": 1, "frc_02": 0, "air_temperature": 0}


def test_a_row_with_an_unreadable_cell_is_rejected_whole(tmp_path: Path) -> None:
    """Its readable cell shares the doubtful row: it must not displace a good sample at that stamp.

    Two force files hold the same instant (as overlapping exports do); in the first, FRC-02 of
    that row is unreadable. The good row of the second file is the one kept, on both channels.
    """
    bad = tmp_path / "a_2022-03-07.csv"
    bad.write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n"
        "2022-03-07 16:35:00.000,233.90,221.10\n"
        "2022-03-07 16:35:00.010,233.90,#WERT!\n"
    )
    good = tmp_path / "b_2022-03-07.csv"
    good.write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n"
        "2022-03-07 16:35:00.010,243.88,221.20\n"
        "2022-03-07 16:35:00.020,243.90,221.30\n"
    )
    data, report = import_csv([bad, good])
    t = _ns("2022-03-07T15:35:00.010")
    for ch, value in (("frc_01", 243.88e3), ("frc_02", 221.20e3)):
        series = data.forces[ch]
        (at,) = np.flatnonzero(series.stamp_ns == t)
        assert series.force_n[at] == pytest.approx(value, rel=1e-12), ch
        assert len(series) == 3
    assert [(r["line"], r["reason"]) for r in report.rejected] == [(3, "unreadable value of frc_02")]


def test_a_file_none_of_whose_rows_can_be_read_is_refused_by_name(tmp_path: Path, capsys) -> None:
    """A record whose every value is unreadable must not leave the bag as a mere count of rejects.

    The bag without it would be a stream missing that record: the state it holds lost with exit 0.
    A file with some bad rows is imported, and the summary names it with its count.
    """
    good = tmp_path / "a_2022-03-07.csv"
    good.write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n"
        "2022-03-07 16:35:00.000,233.90,221.10\n"
        "2022-03-07 16:35:00.010,233.90,#WERT!\n"
        "2022-03-07 16:35:00.020,233.80,221.00\n"
    )
    bad = tmp_path / "b_2022-03-07.csv"
    bad.write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n"
        "2022-03-07 17:35:00.000,np.float64(203.9),np.float64(191.1)\n"
        "2022-03-07 17:35:00.010,np.float64(203.9),np.float64(191.2)\n"
    )
    refused = r"b_2022-03-07\.csv: none of its 2 data rows could be read \(line 2"
    with pytest.raises(InputError, match=refused):
        import_csv([good, bad])
    out = tmp_path / "bag"
    assert main(["import-csv", str(good), str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "b_2022-03-07.csv" in err and err.count("\n") == 1
    assert not out.exists()
    assert main(["import-csv", str(good), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "rejected rows: 1" in text and f"1 of 3 rows in {good}" in text
    assert main(["import-csv", str(good), "--out", str(out), "--force", "--json"]) == 0
    (source,) = json.loads(capsys.readouterr().out)["inputs"]
    assert (source["rows_read"], source["rows_rejected"]) == (2, 1)


def test_a_header_without_rows_or_a_bag_without_forces_is_refused(tmp_path: Path, capsys) -> None:
    """Beside another file, a force file of a header only became 0 rows, exit 0; air alone is a WARN."""
    header = tmp_path / "h_2022-03-07.csv"
    header.write_text("Time (-),FRC-01 (kN),FRC-02 (kN)\n")
    good = tmp_path / "a_2022-03-07.csv"
    good.write_text("Time (-),FRC-01 (kN),FRC-02 (kN)\n2022-03-07 16:35:00.000,233.90,221.10\n")
    air = tmp_path / "t.csv"
    rows = "07.03.2022 16:35:00.000,5.5\n07.03.2022 16:36:00.000,5.6\n"  # the air twice: no load cell
    air.write_bytes(f"Time (-),Air Temperature (°C)\n{rows}".encode("cp1252"))
    out = tmp_path / "bag"
    for files, said in (
        ([header, good], f"{header}: a header and no data rows; nothing was written"),
        ([header, good, "--date", "2022-03-07"], f"{header}: a header and no data rows"),
    ):
        assert main(["import-csv", *map(str, files), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert said in err and err.count("\n") == 1, err
        assert not out.exists()
    assert main(["import-csv", str(air), "--out", str(out), "--json"]) == 0
    out_text, err = capsys.readouterr()
    assert "WARN: no force record among the inputs" in err
    assert json.loads(out_text)["warnings"][0].startswith("no force record")
    assert main(["replay", str(out)]) == 1  # and the replay says why (it said nothing before)
    said = "WARN: no load cell message: /bridge/frc_01/force and /bridge/frc_02/force delivered nothing"
    assert said in capsys.readouterr().err
    assert main(["import-csv", str(good), str(air), "--out", str(tmp_path / "both")]) == 0
    assert "WARN" not in capsys.readouterr().err


def test_a_folder_is_its_csv_and_zip_files(april, munich_data: Path, tmp_path: Path, capsys) -> None:
    """A folder reads as the CSV and zip files directly in it: not its other files or subfolders."""
    files, expected = april
    folder = tmp_path / "Settlements"
    (folder / "Weather").mkdir(parents=True)
    for f in files:
        (folder / Path(f).name).write_bytes(Path(f).read_bytes())
    (folder / "README.md").write_text("not a table\n")
    # a table of another format one level down: read, it would refuse the whole import
    weather = munich_data / "Weather/TemperatureComparisonMUC.csv"
    (folder / "Weather" / weather.name).write_bytes(weather.read_bytes())
    got = import_csv([folder])[0]
    for ch in ("frc_01", "frc_02"):  # the same files imported: stamps (integer ns) exact, values parsed
        np.testing.assert_array_equal(got.forces[ch].stamp_ns, expected.forces[ch].stamp_ns)
        np.testing.assert_allclose(got.forces[ch].force_n, expected.forces[ch].force_n, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(got.temperature.stamp_ns, expected.temperature.stamp_ns)
    np.testing.assert_allclose(got.temperature.temp_c, expected.temperature.temp_c, rtol=1e-12, atol=0)
    # a folder with nothing to read is a one-line user error naming it, and no bag
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no tables here\n")
    assert main(["import-csv", str(empty), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert f"{empty}: a folder without CSV or zip files" in err and err.count("\n") == 1
    assert not (tmp_path / "b").exists()


#: Rows edited the ways exports go wrong (or are merely written otherwise).
_EDITS = (
    lambda row: row + ",",  # a trailing comma: read as the row
    lambda row: row + ",\t",
    lambda row: "  ",  # a blank line: skipped
    lambda row: row[: len(row) // 2],  # cut
    lambda row: row.replace("2", "x", 1),  # an unreadable stamp
    lambda row: row[: row.rindex(",") + 1] + "#WERT!",  # an unreadable value
    lambda row: row.replace("0", "\u0660", 1),  # an Arabic-Indic zero (a digit to a regular expression)
    lambda row: " " + row,  # a space before the stamp: read as the row
    lambda row: row.replace(".", "", 1),  # a stamp without its fraction's point
    lambda row: row + ",1",  # a field too many
    lambda row: row.replace("-11-", "-31-", 1).replace(".04.", ".31.", 1),  # a 31st month
)


def _edited(text: str, edits: list[int], seed: int) -> str:
    """``text`` with the ``_EDITS`` numbered ``edits`` each made to a random row."""
    rng = np.random.default_rng(seed)
    lines = text.split("\n")
    for k in edits:
        i = int(rng.integers(1, len(lines) - 1))
        lines[i] = _EDITS[k](lines[i].rstrip("\r"))
    return "\n".join(lines)


def test_a_uniform_table_is_read_as_the_row_by_row_loop_reads_it(munich_data: Path, monkeypatch) -> None:
    """``parse_source`` reads a logger's uniform table in whole columns (``_uniform_rows``).

    Its result, on the real records and on them with rows edited (bad stamps and cells, blank
    lines, trailing commas, impossible dates), equals the row-by-row loop's, which reads any table
    and is forced here by taking the uniform reader away; the uniform reader must have taken the
    unedited records and some of the edited ones (a reader that always declined would compare the
    loop with itself).
    """
    from bridge_shadow.importers import munich_csv
    from bridge_shadow.importers.sources import find_sources

    def both(source):
        fast = munich_csv.parse_source(source)
        with monkeypatch.context() as m:
            m.setattr(munich_csv, "_uniform_rows", lambda *args: None)
            loop = munich_csv.parse_source(source)
        for name in ("local_ns", "values", "ok"):
            a, b = getattr(fast, name), getattr(loop, name)
            assert a.dtype == b.dtype and a.shape == b.shape, name
        # stamps (integer ns) and the mask of cells read: exact; the values parsed from the same
        # text with a stated tolerance all the same, NaN where the cell did not parse in both
        np.testing.assert_array_equal(fast.local_ns, loop.local_ns)
        np.testing.assert_array_equal(fast.ok, loop.ok)
        np.testing.assert_allclose(fast.values, loop.values, rtol=1e-12, atol=0, equal_nan=True)
        for name in ("columns", "written_dates", "rejected"):
            assert getattr(fast, name) == getattr(loop, name), name

    def uniform(source) -> bool:
        lines = munich_csv._lines(source.text)
        return munich_csv._uniform_rows(lines, source.kind, 3 if source.kind == "force" else 2) is not None

    sources = list(find_sources([munich_data / APR_FORCE, munich_data / APR_TEMP]))
    assert {s.kind for s in sources} == {"force", "temperature"}
    assert all(uniform(s) for s in sources)
    taken = 0
    for source in sources:
        both(source)
        head = "\n".join(source.text.split("\n")[:400])  # the edits on a short piece of each
        rng = np.random.default_rng(len(head))
        edits = [[k] for k in range(len(_EDITS))] + [rng.choice(len(_EDITS), 3).tolist() for _ in range(6)]
        for seed, ks in enumerate(edits):
            edited = dataclasses.replace(source, text=_edited(head, ks, seed))
            taken += uniform(edited)
            both(edited)
    # the blank line, the unreadable value and the 31st month of each source at least
    assert 3 * len(sources) <= taken < len(edits) * len(sources)


def test_a_relative_path_not_here_is_read_from_the_shared_data_folder(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """As ``calibrate`` reads its records: ``import-csv Settlements`` anywhere, BRIDGE_SHADOW_DATA set."""
    data_dir = tmp_path / "data" / "Records"
    data_dir.mkdir(parents=True)
    (data_dir / "a_2022-03-07.csv").write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n"
        "2022-03-07 16:35:00.000,233.90,221.10\n2022-03-07 16:35:00.010,233.80,221.00\n"
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.setenv("BRIDGE_SHADOW_DATA", str(tmp_path / "data"))
    data, _ = import_csv(["Records"])
    assert len(data.forces["frc_01"]) == 2 and data.forces["frc_01"].force_n[0] == pytest.approx(233.9e3)
    # a path here wins over the shared one, and a name found in neither says where it looked
    here = elsewhere / "Records"
    here.mkdir()
    (here / "b_2022-03-07.csv").write_text(
        "Time (-),FRC-01 (kN),FRC-02 (kN)\n2022-03-07 17:35:00.000,203.90,191.10\n"
    )
    assert len(import_csv(["Records"])[0].forces["frc_01"]) == 1
    assert main(["import-csv", "Nowhere", "--out", str(tmp_path / "bag")]) == 2
    err = capsys.readouterr().err
    assert "Nowhere: no such file" in err and str(tmp_path / "data") in err
