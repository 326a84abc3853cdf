"""Bridge model description and mesh: sourced config, overrides, geometry facts, equilibrium."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from bridge_shadow.errors import ConfigError
from bridge_shadow.fe import LinearStaticSolver
from bridge_shadow.model.build import build_model, dead_load_case
from bridge_shadow.model.config import MESH_LEVELS, load_bridge_config, parse_overrides
from bridge_shadow.model.mesh import CENTRAL_BEARINGS, END_BEARINGS, build_mesh


@pytest.fixture(scope="module")
def cfg():
    return load_bridge_config()


@pytest.fixture(scope="module")
def coarse(cfg):
    return build_mesh(cfg, "coarse")


def test_every_value_in_bridge_yaml_carries_a_source(root):
    text = (root / "config" / "bridge.yaml").read_text()
    for tag in ("[paper]", "[table]", "[assume]", "[data]", "[EN 1993-1-1"):
        assert tag in text
    # every parameter line is preceded by (or carries) a comment
    lines = text.splitlines()
    start = lines.index("parameters:")
    for i, line in enumerate(lines[start + 1 :], start + 1):
        if line.startswith("mesh:"):
            break
        if line.strip() and not line.lstrip().startswith("#") and "#" not in line:
            assert lines[i - 1].lstrip().startswith("#"), f"no source comment for: {line}"


def test_config_hash_is_the_file_sha256(cfg, root):
    assert cfg.sha256 == hashlib.sha256((root / "config" / "bridge.yaml").read_bytes()).hexdigest()
    assert set(MESH_LEVELS) <= set(cfg.data["mesh"])


def test_overrides_apply_and_are_recorded(cfg):
    new = cfg.with_overrides(parse_overrides(["bearing_stiffness=1e9", "composite_action=0.5"]))
    assert new.params["bearing_stiffness"] == 1e9
    assert new.params["composite_action"] == 0.5
    assert new.overrides == {"bearing_stiffness": 1e9, "composite_action": 0.5}
    assert cfg.params["bearing_stiffness"] != 1e9  # the original is untouched


def test_infinity_is_taken_as_the_messages_and_files_write_it(root):
    """The range message says 'or be .inf'; --set refused '.inf' as not a number."""
    import math

    parsed = parse_overrides(["support_spring_south=.inf", "support_spring_north=+.Inf", "a=inf"])
    assert parsed == {"support_spring_south": math.inf, "support_spring_north": math.inf, "a": math.inf}
    cfg = load_bridge_config(None, {"support_spring_south": math.inf})
    assert cfg.params["support_spring_south"] == math.inf
    with pytest.raises(ConfigError, match=r"^--reality-set support_spring_south must lie in .* or be \.inf"):
        bad = parse_overrides(["support_spring_south=-1"], "--reality-set")
        load_bridge_config(None, bad, "--reality-set")
    with pytest.raises(ConfigError, match=r"^--reality-set x: '\.infx' is not a number"):
        parse_overrides(["x=.infx"], "--reality-set")


@pytest.mark.parametrize(
    "items",
    [["nonsense=1"], ["bearing_stiffness"], ["bearing_stiffness=abc"], ["bearing_stiffness=-1"]],
)
def test_bad_overrides_are_config_errors(cfg, items):
    with pytest.raises(ConfigError):
        cfg.with_overrides(parse_overrides(items))


def test_unknown_mesh_level_is_a_config_error(cfg):
    with pytest.raises(ConfigError, match="mesh level"):
        build_mesh(cfg, "ultra")


def test_girder_shells_reproduce_the_heb1000_section(cfg, coarse):
    """Web + flange shell area per girder = HEB1000 without fillets (table A = 400 cm^2)."""
    sec = cfg.data["sections"]["heb1000"]
    length = sum(cfg.data["geometry"]["spans"])
    area = 0.0
    for tag in ("web", "flange"):
        part = coarse.shells[tag]
        xyz = coarse.nodes[part.conn]
        quad = 0.5 * np.linalg.norm(np.cross(xyz[:, 2] - xyz[:, 0], xyz[:, 3] - xyz[:, 1]), axis=1)
        area += float(np.sum(quad * part.thickness))
    per_girder = area / 2 / length
    expected = sec["tw"] * (sec["h"] - sec["tf"]) + 2 * sec["b"] * sec["tf"]
    assert per_girder == pytest.approx(expected, rel=1e-12)
    assert per_girder == pytest.approx(400e-4, rel=0.01)  # Euronorm table value with fillets


def test_slab_is_segmented_with_joint_springs(cfg, coarse):
    geo = cfg.data["geometry"]
    n_seg = round(sum(geo["spans"]) / geo["segment_length"])
    ny = len(np.unique(np.round(coarse.nodes[coarse.shells["slab"].conn][:, :, 1], 9)))
    # the joints over the hogging zone are a part of their own (slab_joint_opening softens them)
    parts = [coarse.springs["slab_joint"], coarse.springs["slab_joint_hogging"]]
    assert sum(len(p.node_i) for p in parts) == (n_seg - 1) * ny
    assert len(parts[1].node_i) == 3 * ny  # the joints at 12.5, 15 and 17.5 m
    # joint springs connect distinct nodes at the same place
    a = np.concatenate([p.node_i for p in parts])
    b = np.concatenate([p.node_j for p in parts])
    assert np.all(a != b)
    np.testing.assert_allclose(coarse.nodes[a], coarse.nodes[b], atol=1e-9)
    # tributary widths add up to the deck width at each joint (as built: opening 1)
    k_n = sum(p.k[:, 0].sum() for p in parts) / (n_seg - 1)
    assert k_n == pytest.approx(cfg.params["slab_joint_normal_stiffness"] * geo["deck_width"])


def test_bearings_sit_under_the_right_girders(coarse):
    y = {n: coarse.nodes[coarse.bearings[n].ground] for n in (*CENTRAL_BEARINGS, *END_BEARINGS)}
    assert y["FRC-01"][1] < 0 < y["FRC-02"][1]  # south at negative y
    assert y["FRC-01"][0] == pytest.approx(15.0) and y["end_E_N"][0] == pytest.approx(30.0)
    for name in CENTRAL_BEARINGS:
        assert coarse.bearings[name].weights.sum() == pytest.approx(1.0)


def test_dead_load_equilibrium_and_weight(cfg, coarse):
    """The six bearing reactions carry exactly the self-weight computed from element volumes."""
    model = build_model(cfg, coarse)
    res = LinearStaticSolver(model).solve(dead_load_case(cfg))
    total = sum(res.reaction(n, "uz") for n in (*CENTRAL_BEARINGS, *END_BEARINGS))
    g = cfg.data["loads"]["gravity"]
    weight = 0.0
    for s in model.shells:
        xyz = model.nodes[s.conn]
        quad = 0.5 * np.linalg.norm(np.cross(xyz[:, 2] - xyz[:, 0], xyz[:, 3] - xyz[:, 1]), axis=1)
        weight += float(np.sum(quad * s.thickness * s.rho)) * g
    for b in model.beams:
        length = np.linalg.norm(model.nodes[b.conn[:, 1]] - model.nodes[b.conn[:, 0]], axis=1)
        weight += float(np.sum(length * b.A * b.rho)) * g
    assert total == pytest.approx(weight, rel=1e-9)
    # ~25.9 kN/m of dead load over 30 m (DESIGN 3 infers ~25 kN/m from the measured 470 kN)
    assert weight / 30.0 == pytest.approx(25e3, rel=0.1)
