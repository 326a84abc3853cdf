"""2x2 symmetric algebra on plain floats, for the per-window hot path.

numpy spends 1-3 us of call overhead on every operation with a 2x2 array; one window's settlement
update is about thirty such operations. On floats the same update costs a few microseconds. A
symmetric 2x2 matrix ``[[a, b], [b, d]]`` is the tuple ``(a, b, d)``; a general one
``[[a, b], [c, d]]`` is ``(a, b, c, d)``; vectors are ``(x, y)``. Tests compare each function with
numpy.
"""

from __future__ import annotations

__all__ = ["congruence", "inv_sym", "mat_vec", "quad_inv", "sym_vec"]

Sym = tuple[float, float, float]
Mat = tuple[float, float, float, float]
Vec = tuple[float, float]


def inv_sym(m: Sym) -> Sym:
    """Inverse of a symmetric positive definite ``(a, b, d)``."""
    a, b, d = m
    det = a * d - b * b
    return (d / det, -b / det, a / det)


def quad_inv(m: Sym, v: Vec) -> float:
    """``v' M^-1 v`` for a symmetric positive definite ``M``."""
    a, b, d = m
    x, y = v
    return (d * x * x - 2.0 * b * x * y + a * y * y) / (a * d - b * b)


def sym_vec(m: Sym, v: Vec) -> Vec:
    """``M v`` for a symmetric ``M``."""
    a, b, d = m
    return (a * v[0] + b * v[1], b * v[0] + d * v[1])


def mat_vec(m: Mat, v: Vec) -> Vec:
    """``M v`` for a general ``M``."""
    return (m[0] * v[0] + m[1] * v[1], m[2] * v[0] + m[3] * v[1])


def congruence(t: Mat, m: Sym) -> Sym:
    """``T M T'`` (symmetric) for a general ``T`` and a symmetric ``M``."""
    t0, t1, t2, t3 = t
    a, b, d = m
    # rows of T M
    r00, r01 = t0 * a + t1 * b, t0 * b + t1 * d
    r10, r11 = t2 * a + t3 * b, t2 * b + t3 * d
    return (r00 * t0 + r01 * t1, r00 * t2 + r01 * t3, r10 * t2 + r11 * t3)
