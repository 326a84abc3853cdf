"""The rosbag2 ``metadata.yaml`` checks shared by the fast readers (``sqlite_direct``, ``mcap_format``).

A fast reader takes a bag only when its metadata is readable, names the reader's storage, has a
version up to 9 and no rosbag2 compression, and lists storage files that exist; anything else
returns None and the caller falls back to rosbags.
"""

from __future__ import annotations

from pathlib import Path, PurePath
from typing import Any

import yaml

from bridge_shadow.fileio import load_yaml

__all__ = ["METADATA_ERRORS", "plain_bag_files"]

#: What reading and indexing an unexpected ``metadata.yaml`` can raise: the bag is not for a fast reader.
METADATA_ERRORS = (OSError, yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError)


def plain_bag_files(path: Path, storage: str) -> tuple[list[Path], dict[str, Any]] | None:
    """Return the storage files and the bag information of an uncompressed ``storage`` bag directory.

    None when the metadata cannot be read or says another storage, a later version, compression,
    or no files, or when a listed file is missing.
    """
    try:
        meta = load_yaml((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        if meta["storage_identifier"] != storage or int(meta["version"]) > 9:
            return None
        if str(meta.get("compression_mode") or "").lower() not in ("", "none"):
            return None
        files = [path / PurePath(x).name for x in meta["relative_file_paths"]]
    except METADATA_ERRORS:
        return None
    return (files, meta) if files and all(f.is_file() for f in files) else None
