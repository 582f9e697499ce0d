"""BVH's rotation channels (pure functions, used by the BVH I/O): rotations about one axis and the Z-X-Y Euler
angles BVH files store. The skeleton's kinematics are in :mod:`anima.core.kinematics`.
"""

from __future__ import annotations

import numpy as np

_AX = {"X": 0, "Y": 1, "Z": 2}


def axis_matrix(axis: str, deg: np.ndarray) -> np.ndarray:
    a = np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(np.shape(a) + (3, 3))
    i = _AX[axis]
    j, k = [(1, 2), (2, 0), (0, 1)][i]
    R[..., i, i] = 1
    R[..., j, j] = c
    R[..., k, k] = c
    R[..., j, k] = -s
    R[..., k, j] = s
    return R


def matrix_to_euler_zxy(R: np.ndarray) -> np.ndarray:
    """R = Rz(a) Rx(b) Ry(c) -> degrees (a, b, c) ``[..., 3]`` (BVH channels Zrotation Xrotation Yrotation)."""
    b = np.arcsin(np.clip(R[..., 2, 1], -1, 1))
    a = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    c = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
    return np.rad2deg(np.stack([a, b, c], -1))
