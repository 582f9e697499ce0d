"""Joint positions <-> joint rotations for a fixed-length skeleton (pure functions, used by the BVH I/O).

Convention: global rotation ``G_j`` maps a bone's rest-pose vector to the current one; local rotation
``L_j = G_parent^-1 G_j``; forward kinematics ``p_child = p_j + G_j @ offset_child``.
"""

from __future__ import annotations

import numpy as np


def _kabsch(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Rotations R ``[F, 3, 3]`` minimising sum |R a_i - b_i|^2 for A, B ``[F, n, 3]``."""
    H = A.transpose(0, 2, 1) @ B
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.transpose(0, 2, 1) @ U.transpose(0, 2, 1)))
    D = np.ones((len(A), 3))
    D[:, 2] = d
    return Vt.transpose(0, 2, 1) @ (D[:, :, None] * U.transpose(0, 2, 1))


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vectors a to b, batched ``[F, 3]`` -> ``[F, 3, 3]``."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    v = np.cross(a, b)
    c = (a * b).sum(-1)
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    f = 1.0 / np.maximum(1.0 + c, 1e-9)
    R = np.eye(3) + K + (K @ K) * f[..., None, None]
    # opposite vectors: rotate pi about any axis orthogonal to a
    opp = c < -1 + 1e-9
    if opp.any():
        axis = np.cross(a[opp], np.array([1.0, 0.0, 0.0]))
        small = np.linalg.norm(axis, axis=-1) < 1e-6
        axis[small] = np.cross(a[opp][small], np.array([0.0, 1.0, 0.0]))
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        R[opp] = 2 * axis[:, :, None] * axis[:, None, :] - np.eye(3)
    return R


def positions_to_rotations(P: np.ndarray, parents: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Global rotations ``[F, J, 3, 3]`` that pose the rest skeleton (``offsets [J, 3]``, child minus parent
    in the rest pose) like positions ``P [F, J, 3]``. Joints with several children: best rigid fit of their
    child bones (Kabsch); one child: the parent's rotation followed by the smallest rotation aligning the
    bone (stable twist); no child: the parent's rotation."""
    F, J, _ = P.shape
    G = np.tile(np.eye(3), (F, J, 1, 1))
    kids = [np.flatnonzero(parents == j) for j in range(J)]
    for j in range(J):  # parents precede children
        base = G[:, parents[j]] if parents[j] >= 0 else np.tile(np.eye(3), (F, 1, 1))
        c = kids[j]
        c = c[np.linalg.norm(offsets[c], axis=-1) > 1e-9] if len(c) else c
        if len(c) == 0:
            G[:, j] = base
        elif len(c) == 1:
            rest = base @ offsets[c[0]]
            G[:, j] = _min_rotation(rest, P[:, c[0]] - P[:, j]) @ base
        else:
            A = np.broadcast_to(offsets[c], (F, len(c), 3))
            G[:, j] = _kabsch(A, P[:, c] - P[:, j][:, None])
    return G


def forward_kinematics(
    G_local: np.ndarray, parents: np.ndarray, offsets: np.ndarray, root_pos: np.ndarray | None = None
) -> np.ndarray:
    """Positions ``[F, J, 3]`` from local rotations ``[F, J, 3, 3]``."""
    F, J = G_local.shape[:2]
    G = np.zeros_like(G_local)
    P = np.zeros((F, J, 3))
    for j in range(J):
        p = parents[j]
        if p < 0:
            G[:, j] = G_local[:, j]
            P[:, j] = offsets[j] + (0 if root_pos is None else root_pos)
        else:
            G[:, j] = G[:, p] @ G_local[:, j]
            P[:, j] = P[:, p] + G[:, p] @ offsets[j]
    return P


def local_rotations(G: np.ndarray, parents: np.ndarray) -> np.ndarray:
    L = G.copy()
    for j in range(G.shape[1]):
        if parents[j] >= 0:
            L[:, j] = G[:, parents[j]].transpose(0, 2, 1) @ G[:, j]
    return L


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
