"""GCMQ membrane: 4-node quadrilateral with drilling rotations, vectorized over all elements of a set.

The in-plane part of the flat shell, after Chang, Lee, Carr, Dhakal and Pampanin, "A new drilling
quadrilateral membrane element with high coarse-mesh accuracy using a modified Hu-Washizu
principle", Int. J. Numer. Meth. Engng 118 (2019) 493-514, doi:10.1002/nme.6066 (element GCMQ,
Irons five-point rule: GCMQ-I). Written from the paper's equations; its published MacNeal thin-beam
table is reproduced to four digits (``bridge-shadow verify``, cases ``gcmq_paper_thin_beam_*``).

Fields (local element axes x, y; parent coordinates xi, eta):

* displacement ``u = u_t + u_d``: bilinear in the nodal translations, plus a drilling part
  ``u_d = phi_d d`` with the bubbles ``(1 - xi^2, eta (1 - xi^2), 1 - eta^2, xi (1 - eta^2))`` per
  component. The 8 parameters ``d`` follow from the nodal drilling rotations by the generalized
  conforming condition ``integral_edge u_d ds = integral_edge u_theta ds`` on each edge, where
  ``u_theta`` is the Hermite (beam-like) normal displacement of the edge with end slopes
  ``theta_i, theta_j``: ``d = G^-1 Q theta``. Equal rotations give no ``u_d`` (a rigid rotation
  moves only ``u_t``), rotation differences bend the edges as in Allman's elements;
* stress ``sigma = P alpha``: 11 equilibrated polynomial modes from an Airy function, complete to
  the second order; strain ``epsilon = C P beta`` with ``C`` the plane-stress compliance times E;
* one enhanced strain mode ``F0 (3 xi^2 - 1, 3 eta^2 - 1, 0)``, orthogonal to constant stress.

For a linear elastic material the Hu-Washizu element collapses to a hybrid-stress form
(``D C = E I``)::

    H = int P^T C P dA   N = int P^T B dA   M = int P^T B_enh dA      (Irons 5-point rule)
    K = E t [N^T H^-1 N - N^T H^-1 M (M^T H^-1 M)^-1 M^T H^-1 N]

The element has four zero-energy modes: three rigid-body motions and an equal rotation of all four
nodes with no translation (``n_r = 4`` in the paper). In a shell the last one is a spurious
mechanism, so a penalty ties the area-averaged drilling rotation to the area-averaged rotation
``omega = (v,x - u,y) / 2`` of the bilinear field: ``0.5 gamma t A (theta_bar - omega_bar)^2``
(Hughes-Brezzi in one averaged point). A rigid rotation and every constant-strain state leave it
at zero; under shear with bending it stiffens distorted quads slightly (0.986 -> 0.958 on the
MacNeal-Harder trapezoid at gamma = G; ``verify`` sweeps gamma over six decades).
"""

from __future__ import annotations

import numpy as np

__all__ = ["membrane_stiffness", "membrane_thermal_vector"]

_XI = np.array([-1.0, 1.0, 1.0, -1.0])
_ETA = np.array([-1.0, -1.0, 1.0, 1.0])

#: Irons' five-point rule on the parent square (cubic accuracy): edge midpoints 2/3, centre 4/3.
_IRONS = ((1.0, 0.0, 2 / 3), (-1.0, 0.0, 2 / 3), (0.0, 1.0, 2 / 3), (0.0, -1.0, 2 / 3), (0.0, 0.0, 4 / 3))


def _bubble_matrix_inverse() -> np.ndarray:
    """``G^-1 (8, 8)``: edge integrals ``integral phi_d ds`` (parent length) for both components."""
    r = 4.0 / 3.0
    per_edge = np.array([[r, -r, 0, 0], [0, 0, r, r], [r, r, 0, 0], [0, 0, r, -r]])  # edges 12, 23, 34, 41
    g = np.zeros((8, 8))
    for e in range(4):
        for comp in range(2):
            g[2 * e + comp, comp::2] = per_edge[e]
    return np.linalg.inv(g)


_G_INV = _bubble_matrix_inverse()


