"""Bundled linear static FE solver (numpy/scipy, no ROS): shells, beams, springs, links, supports.

Arrays carry the work: a :class:`Model` holds ``nodes (n, 3)`` and element sets with connectivity
arrays; element matrices are built for a whole set at once and assembled from COO triplets.
Units are SI; 6 DOFs per node ``(ux, uy, uz, rx, ry, rz)`` in global axes (z up in the bridge).

Example (a 2 x 10 m continuous beam, settle the middle support by 1 mm)::

    import numpy as np
    from bridge_shadow.fe import BeamLoad, BeamSet, LinearStaticSolver, LoadCase, Model, Support

    x = np.linspace(0.0, 20.0, 21)
    nodes = np.column_stack([x, 0 * x, 0 * x])
    beam = BeamSet(conn=np.column_stack([np.arange(20), np.arange(1, 21)]), A=0.01, Iy=1e-4,
                   Iz=1e-4, J=1e-4, E=210e9, G=81e9, tag="girder")
    model = Model(nodes, beams=[beam], supports=[
        Support("west", [0], dofs=(0, 1, 2, 3)), Support("mid", [10], dofs=(1, 2)),
        Support("east", [20], dofs=(1, 2))])
    solver = LinearStaticSolver(model)                      # assembles and factorizes once
    settle, dead = solver.solve([
        LoadCase("settle", prescribed={"mid": [0.0, -1e-3]}),
        LoadCase("dead", beam_loads=[BeamLoad("girder", (0, 0, -25e3))])])
    settle.reaction("mid", "uz")                            # N, = -6 EI delta / L^3
    A = solver.support_stiffness(["mid"], "uz")             # Schur complement, N/m

Modules: ``model`` (data), ``elements/`` (shell: MITC4 bending + GCMQ drilling membrane; beam;
spring), ``assembly``, ``loads``, ``constraints`` (rigid links, prescribed DOFs), ``solve`` (factorize
once, many cases, reactions by support name), ``condense`` (Schur complement), ``vtk`` (.vtu export),
``verify/`` (benchmark cases and sweeps behind ``bridge-shadow verify``).
"""

from bridge_shadow.fe.condense import schur_complement
from bridge_shadow.fe.errors import FEError, ModelError, SolverError
from bridge_shadow.fe.model import (
    DOF_NAMES,
    BeamLoad,
    BeamSet,
    LoadCase,
    Model,
    RigidLinks,
    ShellSet,
    SpringSet,
    Support,
    Thermal,
)
from bridge_shadow.fe.solve import LinearStaticSolver, Result, assemble_stiffness

__all__ = [
    "DOF_NAMES",
    "BeamLoad",
    "BeamSet",
    "FEError",
    "LinearStaticSolver",
    "LoadCase",
    "Model",
    "ModelError",
    "Result",
    "RigidLinks",
    "ShellSet",
    "SolverError",
    "SpringSet",
    "Support",
    "Thermal",
    "assemble_stiffness",
    "schur_complement",
]
