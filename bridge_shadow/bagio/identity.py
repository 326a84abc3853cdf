"""What a bag is on disk: the files whose bytes are the bag, and what tells one of them rewritten.

Shared by the archive's reduction cache (``archive.cache``: a bag hashed once while its files stay
as they were) and the bags a checkpoint chain took (``replay.taken``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["bag_files", "stat_signature"]


def bag_files(bag: Path) -> list[Path]:
    """Return the files whose bytes are the bag: ``metadata.yaml`` and storage files (no other YAML)."""
    if bag.is_file():
        return [bag]
    return sorted(
        p
        for p in bag.iterdir()
        if p.is_file() and (p.name == "metadata.yaml" or p.suffix not in (".yaml", ".yml"))
    )


def stat_signature(files: list[Path]) -> list[list[Any]]:
    """Name, size, modification and change time, inode of each file: what tells a file rewritten.

    Size and mtime alone missed a bag replaced by one of the same size with its mtime kept (``cp
    -p``, ``tar -x``, a restore). The change time moves with every write and every ``touch``, and
    no user tool sets it back; a new inode is a file replaced (or a copy).
    """
    out = []
    for p in files:
        st = p.stat()
        out.append([p.name, st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino])
    return out
