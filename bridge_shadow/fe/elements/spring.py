"""Linear springs in global axes: node to node, or node to ground."""

from __future__ import annotations

import numpy as np

__all__ = ["spring_stiffness"]


def spring_stiffness(k: np.ndarray) -> np.ndarray:
    """Node-to-node spring matrices ``(n, 12, 12)`` from per-DOF stiffness ``k (n, 6)``."""
    d = np.zeros((len(k), 6, 6))
    d[:, np.arange(6), np.arange(6)] = k
    return np.concatenate([np.concatenate([d, -d], axis=2), np.concatenate([-d, d], axis=2)], axis=1)
