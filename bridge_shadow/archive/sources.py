"""What an archive holds: bridges, each with its bags, parameter file and surrogate.

``archive_sources(PATH)`` takes one of

- a **folder of bags**: one bridge, named after the folder;
- a **folder of bridges**, each a folder of bags: one bridge per sub-folder;
- a **glob** of bags (``'/data/*/2024-*'``, quoted for the shell): one bridge per parent folder;
- a **manifest** (``.yaml``/``.yml``)::

      bridges:
        munich:                      # the bridge's name (output file names: letters, digits, _ - .)
          bags: [munich/*, extra/2024-01-01]   # paths or globs, relative to the manifest
          params: munich/shadow.yaml           # optional: shadow parameters (config/shadow.yaml)
          surrogate: munich/surrogate.yaml     # optional: its surrogate (else the parameters')

A bridge folder may hold its own ``shadow.yaml`` and ``surrogate.yaml`` beside the bags; the
manifest names them explicitly. A bag is a rosbag2 directory (``metadata.yaml`` or storage files
inside) or a bare ``.db3``/``.mcap`` file. The order of a
bridge's bags is fixed later, by their first message (``archive.run``).
"""

from __future__ import annotations

import glob
import re
from dataclasses import dataclass, field
from pathlib import Path

from bridge_shadow.errors import InputError
from bridge_shadow.fileio import load_yaml, yaml_problem

__all__ = ["BridgeSource", "archive_sources", "is_bag"]

_BAG_FILES = (".db3", ".mcap")
_GLOB_CHARS = set("*?[")
#: A manifest's bridge name: one file name of --out (no folder, not hidden, not ``..``).
_FILE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")

#: Files beside the bags of a bridge folder that name its parameters and surrogate.
PARAMS_FILE, SURROGATE_FILE = "shadow.yaml", "surrogate.yaml"


@dataclass
class BridgeSource:
    """One bridge of an archive.

    Attributes:
        name: the bridge's name (output files are named after it).
        bags: its bags (paths as found; any order).
        params: its shadow parameter file (None: ``config/shadow.yaml``).
        surrogate: its surrogate file (None: the parameters' ``surrogate_path``, else the default).

    """

    name: str
    bags: list[Path] = field(default_factory=list)
    params: Path | None = None
    surrogate: Path | None = None


def is_bag(path: Path) -> bool:
    """Whether ``path`` is a rosbag2 bag: a directory with ``metadata.yaml`` or storage files, or one file."""
    if path.is_file():
        return path.suffix in _BAG_FILES
    if not path.is_dir():
        return False
    return (path / "metadata.yaml").is_file() or any(
        p.suffix in _BAG_FILES for p in path.iterdir() if p.is_file()
    )


def _bags_in(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if not p.name.startswith(".") and is_bag(p))


def _optional(folder: Path, name: str) -> Path | None:
    path = folder / name
    return path if path.is_file() else None


def _bridge_folder(folder: Path, bags: list[Path]) -> BridgeSource:
    return BridgeSource(folder.name, bags, _optional(folder, PARAMS_FILE), _optional(folder, SURROGATE_FILE))


def _from_folder(path: Path) -> list[BridgeSource]:
    if is_bag(path):
        return [BridgeSource(path.name, [path])]
    bags = _bags_in(path)
    subs = [p for p in sorted(path.iterdir()) if p.is_dir() and not p.name.startswith(".") and not is_bag(p)]
    bridges = [_bridge_folder(p, b) for p in subs if (b := _bags_in(p))]
    if bags and bridges:
        names = ", ".join(b.name for b in bridges[:3])
        raise InputError(
            f"{path}: holds bags and bridge folders ({names}); give one bridge's folder, a folder of "
            "bridge folders, or a manifest"
        )
    if bags:
        return [_bridge_folder(path, bags)]
    if not bridges:
        raise InputError(f"{path}: no bags found (neither in it nor in its sub-folders)")
    return bridges


