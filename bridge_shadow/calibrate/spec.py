"""The calibration file (``config/calibration.yaml``): record pairs, imposed settlements, explanations.

Keys (SI units)::

    mesh: default                       # FE mesh level of the calibration
    baseline_change: uncertainty        # or linear, or sun (see bridge_shadow.calibrate.change)
    window_s: 10                        # car-free window length, s
    zero: as_built                      # or before: u0 := the first pair's before record's level
    pairs:                              # one or more record pairs with a known imposed settlement
      - name: lowering_10mm
        before: [FILE, ...]             # one bag, or CSV/zip files (forces and temperature)
        after: [FILE, ...]
        imposed_m: [-0.010, -0.010]     # [south, north], m, positive up
        imposed_sd_m: [0.0005, 0.0005]  # the jacks' accuracy, 1 sd, m
    reference:                          # optional: a record whose split each explanation interprets
      name: 2022-03-07 reference state
      record: [FILE, ...]               # or reactions_n: [south, north]
    explanations:                       # optional: name -> parameter list (or "all"); default below
      support_springs: [support_spring_south, support_spring_north]
    choose: average                     # written to the surrogate: the model average over the
                                        # explanations by evidence, the best one, or a name
    priors: sources                     # prior set (bridge_shadow.model.parameters.PRIOR_SETS)

Relative paths resolve against the file's directory, then the shared data directory. Every key
is checked: an unknown one is an error with the key meant (``keys.check_keys``), and each number
must lie in its physical range (``estimate.parameters.specs.VALUE_SPECS``: a settlement under a metre,
the jacks' accuracy in (0, 0.1] m, car-free windows of 0.1 to 600 s), named in the message.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from bridge_shadow.calibrate.change import BASELINE_CHANGES
from bridge_shadow.calibrate.errors import CalibrationError
from bridge_shadow.errors import ConfigError
from bridge_shadow.estimate.parameters.specs import VALUE_SPECS, check_value
from bridge_shadow.fileio import load_yaml
from bridge_shadow.keys import check_keys
from bridge_shadow.model.config import MESH_LEVELS
from bridge_shadow.model.parameters import PARAMETERS, PRIOR_SETS

__all__ = [
    "DEFAULT_EXPLANATIONS",
    "FILE_KEYS",
    "PAIR_KEYS",
    "REFERENCE_KEYS",
    "CalibrationSpec",
    "PairSpec",
    "load_spec",
    "spec_from_dict",
]

#: The keys of a calibration file, of one of its pairs and of its reference (module docstring).
FILE_KEYS = (
    "mesh",
    "baseline_change",
    "window_s",
    "zero",
    "pairs",
    "reference",
    "explanations",
    "choose",
    "priors",
)
#: Where ``x = 0`` is (``zero``): the first pair's before record (its car-free level is ``u0``), or
#: the as-built FE's dead-load reactions.
ZERO_CHOICES = ("before", "as_built")
PAIR_KEYS = ("name", "before", "after", "imposed_m", "imposed_sd_m")
REFERENCE_KEYS = ("name", "record", "reactions_n")

#: The candidate explanations compared by default: name -> calibrated parameters (``all``: every
#: parameter with a prior). The imposed-settlement errors are estimated in every one of them.
DEFAULT_EXPLANATIONS: dict[str, tuple[str, ...]] = {
    "as_built": (),
    "support_springs": ("support_spring_south", "support_spring_north"),
    "slab_joint_opening": ("slab_joint_opening",),
    "connector_slip": ("connector_stiffness",),
    "composite_action": ("composite_action", "dowel_stiffness"),
    "slab_joints": ("slab_joint_normal_stiffness", "slab_joint_rotational_stiffness"),
    "bearing_stiffness": ("bearing_stiffness",),
    "E_concrete": ("E_concrete",),
    "opening_and_springs": ("slab_joint_opening", "support_spring_south", "support_spring_north"),
    "all": tuple(PARAMETERS),
}


@dataclass
class PairSpec:
    """One record pair. Attributes: name; before, after: record paths; imposed_m, imposed_sd_m: (2,) m."""

    name: str
    before: list[str]
    after: list[str]
    imposed_m: np.ndarray
    imposed_sd_m: np.ndarray


@dataclass
class CalibrationSpec:
    """A parsed calibration file (see the module docstring).

    Attributes:
        pairs, mesh, baseline_change, window_s, zero, explanations, choose, priors: as in the file.
        reference_name, reference_record, reference_reactions_n: the optional reference record
            (paths) or reactions (2,) N.
        base_dir: where relative paths start. path, sha256: the file (None when built in code).

    """

    pairs: list[PairSpec]
    mesh: str = "default"
    baseline_change: str = "uncertainty"
    window_s: float = 10.0
    zero: str = "as_built"
    explanations: dict[str, tuple[str, ...]] = field(default_factory=lambda: dict(DEFAULT_EXPLANATIONS))
    choose: str = "average"
    priors: str = "sources"
    reference_name: str = ""
    reference_record: list[str] = field(default_factory=list)
    reference_reactions_n: np.ndarray | None = None
    base_dir: Path | None = None
    path: Path | None = None
    sha256: str | None = None

    def __post_init__(self) -> None:
        if not self.pairs:
            raise CalibrationError("the calibration needs at least one record pair")
        if self.mesh not in MESH_LEVELS:
            raise CalibrationError(f"mesh must be one of {', '.join(MESH_LEVELS)}, got {self.mesh!r}")
        if self.zero not in ZERO_CHOICES:
            raise CalibrationError(f"zero must be one of {', '.join(ZERO_CHOICES)}, got {self.zero!r}")
        if self.baseline_change not in BASELINE_CHANGES:
            raise CalibrationError(
                f"baseline_change must be one of {', '.join(BASELINE_CHANGES)}, got {self.baseline_change!r}"
            )
        for name, names in self.explanations.items():
            unknown = [n for n in names if n not in PARAMETERS]
            if unknown:
                raise CalibrationError(
                    f"explanation {name}: unknown parameter(s) {', '.join(unknown)}; "
                    f"known: {', '.join(PARAMETERS)}"
                )
        if self.choose not in ("best", "average") and self.choose not in self.explanations:
            raise CalibrationError(
                f"choose: {self.choose!r} is neither 'average', 'best' nor an explanation name"
            )
        if self.priors not in PRIOR_SETS:
            raise CalibrationError(f"priors: {self.priors!r} is not a prior set ({', '.join(PRIOR_SETS)})")
        names = [p.name for p in self.pairs]
        if len(set(names)) != len(names):
            raise CalibrationError(f"pair names must be unique, got {names}")
        # a pair read twice under two names counted as independent data (the weights of the
        # explanations moved from 0.83 / 0.17 to 0.58 / 0.42 without a word)
        seen: dict[tuple[tuple[str, ...], tuple[str, ...]], str] = {}
        for pair in self.pairs:
            before, after = (tuple(os.path.normpath(f) for f in files) for files in (pair.before, pair.after))
            if before == after:
                raise CalibrationError(f"pair {pair.name}: its 'before' and 'after' are the same record(s)")
            if (before, after) in seen:
                raise CalibrationError(
                    f"pairs {seen[before, after]} and {pair.name} read the same records: "
                    "a pair counts once (list it once)"
                )
            seen[before, after] = pair.name


def _checked(what: str, value: Any, kind: str, spec: str) -> Any:
    """Return ``value`` checked against ``VALUE_SPECS[spec]``; CalibrationError naming ``what``."""
    try:
        return check_value(what, value, kind, VALUE_SPECS[spec])
    except ConfigError as err:
        raise CalibrationError(str(err)) from None


def _vec2(value: Any, what: str, spec: str) -> np.ndarray:
    return np.asarray(_checked(what, value, "float_pair", spec), float)


def _paths(value: Any, what: str) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, Sequence) and value and all(isinstance(v, str) for v in value):
        return list(value)
    raise CalibrationError(f"{what} must be a path or a list of paths, got {value!r}")


def _explanations(value: Any) -> dict[str, tuple[str, ...]]:
    if value is None:
        return dict(DEFAULT_EXPLANATIONS)
    if not isinstance(value, Mapping) or not value:
        raise CalibrationError("explanations must map a name to a list of parameter names (or 'all')")
    out = {}
    for name, names in value.items():
        if names == "all":
            out[str(name)] = tuple(PARAMETERS)
        elif names is None:
            out[str(name)] = ()
        elif isinstance(names, Sequence) and not isinstance(names, str):
            out[str(name)] = tuple(str(n) for n in names)
        else:
            raise CalibrationError(f"explanation {name}: expected a list of parameter names or 'all'")
    return out


def spec_from_dict(data: Mapping[str, Any], base_dir: Path | None = None) -> CalibrationSpec:
    """Build a spec from plain data (the YAML's content)."""
    if not isinstance(data, Mapping):
        raise CalibrationError("the calibration file must be a mapping")
    check_keys(data, FILE_KEYS, "calibration file", error=CalibrationError)
    raw_pairs = data.get("pairs")
    if not isinstance(raw_pairs, Sequence) or not raw_pairs:
        raise CalibrationError("pairs: need a list of record pairs (before, after, imposed_m, imposed_sd_m)")
    pairs = []
    for i, p in enumerate(raw_pairs):
        if not isinstance(p, Mapping):
            raise CalibrationError(f"pairs[{i}] must be a mapping")
        name = str(p.get("name", f"pair_{i}"))
        check_keys(p, PAIR_KEYS, f"pair {name}", error=CalibrationError)
        for key in ("before", "after", "imposed_m", "imposed_sd_m"):
            if key not in p:
                raise CalibrationError(f"pair {name}: missing {key}")
        pairs.append(
            PairSpec(
                name,
                _paths(p["before"], f"pair {name}: before"),
                _paths(p["after"], f"pair {name}: after"),
                _vec2(p["imposed_m"], f"pair {name}: imposed_m", "settlement_m"),
                # positive: the jacks are never exact
                _vec2(p["imposed_sd_m"], f"pair {name}: imposed_sd_m", "imposed_sd_m"),
            )
        )
    ref = data.get("reference") or {}
    if not isinstance(ref, Mapping):
        raise CalibrationError("reference must be a mapping with record or reactions_n")
    check_keys(ref, REFERENCE_KEYS, "reference", error=CalibrationError)
    return CalibrationSpec(
        pairs=pairs,
        mesh=str(data.get("mesh", "default")),
        baseline_change=str(data.get("baseline_change", "uncertainty")),
        window_s=_checked("window_s", data.get("window_s", 10.0), "float", "calibration_window_s"),
        zero=str(data.get("zero", "as_built")),
        explanations=_explanations(data.get("explanations")),
        choose=str(data.get("choose", "average")),
        priors=str(data.get("priors", "sources")),
        reference_name=str(ref.get("name", "reference")) if ref else "",
        reference_record=_paths(ref["record"], "reference.record") if "record" in ref else [],
        reference_reactions_n=_vec2(ref["reactions_n"], "reference.reactions_n", "reactions_n")
        if "reactions_n" in ref
        else None,
        base_dir=base_dir,
    )


def load_spec(path: str | Path) -> CalibrationSpec:
    """Read a calibration file (see the module docstring)."""
    file = Path(path)
    try:
        raw = file.read_bytes()
    except OSError as err:
        raise CalibrationError(f"{file}: cannot read calibration file ({err.strerror})") from err
    try:
        data = load_yaml(raw)
    except yaml.YAMLError as err:
        raise CalibrationError(f"{file}: not valid YAML ({err})") from err
    try:
        spec = spec_from_dict(data, file.resolve().parent)
    except CalibrationError as err:
        raise CalibrationError(f"{file}: {err}") from None
    spec.path = file
    spec.sha256 = hashlib.sha256(raw).hexdigest()
    return spec
