"""Hamilton quaternions ``[w, x, y, z]`` (body → navigation) and rotation helpers in numpy, shared
by the Python benchmarks that write a filter or a factor graph of their own."""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """The cross-product matrix ``[v]×`` (``skew(a) @ b == np.cross(a, b)``)."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product ``a ⊗ b``."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def quat_exp(theta: np.ndarray) -> np.ndarray:
    """The unit quaternion of the rotation vector ``theta`` (rad)."""
    angle = np.linalg.norm(theta)
    if angle < 1e-12:
        return np.array([1.0, *(0.5 * theta)])
    return np.array([np.cos(0.5 * angle), *(np.sin(0.5 * angle) / angle * theta)])


def quat_to_rot(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of the unit quaternion ``q``."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
