"""Straight 2-node 3D beam, 12 DOF, Timoshenko (interdependent interpolation) or Euler-Bernoulli.

Local DOF order per end ``(u, v, w, rx, ry, rz)``; bending in the x-y plane uses ``(v, rz)`` with
``rz = v'`` and ``Iz``; bending in the x-z plane uses ``(w, ry)`` with ``ry = -w'`` and ``Iy``.
Rigid end offsets tie each beam end to its node: ``u_end = u_node + r x offset``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bridge_shadow.fe.errors import ModelError

__all__ = ["BeamGeometry", "beam_geometry", "beam_line_load_vector", "beam_stiffness", "beam_thermal_vector"]


@dataclass
class BeamGeometry:
    """Local axes and transformation of a beam set.

    Attributes:
        frame: (n_el, 3, 3) rows ex, ey, ez. length: (n_el,) m between the offset ends.
        tt: (n_el, 12, 12) global nodal DOFs -> local end DOFs (offsets, then rotation).

    """

    frame: np.ndarray
    length: np.ndarray
    tt: np.ndarray


def _skew(r: np.ndarray) -> np.ndarray:
    """(n, 3) -> (n, 3, 3) with ``skew(r) @ a == cross(r, a)``."""
    s = np.zeros((len(r), 3, 3))
    s[:, 0, 1], s[:, 0, 2] = -r[:, 2], r[:, 1]
    s[:, 1, 0], s[:, 1, 2] = r[:, 2], -r[:, 0]
    s[:, 2, 0], s[:, 2, 1] = -r[:, 1], r[:, 0]
    return s


def beam_geometry(
    xi: np.ndarray, xj: np.ndarray, orientation: np.ndarray, off_i: np.ndarray, off_j: np.ndarray
) -> BeamGeometry:
    """Frames, lengths and DOF transformation; all inputs (n_el, 3) m (orientation unitless)."""
    a, b = xi + off_i, xj + off_j
    d = b - a
    length = np.linalg.norm(d, axis=1)
    if np.any(length <= 0):
        raise ModelError("beam element of zero length")
    ex = d / length[:, None]
    vz = orientation - np.einsum("ei,ei->e", orientation, ex)[:, None] * ex
    nz = np.linalg.norm(vz, axis=1)
    if np.any(nz < 1e-9 * np.linalg.norm(orientation, axis=1)):
        raise ModelError("beam orientation vector parallel to the beam axis")
    ez = vz / nz[:, None]
    ey = np.cross(ez, ex)
    frame = np.stack([ex, ey, ez], axis=1)
    n_el = len(d)
    off = np.broadcast_to(np.eye(12), (n_el, 12, 12)).copy()
    off[:, 0:3, 3:6] = -_skew(off_i)
    off[:, 6:9, 9:12] = -_skew(off_j)
    rot = np.zeros((n_el, 12, 12))
    for k in range(4):
        rot[:, 3 * k : 3 * k + 3, 3 * k : 3 * k + 3] = frame
    return BeamGeometry(frame=frame, length=length, tt=rot @ off)


def _bending(ei: np.ndarray, length: np.ndarray, phi: np.ndarray, sign: float) -> np.ndarray:
    """(n_el, 4, 4) bending stiffness on (deflection1, rotation1, deflection2, rotation2)."""
    L = length
    f = ei / (L**3 * (1 + phi))
    s = sign
    k = np.empty((len(L), 4, 4))
    k[:, 0] = np.stack([12 + 0 * L, s * 6 * L, -12 + 0 * L, s * 6 * L], axis=1)
    k[:, 1] = np.stack([s * 6 * L, (4 + phi) * L**2, -s * 6 * L, (2 - phi) * L**2], axis=1)
    k[:, 2] = np.stack([-12 + 0 * L, -s * 6 * L, 12 + 0 * L, -s * 6 * L], axis=1)
    k[:, 3] = np.stack([s * 6 * L, (2 - phi) * L**2, -s * 6 * L, (4 + phi) * L**2], axis=1)
    return k * f[:, None, None]


def beam_stiffness(
    geo: BeamGeometry,
    A: np.ndarray,
    Iy: np.ndarray,
    Iz: np.ndarray,
    J: np.ndarray,
    E: np.ndarray,
    G: np.ndarray,
    Asy: np.ndarray | None,
    Asz: np.ndarray | None,
) -> np.ndarray:
    """Element stiffness matrices ``ke (n_el, 12, 12)`` in global axes (N/m, N, N m)."""
    L = geo.length
    n_el = len(L)
    phi_y = np.zeros(n_el) if Asy is None else 12 * E * Iz / (G * Asy * L**2)
    phi_z = np.zeros(n_el) if Asz is None else 12 * E * Iy / (G * Asz * L**2)
    kl = np.zeros((n_el, 12, 12))
    ax = E * A / L
    tor = G * J / L
    for i, j, s in ((0, 0, 1), (0, 6, -1), (6, 0, -1), (6, 6, 1)):
        kl[:, i, j] = s * ax
        kl[:, i + 3, j + 3] = s * tor
    vy = np.array([1, 5, 7, 11])
    wz = np.array([2, 4, 8, 10])
    kl[:, vy[:, None], vy[None, :]] = _bending(E * Iz, L, phi_y, 1.0)
    kl[:, wz[:, None], wz[None, :]] = _bending(E * Iy, L, phi_z, -1.0)
    return np.einsum("eai,eab,ebj->eij", geo.tt, kl, geo.tt)


def beam_thermal_vector(
    geo: BeamGeometry,
    A: np.ndarray,
    Iy: np.ndarray,
    Iz: np.ndarray,
    E: np.ndarray,
    alpha: np.ndarray,
    depth_y: np.ndarray,
    depth_z: np.ndarray,
    d_uniform: np.ndarray,
    d_grad_z: np.ndarray,
    d_grad_y: np.ndarray,
) -> np.ndarray:
    """Equivalent nodal loads (n_el, 12), global axes, for strain ``alpha (dT + gz z/hz + gy y/hy)``."""
    n_el = len(geo.length)
    fl = np.zeros((n_el, 12))
    n_t = E * A * alpha * d_uniform
    fl[:, 0], fl[:, 6] = -n_t, n_t
    my = E * Iy * alpha * d_grad_z / depth_z  # kappa = ry' = alpha gz / hz
    fl[:, 4], fl[:, 10] = -my, my
    mz = -E * Iz * alpha * d_grad_y / depth_y  # strain = -y rz', so rz' = -alpha gy / hy
    fl[:, 5], fl[:, 11] = -mz, mz
    return np.einsum("eai,ea->ei", geo.tt, fl)


def beam_line_load_vector(geo: BeamGeometry, w: np.ndarray) -> np.ndarray:
    """Consistent nodal loads (n_el, 12), global axes, of a uniform force per length ``w (n_el, 3)`` N/m."""
    q = np.einsum("eij,ej->ei", geo.frame, w)
    L = geo.length
    fl = np.zeros((len(L), 12))
    fl[:, 0] = fl[:, 6] = q[:, 0] * L / 2
    fl[:, 1] = fl[:, 7] = q[:, 1] * L / 2
    fl[:, 2] = fl[:, 8] = q[:, 2] * L / 2
    fl[:, 5], fl[:, 11] = q[:, 1] * L**2 / 12, -q[:, 1] * L**2 / 12
    fl[:, 4], fl[:, 10] = -q[:, 2] * L**2 / 12, q[:, 2] * L**2 / 12
    return np.einsum("eai,ea->ei", geo.tt, fl)
