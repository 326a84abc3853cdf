"""``config/bridge.yaml``: load, validate, apply ``--set name=value`` overrides, hash.

The file is the single source of the bridge model's numbers (SI units). Named parameters (section
``parameters``) can be overridden without editing the file; everything else is fixed geometry.
"""

from __future__ import annotations

import copy
import hashlib
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from bridge_shadow.errors import ConfigError
from bridge_shadow.paths import config_file

__all__ = [
    "MAY_BE_INFINITE",
    "MESH_LEVELS",
    "BridgeConfig",
    "file_sha256",
    "load_bridge_config",
    "parse_overrides",
]

#: Mesh levels every bridge.yaml defines, coarse to fine.
MESH_LEVELS: tuple[str, str, str] = ("coarse", "default", "fine")

_SECTIONS = ("geometry", "sections", "materials", "loads", "parameters", "mesh")
_MAY_BE_ZERO = ("central_bearing_twist_restraint",)
#: Parameters whose value may be ``.inf`` in bridge.yaml (or ``--set name=inf``): the element is
#: absent (a rigid connection), as in the as-built model.
MAY_BE_INFINITE: tuple[str, ...] = ("support_spring_south", "support_spring_north")
#: Fractions: ``(0, 1]`` (``[0, 1]`` for those in ``_MAY_BE_ZERO``).
_FRACTIONS = ("composite_action", "central_bearing_twist_restraint", "slab_joint_opening")
_MESH_KEYS = ("dx", "web", "half_flange", "cantilever", "between", "connector", "brace")


@dataclass
class BridgeConfig:
    """The parsed bridge model description.

    Attributes:
        data: the YAML content with overrides applied (plain dicts, SI units).
        path: the file it came from. sha256: hex digest of the file's bytes (before overrides).
        overrides: parameter name -> value applied on top of the file.

    """

    data: dict[str, Any]
    path: Path
    sha256: str
    overrides: dict[str, float] = field(default_factory=dict)

    @property
    def params(self) -> dict[str, float]:
        """Named stiffness parameters (after overrides)."""
        return self.data["parameters"]

    def mesh(self, level: str) -> dict[str, float]:
        """Mesh settings of ``level`` (coarse, default or fine)."""
        try:
            return self.data["mesh"][level]
        except KeyError:
            raise ConfigError(
                f"{self.path}: unknown mesh level {level!r} (have {sorted(self.data['mesh'])})"
            ) from None

    def with_overrides(self, overrides: Mapping[str, float]) -> BridgeConfig:
        """Return a copy with more parameter overrides applied (validated)."""
        data = copy.deepcopy(self.data)
        merged = dict(self.overrides)
        for name, value in overrides.items():
            if name not in data["parameters"]:
                raise ConfigError(
                    f"unknown parameter {name!r}; overridable: {', '.join(sorted(data['parameters']))}"
                )
            data["parameters"][name] = float(value)
            merged[name] = float(value)
        cfg = BridgeConfig(data, self.path, self.sha256, merged)
        _validate(cfg)
        return cfg


def parse_overrides(items: Iterable[str] | None) -> dict[str, float]:
    """Parse ``["name=value", ...]`` into floats; raise :class:`ConfigError` on bad syntax."""
    out: dict[str, float] = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ConfigError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--set {name.strip()}: {value!r} is not a number") from None
    return out


def _floatify(obj: Any) -> Any:
    """Turn numeric strings that YAML 1.1 leaves as text (``2e9``) into floats."""
    if isinstance(obj, dict):
        return {k: _floatify(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_floatify(v) for v in obj]
    if isinstance(obj, str):
        try:
            return float(obj)
        except ValueError:
            return obj
    return obj


def _validate(cfg: BridgeConfig) -> None:
    d, where = cfg.data, cfg.path
    for name in _SECTIONS:
        if not isinstance(d.get(name), dict):
            raise ConfigError(f"{where}: section {name!r} missing or not a mapping")
    for level in MESH_LEVELS:
        m = d["mesh"].get(level)
        if not isinstance(m, dict) or any(k not in m for k in _MESH_KEYS):
            raise ConfigError(f"{where}: mesh.{level} must define {', '.join(_MESH_KEYS)}")
    for name, value in d["parameters"].items():
        if not isinstance(value, float | int) or math.isnan(value):
            raise ConfigError(f"{where}: parameter {name} must be a number, got {value!r}")
        if math.isinf(value) and not (value > 0 and name in MAY_BE_INFINITE):
            raise ConfigError(
                f"{where}: parameter {name} must be finite (only {', '.join(MAY_BE_INFINITE)} may be .inf)"
            )
        if not value > 0 and name not in _MAY_BE_ZERO:
            raise ConfigError(f"{where}: parameter {name} must be a positive number, got {value!r}")
    for name in _FRACTIONS:
        value = d["parameters"].get(name, 1.0)
        low_ok = value >= 0.0 if name in _MAY_BE_ZERO else value > 0.0
        if not (low_ok and value <= 1.0):
            span = "[0, 1]" if name in _MAY_BE_ZERO else "(0, 1]"
            raise ConfigError(f"{where}: parameter {name} must lie in {span}, got {value!r}")
    geo = d["geometry"]
    if geo["deck_width"] <= geo["girder_spacing"]:
        raise ConfigError(f"{where}: deck_width must exceed girder_spacing")


def load_bridge_config(
    path: str | Path | None = None, overrides: Mapping[str, float] | None = None
) -> BridgeConfig:
    """Read ``bridge.yaml`` (default ``config/bridge.yaml``) and apply ``overrides``."""
    file = Path(path) if path is not None else config_file("bridge.yaml")
    try:
        raw = file.read_bytes()
    except OSError as err:
        raise ConfigError(f"{file}: cannot read bridge model ({err.strerror})") from err
    try:
        data = _floatify(yaml.safe_load(raw))
    except yaml.YAMLError as err:
        from bridge_shadow.fileio import yaml_problem

        raise ConfigError(f"{file}: not valid YAML at {yaml_problem(err)}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: not a bridge model (top level must be a mapping)")
    cfg = BridgeConfig(data, file, hashlib.sha256(raw).hexdigest())
    _validate(cfg)
    return cfg.with_overrides(overrides or {})


def file_sha256(path: str | Path | None = None) -> str:
    """Return the sha256 hex digest of ``bridge.yaml`` (default location)."""
    file = Path(path) if path is not None else config_file("bridge.yaml")
    return hashlib.sha256(file.read_bytes()).hexdigest()
