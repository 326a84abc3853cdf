"""Where the package finds its configuration files, in a source checkout or an install."""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["config_dir", "config_file", "data_candidates", "repo_root", "shared_data_dir"]

_PACKAGE = "bridge_shadow"


def repo_root() -> Path | None:
    """Return the source checkout that holds this package, or None for an installed package."""
    root = Path(__file__).resolve().parent.parent
    return root if (root / "package.xml").is_file() and (root / "config").is_dir() else None


def config_dir() -> Path:
    """Return the directory with ``bridge.yaml``, ``surrogate.yaml`` and ``shadow.yaml``.

    A source checkout wins (so an editable install uses the tree); otherwise the ament share
    directory ``<prefix>/share/bridge_shadow/config`` of an installed package.
    """
    root = repo_root()
    if root is not None:
        return root / "config"
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    for prefix in prefixes:
        candidate = Path(prefix) / "share" / _PACKAGE / "config"
        if candidate.is_dir():
            return candidate
    return Path(sys.prefix) / "share" / _PACKAGE / "config"


def config_file(name: str) -> Path:
    """Return the path of a shipped configuration file (it may not exist yet)."""
    return config_dir() / name


def data_candidates(path: Path, base: Path | None = None) -> list[Path]:
    """Return where a data path a user gave may be, in the order to try.

    As is if absolute; else under ``base`` (if given), the working directory and the shared data
    folder (``shared_data_dir``).
    """
    if path.is_absolute():
        return [path]
    return ([base / path] if base is not None else []) + [Path.cwd() / path, shared_data_dir() / path]


def shared_data_dir() -> Path:
    """Return ``../shared/data/munich-bridge-data`` beside the checkout (or $BRIDGE_SHADOW_DATA).

    A clone made from a local checkout (``git clone /path/to/checkout``) that has no ``../shared``
    of its own uses the one beside the checkout it was cloned from.
    """
    env = os.environ.get("BRIDGE_SHADOW_DATA")
    if env:
        return Path(env)
    root = repo_root() or Path.cwd()
    bases = [root, *filter(None, [_local_origin(root)])]
    for base in bases:
        path = base.parent / "shared" / "data" / "munich-bridge-data"
        if path.is_dir():
            return path
    return root.parent / "shared" / "data" / "munich-bridge-data"


def _local_origin(root: Path) -> Path | None:
    """Return the directory named by ``remote.origin.url`` in ``root/.git/config``, if it is local."""
    config = root / ".git" / "config"
    if not config.is_file():
        return None
    section = ""
    for line in config.read_text(errors="replace").splitlines():
        line = line.strip()
        if line.startswith("["):
            section = line
        elif section == '[remote "origin"]' and line.partition("=")[0].strip() == "url":
            url = line.partition("=")[2].strip().removeprefix("file://")
            path = (root / url).resolve()
            return path if path.is_dir() else None
    return None