def _stress_modes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Equilibrated stress modes ``P (n_el, 3, 11)`` at points ``x, y (n_el,)`` (scaled local axes)."""
    one, zero = np.ones_like(x), np.zeros_like(x)
    rows = [
        [one, zero, zero, zero, y, zero, x, zero, 2 * x * y, -(x**2), 2 * y**2 - x**2],
        [zero, one, zero, x, zero, y, zero, 2 * x * y, zero, 2 * x**2 - y**2, -(y**2)],
        [zero, zero, one, zero, zero, -x, -y, -(x**2), -(y**2), 2 * x * y, 2 * x * y],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=1)


def _drilling_map(xy: np.ndarray) -> np.ndarray:
    """``T_d = G^-1 Q (n_el, 8, 4)``: bubble parameters ``d`` per unit nodal drilling rotation.

    Edge ``i -> j`` with ``(dx, dy) = x_j - x_i``: the Hermite normal displacement along the left
    normal ``(-dy, dx) / l`` integrates to ``l / 6 (theta_i - theta_j)`` over the parent edge.
    """
    n_el = len(xy)
    q = np.zeros((n_el, 8, 4))
    for e in range(4):
        i, j = e, (e + 1) % 4
        dx, dy = (xy[:, j] - xy[:, i]).T
        q[:, 2 * e, i], q[:, 2 * e, j] = -dy / 6, dy / 6
        q[:, 2 * e + 1, i], q[:, 2 * e + 1, j] = dx / 6, -dx / 6
    return _G_INV @ q


def _compliance(nu: np.ndarray) -> np.ndarray:
    """``C (n_el, 3, 3)``: plane-stress compliance times E (engineering shear strain)."""
    c = np.zeros((len(nu), 3, 3))
    c[:, 0, 0] = c[:, 1, 1] = 1.0
    c[:, 0, 1] = c[:, 1, 0] = -nu
    c[:, 2, 2] = 2.0 + 2.0 * nu
    return c


def _operators(xy: np.ndarray, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """Hybrid-stress operators of a set: ``H (n_el, 11, 11)``, ``N (n_el, 11, 12)``, ``M (n_el, 11, 1)``.

    Also returns, per integration point, ``(shape functions (4,), P (n_el, 3, 11), weight * det J)``
    for load vectors. Membrane DOF order ``(u, v, theta) x 4``; areas in the element's units.
    """
    n_el = len(xy)
    d1, d2 = xy[:, 2] - xy[:, 0], xy[:, 3] - xy[:, 1]
    area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    scale = np.sqrt(area)[:, None]  # polynomial coordinates of order 1: a well-conditioned H
    td = _drilling_map(xy)
    comp = _compliance(nu)
    j0 = np.stack([0.25 * _XI @ xy, 0.25 * _ETA @ xy], axis=1)  # [[x,xi y,xi], [x,eta y,eta]]
    j11, j12, j21, j22 = j0[:, 0, 0], j0[:, 0, 1], j0[:, 1, 0], j0[:, 1, 1]
    f0 = np.stack(
        [
            np.stack([j11**2, j21**2, 2 * j11 * j21], axis=-1),
            np.stack([j12**2, j22**2, 2 * j12 * j22], axis=-1),
            np.stack([j11 * j12, j21 * j22, j11 * j22 + j12 * j21], axis=-1),
        ],
        axis=1,
    )
    n_q = len(_IRONS)
    ps = np.zeros((n_el, n_q, 3, 11))  # stress modes, then weighted by w det J
    bs = np.zeros((n_el, n_q, 3, 13))  # strain of the 12 DOFs and of the enhanced mode
    points = []
    for q, (xi, eta, w) in enumerate(_IRONS):
        n = 0.25 * (1 + _XI * xi) * (1 + _ETA * eta)
        dnat = np.stack([0.25 * _XI * (1 + _ETA * eta), 0.25 * _ETA * (1 + _XI * xi)])  # (2, 4)
        jac = np.einsum("ak,ekj->eaj", dnat, xy)
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        inv = np.linalg.inv(jac)
        dn = inv @ dnat  # (n_el, 2, 4): d/dx, d/dy
        bub = np.array([[-2 * xi, -2 * xi * eta, 0.0, 1 - eta**2], [0.0, 1 - xi**2, -2 * eta, -2 * xi * eta]])
        db = inv @ bub  # (n_el, 2, 4)
        b = bs[:, q]
        b[:, 0, 0:12:3], b[:, 1, 1:12:3] = dn[:, 0], dn[:, 1]
        b[:, 2, 0:12:3], b[:, 2, 1:12:3] = dn[:, 1], dn[:, 0]
        bd = np.zeros((n_el, 3, 8))  # strains of the bubbles, d ordered (dx1, dy1, dx2, ...)
        bd[:, 0, 0::2], bd[:, 1, 1::2] = db[:, 0], db[:, 1]
        bd[:, 2, 0::2], bd[:, 2, 1::2] = db[:, 1], db[:, 0]
        b[:, :, 2:12:3] = bd @ td
        b[:, :, 12] = f0 @ np.array([3 * xi**2 - 1, 3 * eta**2 - 1, 0.0])
        pos = n @ xy / scale
        p = _stress_modes(pos[:, 0], pos[:, 1])
        wd = w * det
        ps[:, q] = p * wd[:, None, None]
        points.append((n, p, wd))
    # sum over points and stress components in one product: (n_el, 11, 3 q) @ (n_el, 3 q, .)
    left = np.swapaxes(ps, 2, 3).swapaxes(1, 2).reshape(n_el, 11, 3 * n_q)
    modes = np.stack([p for _, p, _ in points], axis=1)  # unweighted (n_el, q, 3, 11)
    h = left @ (comp[:, None] @ modes).reshape(n_el, 3 * n_q, 11)
    nm = left @ bs.reshape(n_el, 3 * n_q, 13)
    nmat, m = nm[:, :, :12], nm[:, :, 12:]
    return h, nmat, m, points


def _drilling_penalty_vector(n: np.ndarray, dndx: np.ndarray, dA: np.ndarray) -> np.ndarray:
    """``b (n_el, 12)`` with ``b q = theta_bar - omega_bar`` (area averages, 2x2 Gauss, exact).

    ``n (q, 4)``, ``dndx (n_el, q, 2, 4)``, ``dA (n_el, q)`` are the bilinear shape functions, their
    Cartesian derivatives and the weighted Jacobians of the shell's Gauss points.
    """
    area = dA.sum(axis=1)
    b = np.zeros((len(dA), 12))
    b[:, 2::3] = np.einsum("eq,qa->ea", dA, n)
    b[:, 0::3] = 0.5 * np.einsum("eq,eqa->ea", dA, dndx[:, :, 1, :])  # omega = (v,x - u,y) / 2
    b[:, 1::3] = -0.5 * np.einsum("eq,eqa->ea", dA, dndx[:, :, 0, :])
    return b / area[:, None]


def membrane_stiffness(
    xy: np.ndarray,
    thickness: np.ndarray,
    E: np.ndarray,
    nu: np.ndarray,
    gamma: np.ndarray,
    gauss: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> np.ndarray:
    """Membrane + drilling stiffness ``(n_el, 12, 12)``, DOFs ``(u, v, theta_z) x 4`` in element axes.

    Args:
        xy: (n_el, 4, 2) m, nodal coordinates in the element plane, counter-clockwise.
        thickness, E, nu: (n_el,) m, Pa, -.
        gamma: (n_el,) Pa, drilling penalty modulus (a small fraction of the shear modulus).
        gauss: ``(n (4, 4), dndx (n_el, 4, 2, 4), dA (n_el, 4))`` of the 2x2 Gauss rule.

    Returns:
        ke: (n_el, 12, 12) float, N/m, N and N m.

    """
    h, nmat, m, _ = _operators(xy, nu)
    x = np.linalg.solve(h, np.concatenate([nmat, m], axis=2))  # H^-1 [N M]
    hn, hm = x[:, :, :12], x[:, :, 12:]
    u = np.swapaxes(nmat, 1, 2) @ hn  # N^T H^-1 N
    w = np.swapaxes(nmat, 1, 2) @ hm  # N^T H^-1 M
    v = np.swapaxes(m, 1, 2) @ hm  # M^T H^-1 M  (n_el, 1, 1)
    k = (E * thickness)[:, None, None] * (u - w @ np.swapaxes(w, 1, 2) / v)
    b = _drilling_penalty_vector(*gauss)
    area = gauss[2].sum(axis=1)
    return k + (gamma * thickness * area)[:, None, None] * b[:, :, None] * b[:, None, :]


def membrane_thermal_vector(
    xy: np.ndarray, thickness: np.ndarray, E: np.ndarray, nu: np.ndarray, alpha: np.ndarray, dT: np.ndarray
) -> np.ndarray:
    """Nodal loads ``(n_el, 12)`` in element axes of the free strain ``alpha dT (1, 1, 0)``.

    ``dT`` is ``(n_el, 4)`` nodal values (K), interpolated bilinearly. With ``g = E t alpha
    integral P^T (1, 1, 0) dT dA`` the consistent load is ``N^T H^-1 g - N^T H^-1 M (M^T H^-1 M)^-1
    M^T H^-1 g`` (the stationary point of the same functional as the stiffness).
    """
    h, nmat, m, points = _operators(xy, nu)
    g = np.zeros((len(xy), 11))
    for n, p, wd in points:
        g += (p[:, 0, :] + p[:, 1, :]) * (wd * (dT @ n))[:, None]
    g *= (E * thickness * alpha)[:, None]
    x = np.linalg.solve(h, np.concatenate([nmat, m, g[:, :, None]], axis=2))
    hm, hg = x[:, :, 12:13], x[:, :, 13]
    nt = np.swapaxes(nmat, 1, 2)
    w = nt @ hm  # (n_el, 12, 1)
    v = np.einsum("eij,ei->e", m, hm[:, :, 0])
    mg = np.einsum("eij,ei->e", m, hg)
    return np.einsum("eij,ej->ei", nt, hg) - w[:, :, 0] * (mg / v)[:, None]
