"""Flat 4-node shell, 6 DOF per node, vectorized over all elements of a set.

* Bending: MITC4 (Bathe-Dvorkin) Reissner-Mindlin plate, transverse shear tied at the edge
  midpoints, so it does not lock when thin.
* Membrane: GCMQ (Chang et al. 2019, :mod:`bridge_shadow.fe.elements.membrane`), a drilling
  quadrilateral whose nodal in-plane rotations bend its edges (generalized conforming, Allman-like)
  with a second-order equilibrated stress field and one enhanced strain mode. It passes the patch
  test on any convex quad and does not lock in in-plane bending on trapezoids or parallelograms
  (MacNeal-Harder: 0.96-0.99). A small Hughes-Brezzi penalty ``DRILL_FACTOR * G`` on the
  area-averaged rotation removes its one spurious mode (equal drilling rotations, no translation).
* Warped quads: the element is built on the mean plane (normal from the diagonals, through the
  centroid) and tied to the real nodes by rigid offsets along the normal (the usual warping
  correction), so rigid-body motions stay force-free.

Local DOF order per node ``(u, v, w, rx, ry, rz)``; the plate kinematics are
``u(z) = z ry``, ``v(z) = -z rx``, curvatures ``kx = ry,x``, ``ky = -rx,y``, ``kxy = ry,y - rx,x``,
shear ``gxz = w,x + ry``, ``gyz = w,y - rx``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bridge_shadow.fe.elements.membrane import membrane_stiffness, membrane_thermal_vector
from bridge_shadow.fe.errors import ModelError

__all__ = [
    "DRILL_FACTOR",
    "ShellKinematics",
    "shell_kinematics",
    "shell_mass_vector",
    "shell_pressure_vector",
    "shell_stiffness",
    "shell_thermal_vector",
]

#: Drilling penalty ``gamma / G`` on the area-averaged ``theta_z - omega``. The GCMQ membrane is stiff
#: in every drilling mode but one (all four rotations equal, no translation); the penalty exists only
#: to remove that mechanism, so it is set small and fixed a priori: three decades below the shear
#: modulus, far above round-off. ``bridge-shadow verify`` sweeps it over six decades (1e-6 to 1) and
#: reports the spread of every case; the choice moves no toleranced case by more than its tolerance.
DRILL_FACTOR = 1.0

_XI = np.array([-1.0, 1.0, 1.0, -1.0])
_ETA = np.array([-1.0, -1.0, 1.0, 1.0])
_G = 1.0 / np.sqrt(3.0)
_GP = np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]])  # 2x2 Gauss points, weights 1


def _shape(xi: float, eta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bilinear shape functions and their natural derivatives at one point, each (4,)."""
    n = 0.25 * (1 + _XI * xi) * (1 + _ETA * eta)
    dxi = 0.25 * _XI * (1 + _ETA * eta)
    deta = 0.25 * _ETA * (1 + _XI * xi)
    return n, dxi, deta


