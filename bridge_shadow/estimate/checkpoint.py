"""Checkpoint of the shadow's online state: one ``.npz`` file, written atomically.

The nested state of ``Shadow.state_dict`` is flattened to ``a/b/0/c`` keys holding numpy arrays
(no pickle); the file is written to a temporary name in the same directory and renamed over the
target, so a crash never leaves a half-written checkpoint.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from bridge_shadow.errors import InputError

__all__ = ["load_state", "save_state"]

_LIST = "__list__"


def _flatten(obj: Any, prefix: str, out: dict[str, np.ndarray]) -> None:
    if isinstance(obj, dict):
        for key, value in obj.items():
            _flatten(value, f"{prefix}{key}/", out)
    elif isinstance(obj, (list, tuple)) and (not obj or isinstance(obj[0], dict)):
        out[f"{prefix}{_LIST}"] = np.array(len(obj))
        for i, value in enumerate(obj):
            _flatten(value, f"{prefix}{i}/", out)
    else:
        out[prefix.rstrip("/")] = np.asarray(obj)


def _unflatten(flat: dict[str, np.ndarray]) -> dict[str, Any]:
    root: dict[str, Any] = {}
    for key, value in flat.items():
        parts = key.split("/")
        node = root
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value

    def fix(node: Any) -> Any:
        if not isinstance(node, dict):
            return node[()] if node.ndim == 0 else node
        if _LIST in node:
            return [fix(node[str(i)]) for i in range(int(node[_LIST]))]
        return {k: fix(v) for k, v in node.items()}

    return fix(root)


def save_state(state: dict[str, Any], path: str | Path) -> Path:
    """Write ``state`` to ``path`` atomically (temp file + rename); return the path."""
    file = Path(path)
    file.parent.mkdir(parents=True, exist_ok=True)
    flat: dict[str, np.ndarray] = {}
    _flatten(state, "", flat)
    tmp = file.with_name(f".{file.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, **flat)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, file)
    return file


def load_state(path: str | Path) -> dict[str, Any]:
    """Read a state written by ``save_state``; InputError if missing or unreadable."""
    file = Path(path)
    if not file.is_file():
        raise InputError(f"{file}: checkpoint not found")
    try:
        with np.load(file, allow_pickle=False) as data:
            flat = {k: data[k] for k in data.files}
    except (OSError, ValueError) as err:
        raise InputError(f"{file}: not a readable checkpoint ({err})") from err
    return _unflatten(flat)