def _from_glob(pattern: str) -> list[BridgeSource]:
    matches = sorted(Path(p) for p in glob.glob(pattern) if is_bag(Path(p)))
    if not matches:
        raise InputError(f"{pattern}: matches no bag")
    by_parent: dict[Path, list[Path]] = {}
    for bag in matches:
        by_parent.setdefault(bag.parent.resolve(), []).append(bag)
    names = [p.name for p in by_parent]
    out = []
    for parent, bags in by_parent.items():
        name = parent.name if names.count(parent.name) == 1 else str(parent).strip("/").replace("/", "_")
        out.append(
            BridgeSource(name, bags, _optional(parent, PARAMS_FILE), _optional(parent, SURROGATE_FILE))
        )
    return out


def _manifest_path(base: Path, value: object, what: str, manifest: Path) -> Path:
    if not isinstance(value, str) or not value:
        raise InputError(f"{manifest}: {what} must be a path (got {value!r})")
    path = Path(value)
    return path if path.is_absolute() else base / path


def _from_manifest(manifest: Path) -> list[BridgeSource]:
    import yaml

    try:
        doc = load_yaml(manifest.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as err:
        raise InputError(f"{manifest}: cannot read the manifest ({yaml_problem(err)})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("bridges"), dict) or not doc["bridges"]:
        raise InputError(f"{manifest}: a manifest maps 'bridges' to {{name: {{bags: [...], ...}}}}")
    unknown = sorted(set(doc) - {"bridges"})
    if unknown:
        raise InputError(f"{manifest}: unknown key(s) {', '.join(unknown)} (expected: bridges)")
    base = manifest.parent
    out = []
    for name, spec in doc["bridges"].items():
        where = f"bridge {name!r}"
        if not _FILE_NAME.fullmatch(str(name)):
            raise InputError(
                f"{manifest}: {where}: a bridge's name names its output files: letters, digits, "
                "'_', '-' and '.', not first"
            )
        if not isinstance(spec, dict) or "bags" not in spec:
            raise InputError(f"{manifest}: {where} needs a 'bags' list")
        bad = sorted(set(spec) - {"bags", "params", "surrogate"})
        if bad:
            raise InputError(
                f"{manifest}: {where}: unknown key(s) {', '.join(bad)} (bags, params, surrogate)"
            )
        entries = spec["bags"] if isinstance(spec["bags"], list) else [spec["bags"]]
        bags: list[Path] = []
        for entry in entries:
            path = _manifest_path(base, entry, f"{where}: a bag", manifest)
            if _GLOB_CHARS & set(str(entry)):
                found = sorted(Path(p) for p in glob.glob(str(path)) if is_bag(Path(p)))
                if not found:
                    raise InputError(f"{manifest}: {where}: {entry} matches no bag")
                bags += found
            else:
                bags.append(path)  # a missing or broken bag is reported and skipped by the run
        # a bag named twice (a glob that also matches a bag listed on its own) is taken once: fed
        # twice, its messages were rejected the second time and a dead load cell was warned of
        first: dict[Path, Path] = {}
        for b in bags:
            first.setdefault(b.resolve(), b)
        bags = list(first.values())
        params = (
            _manifest_path(base, spec["params"], f"{where}: params", manifest) if "params" in spec else None
        )
        sur = spec.get("surrogate")
        surrogate = _manifest_path(base, sur, f"{where}: surrogate", manifest) if sur is not None else None
        out.append(BridgeSource(str(name), bags, params, surrogate))
    return out


def archive_sources(path: str) -> list[BridgeSource]:
    """Return the bridges of an archive given as a folder, a glob or a manifest (module docstring).

    Raises:
        InputError: the path does not exist, matches nothing, or the manifest is malformed.

    """
    p = Path(path)
    if _GLOB_CHARS & set(path) and not p.exists():
        bridges = _from_glob(path)
    elif p.is_file() and p.suffix in (".yaml", ".yml"):
        bridges = _from_manifest(p)
    elif p.is_dir():
        bridges = _from_folder(p)
    elif is_bag(p):
        bridges = [BridgeSource(p.stem, [p])]
    elif p.exists():
        raise InputError(f"{path}: not a folder, a manifest (.yaml) or a bag (.db3, .mcap)")
    else:
        raise InputError(f"{path}: no such folder, manifest or bag")
    names = [b.name for b in bridges]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"{path}: bridge name(s) {', '.join(dup)} appear more than once")
    return bridges