@dataclass
class ShellKinematics:
    """Geometry of a shell set on its mean planes.

    Attributes:
        frame: (n_el, 3, 3) rows e1, e2, e3 (e3 the normal) of each element's local axes.
        xy: (n_el, 4, 2) m, nodal coordinates in the mean plane.
        warp: (n_el, 4) m, offset of each node from the mean plane along e3.
        n: (4, 4) shape functions at the 4 Gauss points; dndx: (n_el, 4, 2, 4) Cartesian derivatives.
        dA: (n_el, 4) m^2, Gauss weight times det J.

    """

    frame: np.ndarray
    xy: np.ndarray
    warp: np.ndarray
    n: np.ndarray
    dndx: np.ndarray
    dA: np.ndarray
    jac: np.ndarray

    def node_transforms(self) -> np.ndarray:
        """``T (n_el, 4, 6, 6)``: flat local DOFs of each node from its global DOFs (offset, then rotation).

        Flat DOFs follow the real nodes through rigid offsets to the mean plane
        (``u_flat = u - z ry``, ``v_flat = v + z rx``, local axes); each 3-vector is rotated by ``frame``.
        """
        n_el = len(self.frame)
        t = np.zeros((n_el, 4, 6, 6))
        t[:, :, 0:3, 0:3] = self.frame[:, None]
        t[:, :, 3:6, 3:6] = self.frame[:, None]
        t[:, :, 0, 3:6] = -self.warp[:, :, None] * self.frame[:, None, 1, :]
        t[:, :, 1, 3:6] = self.warp[:, :, None] * self.frame[:, None, 0, :]
        return t

    def to_global(self, kf: np.ndarray) -> np.ndarray:
        """``T^T kf T`` for flat local matrices ``kf (n_el, 24, 24)``, node block by node block."""
        n_el = len(kf)
        t = self.node_transforms()
        k = kf.reshape(n_el, 24, 4, 6).transpose(0, 2, 1, 3) @ t  # K T, column block b: (n_el, 4, 24, 6)
        k = k.transpose(0, 2, 1, 3).reshape(n_el, 4, 6, 24)
        return (np.swapaxes(t, 2, 3) @ k).reshape(n_el, 24, 24)  # T^T (K T), row block a

    def vector_to_global(self, ff: np.ndarray) -> np.ndarray:
        """``T^T ff`` for flat local load vectors ``ff (n_el, 24)``."""
        f = ff.copy()
        z = self.warp
        for a in range(4):
            f[:, 6 * a + 4] -= z[:, a] * f[:, 6 * a]
            f[:, 6 * a + 3] += z[:, a] * f[:, 6 * a + 1]
        f3 = np.einsum("eji,eaj->eai", self.frame, f.reshape(-1, 8, 3))
        return f3.reshape(-1, 24)


def shell_kinematics(xyz: np.ndarray) -> ShellKinematics:
    """Local frames, mean-plane coordinates, Jacobians and the DOF transformation for quads.

    Args:
        xyz: (n_el, 4, 3) m, nodal coordinates.

    """
    xyz = np.asarray(xyz, float)
    c = xyz.mean(axis=1)
    normal = np.cross(xyz[:, 2] - xyz[:, 0], xyz[:, 3] - xyz[:, 1])
    norm = np.linalg.norm(normal, axis=1)
    if np.any(norm <= 0):
        raise ModelError("degenerate shell element (zero area)")
    e3 = normal / norm[:, None]
    a1 = 0.5 * (xyz[:, 1] + xyz[:, 2] - xyz[:, 0] - xyz[:, 3])
    a1 = a1 - np.einsum("ei,ei->e", a1, e3)[:, None] * e3
    e1 = a1 / np.linalg.norm(a1, axis=1)[:, None]
    e2 = np.cross(e3, e1)
    frame = np.stack([e1, e2, e3], axis=1)
    rel = xyz - c[:, None, :]
    local = np.einsum("eij,ekj->eki", frame, rel)
    xy, warp = local[:, :, :2], local[:, :, 2]
    # the membrane samples the Jacobian at the edge midpoints too (Irons' rule)
    for xi, eta in ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)):
        _, dxi, deta = _shape(xi, eta)
        jx, jy = np.einsum("k,ekj->ej", dxi, xy), np.einsum("k,ekj->ej", deta, xy)
        if np.any(jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0] <= 0):
            raise ModelError("shell element with non-positive Jacobian (node order or a concave quad)")

    ns, dndx, dA, jacs = [], [], [], []
    for xi, eta in _GP:
        n, dxi, deta = _shape(xi, eta)
        jac = np.einsum("k,ekj->ej", dxi, xy), np.einsum("k,ekj->ej", deta, xy)
        jac = np.stack(jac, axis=1)  # (n_el, 2, 2): [[x,xi y,xi], [x,eta y,eta]]
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        if np.any(det <= 0):
            raise ModelError("shell element with non-positive Jacobian (node order or a concave quad)")
        inv = np.linalg.inv(jac)
        ns.append(n)
        dndx.append(inv @ np.stack([dxi, deta])[None])
        dA.append(det)
        jacs.append(jac)
    return ShellKinematics(
        frame=frame,
        xy=xy,
        warp=warp,
        n=np.array(ns),
        dndx=np.stack(dndx, axis=1),
        dA=np.stack(dA, axis=1),
        jac=np.stack(jacs, axis=1),
    )


