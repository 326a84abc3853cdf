"""``config/bridge.yaml``: load, validate, apply ``--set name=value`` overrides, hash.

The file is the single source of the bridge model's numbers (SI units). Named parameters (section
``parameters``) can be overridden without editing the file; everything else is fixed geometry.

Every key is known (``KEYS``; an unknown one is an error with the key meant), and the file's
parameters and every ``--set`` value lie in a physical range (``physical_range``): a unit
mistake (``E_concrete=34000``, MPa for Pa) is refused by name before a minute of FE solves.
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
from bridge_shadow.fileio import load_yaml, yaml_problem
from bridge_shadow.keys import check_keys, did_you_mean
from bridge_shadow.paths import config_file

__all__ = [
    "KEYS",
    "MAY_BE_INFINITE",
    "MESH_LEVELS",
    "PHYSICAL_DECADES",
    "BridgeConfig",
    "file_sha256",
    "load_bridge_config",
    "parse_overrides",
    "physical_range",
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
_I_SECTION = ("h", "b", "tw", "tf")
_BEAM_SECTION = ("h", "b", "A", "Iy", "Iz", "J")
#: Every key of bridge.yaml: section -> its keys (a tuple), or -> {key: the keys under it}.
KEYS: dict[str, Any] = {
    "geometry": (
        "spans",
        "girder_spacing",
        "deck_width",
        "slab_thickness",
        "segment_length",
        "brace_connection_depth",
        "braces_heb280_x",
        "braces_heb120_x",
        "stiffener_thickness",
    ),
    "sections": {
        "heb1000": _I_SECTION,
        "heb280": _BEAM_SECTION,
        "heb120": _BEAM_SECTION,
        "hea340_half": _I_SECTION,
        "connector_web_solid_fraction": (),
    },
    "materials": {"steel": ("E", "nu", "rho", "alpha"), "concrete": ("nu", "rho")},
    "loads": ("gravity", "superimposed_pa"),
    "parameters": (
        "bearing_stiffness",
        "central_bearing_twist_restraint",
        "end_bearing_stiffness",
        "support_spring_south",
        "support_spring_north",
        "fixed_bearing_stiffness",
        "connector_stiffness",
        "connector_axial_factor",
        "dowel_stiffness",
        "composite_action",
        "dowel_rotational_stiffness",
        "slab_joint_normal_stiffness",
        "slab_joint_shear_stiffness",
        "slab_joint_rotational_stiffness",
        "slab_joint_opening",
        "E_concrete",
        "alpha_concrete",
    ),
    "mesh": dict.fromkeys(MESH_LEVELS, _MESH_KEYS),
}
#: How far beyond its plausible range (the prior's 95 % interval, ``model.parameters``) a
#: parameter may be set, in decades either way: three, so that the calibration and the gap
#: diagnosis can step well outside the plausible range, while a unit mistake (MPa or GPa for Pa:
#: six or nine decades, kN for N: three beyond the range's own span) is refused.
PHYSICAL_DECADES = 3
#: Parameters without a prior: their physical range (SI). The axial factor of the bolted joint
#: (10 as built, bridge.yaml) up to a thousand times its shear stiffness; concrete's thermal
#: expansion up to ten times the largest of any concrete (EN 1992-1-1 3.1.3: about 1e-5 /K).
_RANGES = {"connector_axial_factor": (0.0, 1.0e3), "alpha_concrete": (0.0, 1.0e-4)}


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
                    f"unknown parameter {name!r}{did_you_mean(name, data['parameters'])}; "
                    f"overridable: {', '.join(sorted(data['parameters']))}"
                )
            data["parameters"][name] = float(value)
            merged[name] = float(value)
        cfg = BridgeConfig(data, self.path, self.sha256, merged)
        _validate(cfg)
        return cfg


#: YAML's spellings of infinity (the range messages and the files write ``.inf``).
_YAML_INF = {".inf": math.inf, "+.inf": math.inf, "-.inf": -math.inf}


def parse_overrides(items: Iterable[str] | None, option: str = "--set") -> dict[str, float]:
    """Parse ``["name=value", ...]`` into floats (``.inf`` as YAML writes it); ConfigError on bad syntax."""
    out: dict[str, float] = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ConfigError(f"{option} expects NAME=VALUE, got {item!r}")
        try:
            out[name.strip()] = _YAML_INF.get(value.strip().lower()) or float(value)
        except ValueError:
            raise ConfigError(f"{option} {name.strip()}: {value!r} is not a number") from None
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


def physical_range(name: str) -> tuple[float, float]:
    """Return the range ``(low, high)`` (SI, open at 0) a value of parameter ``name`` must lie in.

    With a prior: ``PHYSICAL_DECADES`` beyond its plausible range either way (fractions up to 1);
    otherwise ``_RANGES`` ((0, 1] for the fractions); a support spring may also be ``.inf``.
    """
    from bridge_shadow.model.parameters import PARAMETERS

    if name in PARAMETERS:
        p = PARAMETERS[name]
        high = p.upper if p.upper is not None else p.high * 10.0**PHYSICAL_DECADES
        return p.low * 10.0**-PHYSICAL_DECADES, high
    if name in _FRACTIONS:
        return 0.0, 1.0
    return _RANGES.get(name, (0.0, math.inf))


def _check_ranges(params: Mapping[str, Any], what: str) -> None:
    """Refuse a parameter value outside ``physical_range`` (one line naming it, as ``what NAME``)."""
    for name, value in params.items():
        if name not in KEYS["parameters"] or not isinstance(value, float | int) or math.isnan(value):
            continue  # unknown names and non-numbers: _validate says so
        low, high = physical_range(name)
        if math.isinf(value) and value > 0 and name in MAY_BE_INFINITE:
            continue
        if not (low <= value <= high) or (value == 0.0 and name not in _MAY_BE_ZERO):
            left = "[" if low > 0 or name in _MAY_BE_ZERO else "("
            raise ConfigError(
                f"{what}{name} must lie in {left}{low:g}, {high:g}]"
                + (" or be .inf" if name in MAY_BE_INFINITE else "")
                + f", not {value:g} (a unit mistake? SI units: N, m, Pa)"
            )


def _check_keys(data: dict[str, Any], where: Path) -> None:
    check_keys(data, KEYS, f"{where}")
    for section, keys in KEYS.items():
        block = data.get(section)
        if not isinstance(block, dict):
            continue  # _validate says it is missing
        check_keys(block, keys, f"{where}: {section}")
        if isinstance(keys, dict):
            for name, inner in keys.items():
                if inner and isinstance(block.get(name), dict):
                    check_keys(block[name], inner, f"{where}: {section}.{name}")


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
    path: str | Path | None = None, overrides: Mapping[str, float] | None = None, option: str = "--set"
) -> BridgeConfig:
    """Read ``bridge.yaml`` (default ``config/bridge.yaml``) and apply ``overrides`` (named ``option``)."""
    file = Path(path) if path is not None else config_file("bridge.yaml")
    try:
        raw = file.read_bytes()
    except OSError as err:
        raise ConfigError(f"{file}: cannot read bridge model ({err.strerror})") from err
    try:
        data = _floatify(load_yaml(raw))
    except yaml.YAMLError as err:
        raise ConfigError(f"{file}: not valid YAML at {yaml_problem(err)}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: not a bridge model (top level must be a mapping)")
    _check_keys(data, file)
    cfg = BridgeConfig(data, file, hashlib.sha256(raw).hexdigest())
    _validate(cfg)
    _check_ranges(cfg.params, f"{file}: parameter ")
    _check_ranges(overrides or {}, f"{option} ")
    return cfg.with_overrides(overrides or {})


def file_sha256(path: str | Path | None = None) -> str:
    """Return the sha256 hex digest of ``bridge.yaml`` (default location)."""
    file = Path(path) if path is not None else config_file("bridge.yaml")
    return hashlib.sha256(file.read_bytes()).hexdigest()
