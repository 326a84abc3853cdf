"""Importers of foreign record formats into the contract topics (no ROS import)."""

from __future__ import annotations

from bridge_shadow.importers.localtime import local_to_utc_ns
from bridge_shadow.importers.munich_csv import ImportReport, import_csv, parse_source
from bridge_shadow.importers.sources import CsvSource, classify_header, find_sources

__all__ = [
    "CsvSource",
    "ImportReport",
    "classify_header",
    "find_sources",
    "import_csv",
    "local_to_utc_ns",
    "parse_source",
]