def _bending_b(kin: ShellKinematics) -> tuple[np.ndarray, np.ndarray]:
    """Bending B (n_el, 4, 3, 12) and MITC4 shear B (n_el, 4, 2, 12); DOFs (w, rx, ry) per node."""
    n_el = len(kin.xy)
    dx, dy = kin.dndx[:, :, 0, :], kin.dndx[:, :, 1, :]
    bb = np.zeros((n_el, 4, 3, 12))
    bb[:, :, 0, 2::3] = dx
    bb[:, :, 1, 1::3] = -dy
    bb[:, :, 2, 2::3] = dy
    bb[:, :, 2, 1::3] = -dx

    def covariant(xi: float, eta: float, along_xi: bool) -> np.ndarray:
        """Row (n_el, 12) of the covariant shear e_xi (or e_eta) at a tying point."""
        n, dxi, deta = _shape(xi, eta)
        dn = dxi if along_xi else deta
        xt = np.einsum("k,ekj->ej", dn, kin.xy)  # (n_el, 2): x,t and y,t
        row = np.zeros((n_el, 12))
        row[:, 0::3] = dn
        row[:, 2::3] = n[None] * xt[:, 0:1]
        row[:, 1::3] = -n[None] * xt[:, 1:2]
        return row

    exi_m, exi_p = covariant(0.0, -1.0, True), covariant(0.0, 1.0, True)
    eeta_m, eeta_p = covariant(-1.0, 0.0, False), covariant(1.0, 0.0, False)
    bs = np.zeros((n_el, 4, 2, 12))
    for q, (xi, eta) in enumerate(_GP):
        nat = np.stack(
            [
                0.5 * (1 - eta) * exi_m + 0.5 * (1 + eta) * exi_p,
                0.5 * (1 - xi) * eeta_m + 0.5 * (1 + xi) * eeta_p,
            ],
            axis=1,
        )
        bs[:, q] = np.linalg.solve(kin.jac[:, q], nat)
    return bb, bs


def _btdb(b: np.ndarray, d: np.ndarray | None, w: np.ndarray) -> np.ndarray:
    """Sum over Gauss points of ``w B^T D B``: b (n_el, q, r, m), d (n_el, r, r) or None, w (n_el, q)."""
    db = b if d is None else np.einsum("eab,eqbj->eqaj", d, b)
    n_el, q, r, m = b.shape
    left = (b * w[:, :, None, None]).reshape(n_el, q * r, m)
    return np.swapaxes(left, 1, 2) @ db.reshape(n_el, q * r, m)


