"""Laws every stiffness must obey: symmetry, rigid-body modes, patch tests, Schur condensation, statics."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from bridge_shadow.fe import (
    BeamLoad,
    BeamSet,
    LinearStaticSolver,
    LoadCase,
    Model,
    ModelError,
    RigidLinks,
    ShellSet,
    SolverError,
    SpringSet,
    Support,
    Thermal,
    schur_complement,
)
from bridge_shadow.fe.elements.beam import beam_geometry, beam_stiffness
from bridge_shadow.fe.elements.shell import shell_stiffness
from bridge_shadow.fe.meshes import grid, node_at
from bridge_shadow.fe.verify import patch_test

RNG = np.random.default_rng(20261123)


def _random_quads(n: int, warp: float) -> np.ndarray:
    """Random convex-ish quads in random 3D orientations, nodes lifted off their plane by ``warp``."""
    base = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    xy = base[None] + RNG.uniform(-0.2, 0.2, (n, 4, 2))
    xyz = np.concatenate([xy, warp * RNG.uniform(-1, 1, (n, 4, 1))], axis=2)
    q, _ = np.linalg.qr(RNG.normal(size=(n, 3, 3)))
    return np.einsum("eij,ekj->eki", q, xyz) + RNG.normal(size=(n, 1, 3))


def _rigid_modes(xyz: np.ndarray) -> np.ndarray:
    """Six rigid-body motions of the nodes ``xyz (n_el, m, 3)`` as ``(n_el, 6 m, 6)``."""
    n_el, m, _ = xyz.shape
    modes = np.zeros((n_el, m, 6, 6))
    for k in range(3):
        modes[:, :, k, k] = 1.0  # translation
        theta = np.eye(3)[k]
        modes[:, :, 0:3, 3 + k] = np.cross(theta, xyz)  # u = theta x x
        modes[:, :, 3 + k, 3 + k] = 1.0
    return modes.reshape(n_el, 6 * m, 6)


@pytest.mark.parametrize("warp", [0.0, 0.05])
def test_shell_symmetric_and_rigid_body_free(warp: float) -> None:
    xyz = _random_quads(50, warp)
    n = len(xyz)
    ke = shell_stiffness(xyz, np.full(n, 0.02), np.full(n, 2e11), np.full(n, 0.3))
    scale = np.abs(ke).max()
    assert np.abs(ke - np.swapaxes(ke, 1, 2)).max() < 1e-12 * scale
    assert np.abs(ke @ _rigid_modes(xyz)).max() < 1e-9 * scale
    # positive semi-definite with exactly six zero modes
    eig = np.linalg.eigvalsh(ke)
    assert eig.min() > -1e-9 * scale
    assert np.all(np.sum(eig < 1e-8 * scale, axis=1) == 6)


def test_beam_with_offsets_symmetric_and_rigid_body_free() -> None:
    n = 40
    xi, xj = RNG.normal(size=(n, 3)), RNG.normal(size=(n, 3))
    geo = beam_geometry(
        xi, xj, RNG.normal(size=(n, 3)), 0.3 * RNG.normal(size=(n, 3)), 0.3 * RNG.normal(size=(n, 3))
    )
    ones = np.ones(n)
    ke = beam_stiffness(
        geo,
        0.01 * ones,
        2e-4 * ones,
        1e-4 * ones,
        5e-5 * ones,
        2e11 * ones,
        8e10 * ones,
        0.005 * ones,
        0.004 * ones,
    )
    scale = np.abs(ke).max()
    assert np.abs(ke - np.swapaxes(ke, 1, 2)).max() < 1e-12 * scale
    assert np.abs(ke @ _rigid_modes(np.stack([xi, xj], axis=1))).max() < 1e-9 * scale


def _random_patch_inner() -> np.ndarray:
    """Random interior nodes (4, 2) of the MacNeal-Harder patch, redrawn until all five quads are convex."""
    from bridge_shadow.fe.verify.shells import _patch_mesh

    nodes, conn = _patch_mesh()
    while True:
        inner = np.array([[0.06, 0.03], [0.18, 0.03], [0.18, 0.09], [0.06, 0.09]]) + RNG.uniform(
            -0.025, 0.025, (4, 2)
        )
        xy = np.vstack([nodes[:4, :2], inner])[conn]  # (5, 4, 2)
        edge = np.roll(xy, -1, axis=1) - xy
        nxt = np.roll(edge, -1, axis=1)
        if np.all(edge[:, :, 0] * nxt[:, :, 1] - edge[:, :, 1] * nxt[:, :, 0] > 0):
            return inner


@pytest.mark.parametrize("kind", ["membrane", "bending"])
def test_patch_test_random_distortion(kind: str) -> None:
    for _ in range(5):
        assert patch_test(kind, inner=_random_patch_inner()).value < 1e-8


def test_membrane_patch_test_with_rigid_spin() -> None:
    """A constant strain plus a rigid in-plane rotation is exact too; the drilling DOFs follow the spin."""
    for _ in range(3):
        assert patch_test("membrane", inner=_random_patch_inner(), spin=2e-3).value < 1e-8


def _plane_quads(n: int) -> np.ndarray:
    """Random convex quads in the x-y plane, (n, 4, 2), counter-clockwise."""
    base = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    return base[None] * RNG.uniform(0.5, 3.0, (n, 1, 2)) + RNG.uniform(-0.2, 0.2, (n, 4, 2))


@pytest.mark.parametrize(("gamma", "zero_modes"), [(0.0, 4), (8e10, 3)])
def test_gcmq_membrane_modes(gamma: float, zero_modes: int) -> None:
    """GCMQ alone has 3 rigid modes plus equal drilling rotations; the drilling penalty removes the last."""
    from bridge_shadow.fe.elements.membrane import membrane_stiffness
    from bridge_shadow.fe.elements.shell import shell_kinematics

    xy = _plane_quads(40)
    n = len(xy)
    kin = shell_kinematics(np.concatenate([xy, np.zeros((n, 4, 1))], axis=2))
    ones = np.ones(n)
    gauss = (kin.n, kin.dndx, kin.dA)
    ke = membrane_stiffness(kin.xy, 0.02 * ones, 2e11 * ones, 0.3 * ones, gamma * ones, gauss)
    scale = np.abs(ke).max()
    assert np.abs(ke - np.swapaxes(ke, 1, 2)).max() < 1e-12 * scale
    eig = np.linalg.eigvalsh(ke)
    assert eig.min() > -1e-10 * scale
    assert np.all(np.sum(eig < 1e-9 * scale, axis=1) == zero_modes)


def test_free_uniform_temperature_on_a_distorted_patch_is_exact() -> None:
    """A uniform temperature change expands a patch of distorted quads freely: u = alpha dT x, no stress."""
    from bridge_shadow.fe.verify.shells import _patch_mesh

    nodes, conn = _patch_mesh()
    nodes[4:, :2] += RNG.uniform(-0.01, 0.01, (4, 2))
    alpha, dT = 1.2e-5, 25.0
    plate = ShellSet(conn, 0.01, 2.1e11, 0.3, alpha=alpha, tag="patch")
    supports = [
        Support("origin", [0], (0, 1)),
        Support("roller", [1], (1,)),  # node 1 sits on the x axis
        Support("flat", np.arange(8), (2, 3, 4)),
    ]
    solver = LinearStaticSolver(Model(nodes, shells=[plate], supports=supports))
    res = solver.solve(LoadCase("warm", thermal=[Thermal("patch", uniform=dT)]))
    np.testing.assert_allclose(res.u[:, :2], alpha * dT * nodes[:, :2], rtol=1e-10, atol=1e-16)
    np.testing.assert_allclose(res.u[:, 5], 0.0, atol=1e-14)  # no rotation anywhere
    assert abs(res.reaction("roller", "uy")) < 1e-6


def _cantilever(n: int = 8, L: float = 2.0, shear: bool = False) -> tuple[Model, dict[str, float]]:
    p = {"E": 2e11, "G": 8e10, "A": 0.01, "I": 2e-5, "As": 0.004, "L": L}
    x = np.linspace(0, L, n + 1)
    beam = BeamSet(
        np.column_stack([np.arange(n), np.arange(1, n + 1)]),
        A=p["A"],
        Iy=p["I"],
        Iz=p["I"],
        J=p["I"],
        E=p["E"],
        G=p["G"],
        Asy=p["As"] if shear else None,
        Asz=p["As"] if shear else None,
        tag="b",
    )
    nodes = np.column_stack([x, 0 * x, 0 * x])
    return Model(nodes, beams=[beam], supports=[Support("root", [0], range(6))]), p


def test_timoshenko_cantilever_tip_deflection() -> None:
    model, p = _cantilever(shear=True)
    res = LinearStaticSolver(model).solve(LoadCase("tip", nodal=[(8, 2, -1000.0)]))
    exact = 1000.0 * p["L"] ** 3 / (3 * p["E"] * p["I"]) + 1000.0 * p["L"] / (p["G"] * p["As"])
    assert -res.u[8, 2] == pytest.approx(exact, rel=1e-10)
    assert res.reaction("root", "uz") == pytest.approx(1000.0, rel=1e-12)
    assert res.reaction("root", "ry") == pytest.approx(-1000.0 * p["L"], rel=1e-10)


def test_rigid_link_equals_end_offset_and_closed_form() -> None:
    e, F = 0.5, 1000.0
    model, p = _cantilever()
    nodes = np.vstack([model.nodes, [p["L"], 0.0, e]])
    linked = Model(nodes, beams=model.beams, supports=model.supports, links=[RigidLinks([8], [9])])
    r1 = LinearStaticSolver(linked).solve(LoadCase("push", nodal=[(9, 0, F)]))
    # the same with the last element ending at an offset point
    b = model.beams[0]
    off = np.zeros((8, 3))
    off[-1] = (0.0, 0.0, e)
    conn = b.conn.copy()
    conn[-1, 1] = 9
    beam2 = BeamSet(conn, A=b.A, Iy=b.Iy, Iz=b.Iz, J=b.J, E=b.E, G=b.G, offset_j=-off, tag="b")
    parked = Support("parked", [8], range(6))  # node 8 is unused in this variant
    r2 = LinearStaticSolver(Model(nodes, beams=[beam2], supports=[*model.supports, parked])).solve(
        LoadCase("push", nodal=[(9, 0, F)])
    )
    # a +x force at +z has moment +F e about y: tip ry = F e L / EI, w = -F e L^2 / (2 EI)
    theta = F * e * p["L"] / (p["E"] * p["I"])
    np.testing.assert_allclose(r1.u[8, 4], theta, rtol=1e-10)
    np.testing.assert_allclose(r1.u[8, 2], -F * e * p["L"] ** 2 / (2 * p["E"] * p["I"]), rtol=1e-10)
    np.testing.assert_allclose(r1.u[9, 0], F * p["L"] / (p["E"] * p["A"]) + e * theta, rtol=1e-10)
    np.testing.assert_allclose(r2.u[9], r1.u[9], rtol=1e-10, atol=1e-15)


def _two_supports() -> LinearStaticSolver:
    """A shell plate on four corner bearings plus a spring pair, with two named rigid bearings."""
    st, conn = grid(8, 4)
    nodes = np.column_stack([st[:, 0] * 8.0, st[:, 1] * 4.0, 0 * st[:, 0]])
    plate = ShellSet(conn, 0.2, 3e10, 0.2, rho=2500.0, tag="slab")
    c = [node_at(nodes, p) for p in ((0, 0, 0), (8, 0, 0), (8, 4, 0), (0, 4, 0))]
    south, north = node_at(nodes, (4, 0, 0)), node_at(nodes, (4, 4, 0))
    supports = [
        Support("corners", c[:1], (0, 1, 2)),
        Support("rollers", c[1:], (2,)),
        Support("guide", [c[3]], (0,)),
        Support("south", [south], (2,)),
        Support("north", [north], (2,)),
    ]
    springs = [SpringSet([c[1]], [-1], [0, 1e6, 0, 0, 0, 0])]
    return LinearStaticSolver(Model(nodes, shells=[plate], springs=springs, supports=supports))


def test_schur_complement_equals_unit_displacement_solves() -> None:
    solver = _two_supports()
    a = solver.support_stiffness(["south", "north"], "uz")
    cons = solver.constraints
    names = ["south", "north"]
    cols = [int(cons.presc_index[n][0, 0]) for n in names]
    c = sp.hstack([cons.cf, cons.cp[:, cols]]).tocsr()
    kg = c.T @ solver.K @ c
    keep = np.arange(cons.cf.shape[1], kg.shape[0])
    s = schur_complement(kg, keep, backend="splu-mmd")
    np.testing.assert_allclose(a, s, rtol=1e-8, atol=1e-8 * np.abs(s).max())
    groups = np.concatenate([cons.free, cons.presc[cols]]) // 6  # node of each column: any ordering agrees
    s_nd = schur_complement(kg, keep, groups=groups)
    np.testing.assert_allclose(s_nd, s, rtol=1e-8, atol=1e-8 * np.abs(s).max())
    assert np.allclose(a, a.T, rtol=1e-8)
    assert np.all(np.linalg.eigvalsh(a) > 0)


def test_batch_solve_equals_single_solves_and_statics() -> None:
    solver = _two_supports()
    cases = [
        LoadCase("dead", gravity=(0, 0, -9.81)),
        LoadCase("settle", prescribed={"south": -0.001}),
        LoadCase("warm", thermal=[Thermal("slab", uniform=10.0, gradient=5.0)]),
    ]
    batch = solver.solve(cases)
    for case, r in zip(cases, batch, strict=True):
        single = solver.solve(case)
        np.testing.assert_allclose(single.u, r.u, rtol=1e-12, atol=1e-18)
    # vertical equilibrium: reactions carry the whole weight
    weight = 8.0 * 4.0 * 0.2 * 2500.0 * 9.81
    total = sum(batch[0].reaction(n, "uz") for n in ("corners", "rollers", "south", "north"))
    assert total == pytest.approx(weight, rel=1e-10)
    # self-equilibrated loads: reactions sum to zero
    for r in batch[1:]:
        total = sum(r.reaction(n, "uz") for n in ("corners", "rollers", "south", "north"))
        assert abs(total) < 1e-8 * weight


def test_elastic_support_reaction_and_ground_shift() -> None:
    k, P, g = 1e7, 5000.0, -0.002
    model, p = _cantilever()
    sup = [Support("root", [0], range(6)), Support("tip", [8], (2,), stiffness=k)]
    solver = LinearStaticSolver(Model(model.nodes, beams=model.beams, supports=sup))
    res = solver.solve(LoadCase("c", nodal=[(8, 2, -P)], prescribed={"tip": g}))
    kb = 3 * p["E"] * p["I"] / p["L"] ** 3
    w = (-P + k * g) / (kb + k)
    assert res.u[8, 2] == pytest.approx(w, rel=1e-10)
    assert res.reaction("tip", "uz") == pytest.approx(k * (g - w), rel=1e-10)
    assert res.reaction("root", "uz") + res.reaction("tip", "uz") == pytest.approx(P, rel=1e-10)


def test_beam_line_load_and_gradient_two_spans() -> None:
    L, q = 10.0, 1.0e4
    x = np.linspace(0.0, 2 * L, 9)
    beam = BeamSet(
        np.column_stack([np.arange(8), np.arange(1, 9)]),
        A=0.01,
        Iy=1e-4,
        Iz=1e-4,
        J=1e-4,
        E=2e11,
        G=8e10,
        orientation=(0, 1, 0),
        tag="g",
    )
    sup = [Support("a", [0], (0, 1, 2, 3)), Support("m", [4], (1, 2)), Support("b", [8], (1, 2))]
    solver = LinearStaticSolver(Model(np.column_stack([x, 0 * x, 0 * x]), beams=[beam], supports=sup))
    # orientation (0, 1, 0) makes local z the global y axis: the vertical load bends about local z
    r = solver.solve(LoadCase("q", beam_loads=[BeamLoad("g", (0, 0, -q))]))
    assert r.reaction("m", "uz") == pytest.approx(5 * q * L / 4, rel=1e-10)
    assert r.reaction("a", "uz") == pytest.approx(3 * q * L / 8, rel=1e-10)


def test_mechanism_and_bad_input_raise_clear_errors() -> None:
    model, _ = _cantilever()
    free = Model(model.nodes, beams=model.beams)
    with pytest.raises(SolverError, match="node"):
        LinearStaticSolver(free).solve(LoadCase("x", nodal=[(8, 2, 1.0)]))
    # a beam line with its torsion left free is a mechanism too
    torsion_free = Support("root", [0], (0, 1, 2, 4, 5))
    with pytest.raises(SolverError, match="rx"):
        LinearStaticSolver(Model(model.nodes, beams=model.beams, supports=[torsion_free]))
    solver = LinearStaticSolver(model)
    with pytest.raises(ModelError):
        solver.solve(LoadCase("x", prescribed={"nowhere": 0.0}))
    with pytest.raises(ModelError):
        solver.solve(LoadCase("x", thermal=[Thermal("nothing", uniform=1.0)]))


def test_vtu_round_trip(tmp_path) -> None:
    import meshio

    from bridge_shadow.fe.vtk import write_vtu

    solver = _two_supports()
    res = solver.solve(LoadCase("dead", gravity=(0, 0, -9.81)))
    path = write_vtu(tmp_path / "plate.vtu", solver.model, res)
    mesh = meshio.read(path)
    np.testing.assert_allclose(mesh.points, solver.model.nodes)
    np.testing.assert_allclose(mesh.point_data["dead:displacement"], res.u[:, :3])


def test_shell_girder_linear_temperature_is_stress_free_bending() -> None:
    """A simply supported shell I-girder with T linear over the depth bends freely: w = kappa L^2 / 8."""
    from bridge_shadow.fe.verify import i_girder

    model, _, h, z_nodes = i_girder(10)
    keep = [s for s in model.supports if s.name not in ("mid", "fork_mid")]
    solver = LinearStaticSolver(Model(model.nodes, shells=model.shells, supports=keep))
    dT, alpha, span = 10.0, 1.2e-5, 30.0
    # T linear over the depth: nodal values in the web, and across each flange's thickness too
    tf = 0.036
    grad = [
        Thermal(tag, uniform=dT * (z_nodes[tag] / h - 0.5), gradient=0.0 if tag == "web" else dT * tf / h)
        for tag in ("web", "top", "bottom")
    ]
    res = solver.solve(LoadCase("gradient", thermal=grad))
    mid = node_at(model.nodes, (span / 2, 0.0, 0.0))
    # The GCMQ membrane is exact for constant strain; over the web the strain is linear, and its
    # displacement field lacks the quadratic tangential edge term, so a self-stress of a few 1e-5 of
    # the deflection remains (1.9e-5 at this mesh, the same order at 5 and 20 elements per span).
    assert res.u[mid, 2] == pytest.approx(alpha * dT / h * span**2 / 8, rel=1e-4)
    restrained = 2.1e11 * (0.019 + 2 * 0.3 * tf) * alpha * dT  # N, force a full restraint would take
    assert abs(res.reaction("west", "uz")) < 1e-9 * restrained


def test_concave_quad_is_refused() -> None:
    """A quad whose Jacobian vanishes at an edge midpoint, where the membrane samples it, is a ModelError."""
    from bridge_shadow.fe.elements.shell import shell_kinematics

    dart = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.2, 0.2, 0.0], [0.0, 1.0, 0.0]]])
    with pytest.raises(ModelError, match="concave"):
        shell_kinematics(dart)


def test_cholmod_backend_equals_superlu() -> None:
    """The optional CHOLMOD factorization (scikit-sparse) solves the same system as SuperLU."""
    pytest.importorskip("sksparse.cholmod", reason="scikit-sparse is optional (GPL; see README)")
    from bridge_shadow.fe.solve import Factorization

    solver = _two_supports()
    cholmod = LinearStaticSolver(solver.model, backend="cholmod")
    assert cholmod.backend == "cholmod"
    cases = [LoadCase("dead", gravity=(0, 0, -9.81)), LoadCase("settle", prescribed={"south": -0.001})]
    for a, b in zip(solver.solve(cases), cholmod.solve(cases), strict=True):
        np.testing.assert_allclose(b.u, a.u, rtol=1e-9, atol=1e-12 * np.abs(a.u).max())
    np.testing.assert_allclose(
        cholmod.support_stiffness(["south", "north"]), solver.support_stiffness(["south", "north"]), rtol=1e-9
    )
    # a mechanism is refused with a SolverError, as with SuperLU
    k = sp.diags([1.0, 2.0, 0.0]).tocsc()
    with pytest.raises(SolverError):
        Factorization(k, backend="cholmod")


def test_package_docstring_example_runs() -> None:
    """The usage example in ``bridge_shadow.fe``'s docstring runs and gives the closed forms."""
    import bridge_shadow.fe as fe

    block = fe.__doc__.split("::")[1].split("Modules:")[0]
    ns: dict[str, object] = {}
    exec("\n".join(line[4:] for line in block.splitlines()), ns)
    ei, L = 210e9 * 1e-4, 10.0
    assert ns["settle"].reaction("mid", "uz") == pytest.approx(-6 * ei * 1e-3 / L**3, rel=1e-9)  # type: ignore[attr-defined]
    assert ns["dead"].reaction("mid", "uz") == pytest.approx(5 * 25e3 * L / 4, rel=1e-9)  # type: ignore[attr-defined]
    np.testing.assert_allclose(ns["A"], [[6 * ei / L**3]], rtol=1e-9)
