"""Find the CSV tables in the given files: plain CSVs or zips (nested zips too), by header."""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from datetime import date
from pathlib import Path

from bridge_shadow.contract import RECORD_FILE_SUFFIXES
from bridge_shadow.errors import InputError
from bridge_shadow.paths import data_candidates, shared_data_dir

__all__ = ["CsvSource", "classify_header", "find_sources", "folder_files"]

#: A zip's first bytes: a local file header, or an empty zip's end of central directory.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")
_TIME = "time (-)"


@dataclass(frozen=True)
class CsvSource:
    """One CSV table found in the inputs.

    Attributes:
        file: the path given on the command line.
        member: the zip member path inside ``file`` (nested zips joined by ``!``), "" for a plain CSV.
        kind: ``"force"`` or ``"temperature"``.
        text: the decoded content (cp1252), header included.
        modified: the file's modification date (zip member date or file mtime), evidence for dates.

    """

    file: str
    member: str
    kind: str
    text: str
    modified: date | None

    @property
    def label(self) -> str:
        """``file`` or ``file!member`` for messages."""
        return f"{self.file}!{self.member}" if self.member else self.file

    @property
    def name(self) -> str:
        """Base name of the innermost file (its name may carry the recording date)."""
        return Path(self.member or self.file).name


def classify_header(line: str) -> str | None:
    """Return ``"force"``, ``"temperature"`` or None for a CSV header line.

    Force: ``Time (-),FRC-01 (kN),FRC-02 (kN)`` (or ``[kN]``); temperature:
    ``Time (-),Air Temperature (°C),`` (trailing comma allowed).
    """
    cols = [
        c.strip().lower().replace("[", "(").replace("]", ")") for c in line.strip("\ufeff\r\n ").split(",")
    ]
    while cols and cols[-1] == "":
        cols.pop()
    if cols == [_TIME, "frc-01 (kn)", "frc-02 (kn)"]:
        return "force"
    if len(cols) == 2 and cols[0] == _TIME and cols[1] in ("air temperature (°c)", "air temperature (c)"):
        return "temperature"
    return None


def _decode(data: bytes) -> str:
    if data.startswith(b"\xef\xbb\xbf"):
        return data[3:].decode("utf-8", errors="replace")
    return data.decode("cp1252", errors="replace")


def _from_bytes(file: str, member: str, data: bytes, modified: date | None, out: list[CsvSource]) -> None:
    label = f"{file}!{member}" if member else file
    if data.startswith(_ZIP_MAGIC):
        try:
            archive = zipfile.ZipFile(io.BytesIO(data))
        except zipfile.BadZipFile as err:
            raise InputError(f"{label}: not a readable zip ({err})") from err
        with archive:
            infos = [i for i in archive.infolist() if not i.is_dir()]
            if not infos:
                raise InputError(f"{label}: an empty zip (no file in it)")
            for info in infos:
                try:
                    content = archive.read(info)
                except (zipfile.BadZipFile, OSError, EOFError) as err:
                    raise InputError(f"{label}!{info.filename}: cannot unzip ({err})") from err
                inner = f"{member}!{info.filename}" if member else info.filename
                _from_bytes(file, inner, content, date(*info.date_time[:3]), out)
        return
    text = _decode(data)
    first = text.split("\n", 1)[0]
    kind = classify_header(first)
    if kind is None:
        raise InputError(
            f"{label}: not a munich-bridge-data force or temperature CSV (header {first.strip()!r})"
        )
    out.append(CsvSource(file, member, kind, text, modified))


def folder_files(folder: Path) -> list[Path]:
    """Return the CSV and zip files directly in ``folder``, sorted by name (not its subfolders).

    A folder of the data set (``Settlements/``) holds one day's records and its air temperature;
    its other files (a README) are left alone, as are subfolders, whose tables belong to other
    days and other formats (``Weather/``).

    Raises:
        InputError: the folder cannot be listed or holds no CSV or zip file.

    """
    try:
        found = sorted(
            p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in RECORD_FILE_SUFFIXES
        )
    except OSError as err:
        raise InputError(f"{folder}: cannot list the folder ({err.strerror})") from err
    if not found:
        raise InputError(f"{folder}: a folder without CSV or zip files; give the files, or their folder")
    return found


def _located(path: Path) -> Path:
    """Return ``path``, or a relative one missing here under the shared data folder (as ``calibrate``)."""
    if path.exists():
        return path  # as given, so the tables keep the name the user wrote
    return next((c for c in data_candidates(path) if c.exists()), path)


def find_sources(files: list[str | Path]) -> list[CsvSource]:
    """Read every given CSV or zip (a folder: its CSV and zip files) and return its tables, by header.

    A relative path that is not here is looked for under the shared data folder
    (``paths.shared_data_dir``: ``../shared/data/munich-bridge-data`` or ``$BRIDGE_SHADOW_DATA``).

    Raises:
        InputError: a file is missing, unreadable, a broken zip, or holds a CSV of another format;
            a folder holds no CSV or zip file.

    """
    out: list[CsvSource] = []
    paths: list[Path] = []
    for f in files:
        path = _located(Path(f))
        paths.extend(folder_files(path) if path.is_dir() else [path])
    for path in paths:
        if not path.is_file():
            raise InputError(f"{path}: no such file (nor in the shared data folder {shared_data_dir()})")
        try:
            data = path.read_bytes()
        except OSError as err:
            raise InputError(f"{path}: cannot read ({err.strerror})") from err
        modified = date.fromtimestamp(path.stat().st_mtime)
        _from_bytes(str(path), "", data, modified, out)
    return out