def _material(E: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Plane-stress matrix (n_el, 3, 3) per unit thickness, Pa."""
    c = np.zeros((len(E), 3, 3))
    f = E / (1 - nu**2)
    c[:, 0, 0] = c[:, 1, 1] = f
    c[:, 0, 1] = c[:, 1, 0] = f * nu
    c[:, 2, 2] = f * (1 - nu) / 2
    return c


def _flat_to_dofs() -> tuple[np.ndarray, np.ndarray]:
    """Positions of the 12 membrane (u, v, rz) and 12 bending (w, rx, ry) DOFs among 24."""
    memb = np.array([6 * a + d for a in range(4) for d in (0, 1, 5)])
    bend = np.array([6 * a + d for a in range(4) for d in (2, 3, 4)])
    return memb, bend


def shell_stiffness(
    xyz: np.ndarray,
    thickness: np.ndarray,
    E: np.ndarray,
    nu: np.ndarray,
    kin: ShellKinematics | None = None,
    drill_factor: float | np.ndarray = DRILL_FACTOR,
) -> np.ndarray:
    """Element stiffness matrices in global axes.

    Args:
        xyz: (n_el, 4, 3) m. thickness, E, nu: (n_el,).
        kin: precomputed kinematics (optional).
        drill_factor: drilling penalty over the shear modulus, scalar or (n_el,) (removes the one
            spurious mode).

    Returns:
        ke: (n_el, 24, 24) float, N/m, N and N m, global DOF order ``(ux, uy, uz, rx, ry, rz)`` per node.

    """
    kin = shell_kinematics(xyz) if kin is None else kin
    t = np.asarray(thickness, float)
    E, nu = np.asarray(E, float), np.asarray(nu, float)
    c = _material(E, nu)
    shear_mod = E / (2 * (1 + nu))
    km = membrane_stiffness(kin.xy, t, E, nu, drill_factor * shear_mod, (kin.n, kin.dndx, kin.dA))

    bb, bs = _bending_b(kin)
    db = c * (t**3 / 12.0)[:, None, None]
    ds = (5.0 / 6.0) * shear_mod * t
    kb = _btdb(bb, db, kin.dA) + _btdb(bs, None, kin.dA * ds[:, None])

    memb, bend = _flat_to_dofs()
    kf = np.zeros((len(t), 24, 24))
    kf[:, memb[:, None], memb[None, :]] = km
    kf[:, bend[:, None], bend[None, :]] = kb
    return kin.to_global(kf)


def shell_thermal_vector(
    kin: ShellKinematics,
    thickness: np.ndarray,
    E: np.ndarray,
    nu: np.ndarray,
    alpha: np.ndarray,
    d_uniform: np.ndarray,
    d_gradient: np.ndarray,
) -> np.ndarray:
    """Equivalent nodal loads (n_el, 24), global axes, of a uniform change and a through-thickness gradient.

    ``d_gradient`` is the temperature of the +normal face minus the -normal face (K); free thermal
    strain ``alpha (d_uniform + d_gradient z / t)``. Each of ``d_uniform``, ``d_gradient`` is
    ``(n_el,)`` (constant per element) or ``(n_el, 4)`` (nodal values, interpolated bilinearly).
    """
    t = np.asarray(thickness, float)
    n_el = len(t)
    c = _material(np.asarray(E, float), np.asarray(nu, float))
    ones = np.array([1.0, 1.0, 0.0])

    def at_gauss(d: np.ndarray) -> np.ndarray:
        d = np.asarray(d, float)
        return np.broadcast_to(d[:, None], (n_el, 4)) if d.ndim == 1 else d @ kin.n.T

    cu = np.einsum("eab,b->ea", c, ones)
    m_t = cu[:, None, :] * (t**2 / 12.0 * alpha)[:, None, None] * at_gauss(d_gradient)[:, :, None]
    bb, _ = _bending_b(kin)
    du = np.asarray(d_uniform, float)
    du = np.broadcast_to(du[:, None], (n_el, 4)) if du.ndim == 1 else du
    fm = membrane_thermal_vector(kin.xy, t, np.asarray(E, float), np.asarray(nu, float), alpha, du)
    fb = np.einsum("eq,eqai,eqa->ei", kin.dA, bb, m_t)
    memb, bend = _flat_to_dofs()
    ff = np.zeros((len(t), 24))
    ff[:, memb] = fm
    ff[:, bend] = fb
    return kin.vector_to_global(ff)


def shell_nodal_areas(kin: ShellKinematics) -> np.ndarray:
    """Consistent nodal areas ``integral N_i dA`` (n_el, 4), m^2."""
    return np.einsum("eq,qa->ea", kin.dA, kin.n)


def shell_pressure_vector(kin: ShellKinematics, pressure_pa: np.ndarray) -> np.ndarray:
    """Nodal forces (n_el, 24), global axes, of a traction ``p n`` (positive along the element normal)."""
    areas = shell_nodal_areas(kin) * np.asarray(pressure_pa, float)[:, None]
    f = np.zeros((len(areas), 4, 6))
    f[:, :, 0:3] = areas[:, :, None] * kin.frame[:, None, 2, :]
    return f.reshape(len(areas), 24)


def shell_mass_vector(
    kin: ShellKinematics, thickness: np.ndarray, rho: np.ndarray, g: np.ndarray
) -> np.ndarray:
    """Self-weight nodal forces (n_el, 24), global axes, for acceleration ``g`` (3,) m/s^2."""
    mass = shell_nodal_areas(kin) * (np.asarray(thickness) * np.asarray(rho))[:, None]
    f = np.zeros((len(mass), 4, 6))
    f[:, :, 0:3] = mass[:, :, None] * np.asarray(g, float)[None, None, :]
    return f.reshape(len(mass), 24)
