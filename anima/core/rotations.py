"""Rotation conversions on batched arrays ``[..., 3]`` / ``[..., 3, 3]`` / ``[..., 4]``.

Convention: rotation vectors are axis * angle (radians); quaternions are (x, y, z, w) as in glTF;
matrices act on column vectors (``R @ v``). Euler angles (yaw, pitch, roll) compose as
``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)`` (ARKit head-rotation order).
"""

from __future__ import annotations

import numpy as np


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(v.shape[:-1], dtype=v.dtype)
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


def rotvec_to_matrix(rv: np.ndarray) -> np.ndarray:
    """Rodrigues' formula. ``rv [..., 3]`` -> ``R [..., 3, 3]``."""
    rv = np.asarray(rv, dtype=np.float64)
    theta = np.linalg.norm(rv, axis=-1, keepdims=True)
    small = theta < 1e-8
    axis = np.where(small, 0.0, rv / np.where(small, 1.0, theta))
    K = _skew(axis)
    th = theta[..., None]
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rotvec_to_matrix` (via quaternions, stable near 0 and pi)."""
    q = matrix_to_quat(R)
    q = np.where(q[..., 3:4] < 0, -q, q)
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2 * np.arctan2(s, q[..., 3:4])
    scale = np.where(s < 1e-12, 2.0, angle / np.where(s < 1e-12, 1.0, s))
    return q[..., :3] * scale


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """``R [..., 3, 3]`` -> unit quaternion ``(x, y, z, w)`` (Shepperd's method, batched)."""
    R = np.asarray(R, dtype=np.float64)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = m00 + m11 + m22
    cand = np.stack([tr, m00, m11, m22], -1)
    which = np.argmax(cand, -1)
    q = np.zeros(R.shape[:-2] + (4,))
    # case w largest
    s = np.sqrt(np.maximum(1 + tr, 1e-12)) * 2
    qw = np.stack(
        [
            (R[..., 2, 1] - R[..., 1, 2]) / s,
            (R[..., 0, 2] - R[..., 2, 0]) / s,
            (R[..., 1, 0] - R[..., 0, 1]) / s,
            0.25 * s,
        ],
        -1,
    )
    s = np.sqrt(np.maximum(1 + m00 - m11 - m22, 1e-12)) * 2
    qx = np.stack(
        [
            0.25 * s,
            (R[..., 0, 1] + R[..., 1, 0]) / s,
            (R[..., 0, 2] + R[..., 2, 0]) / s,
            (R[..., 2, 1] - R[..., 1, 2]) / s,
        ],
        -1,
    )
    s = np.sqrt(np.maximum(1 - m00 + m11 - m22, 1e-12)) * 2
    qy = np.stack(
        [
            (R[..., 0, 1] + R[..., 1, 0]) / s,
            0.25 * s,
            (R[..., 1, 2] + R[..., 2, 1]) / s,
            (R[..., 0, 2] - R[..., 2, 0]) / s,
        ],
        -1,
    )
    s = np.sqrt(np.maximum(1 - m00 - m11 + m22, 1e-12)) * 2
    qz = np.stack(
        [
            (R[..., 0, 2] + R[..., 2, 0]) / s,
            (R[..., 1, 2] + R[..., 2, 1]) / s,
            0.25 * s,
            (R[..., 1, 0] - R[..., 0, 1]) / s,
        ],
        -1,
    )
    for i, cand_q in enumerate((qw, qx, qy, qz)):
        q = np.where((which == i)[..., None], cand_q, q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def euler_to_matrix(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)`` for arrays of angles in radians."""
    yaw, pitch, roll = (np.asarray(a, dtype=np.float64) for a in (yaw, pitch, roll))
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    o, z = np.ones_like(cy), np.zeros_like(cy)
    Ry = np.stack([np.stack([cy, z, sy], -1), np.stack([z, o, z], -1), np.stack([-sy, z, cy], -1)], -2)
    Rx = np.stack([np.stack([o, z, z], -1), np.stack([z, cp, -sp], -1), np.stack([z, sp, cp], -1)], -2)
    Rz = np.stack([np.stack([cr, -sr, z], -1), np.stack([sr, cr, z], -1), np.stack([z, z, o], -1)], -2)
    return Ry @ Rx @ Rz


def matrix_to_euler(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`euler_to_matrix`: returns ``[..., 3]`` = (yaw, pitch, roll) in radians."""
    R = np.asarray(R, dtype=np.float64)
    pitch = np.arcsin(np.clip(-R[..., 1, 2], -1.0, 1.0))
    yaw = np.arctan2(R[..., 0, 2], R[..., 2, 2])
    roll = np.arctan2(R[..., 1, 0], R[..., 1, 1])
    return np.stack([yaw, pitch, roll], -1)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(x, y, z, w) [..., 4]`` (normalised here) -> rotation matrices ``[..., 3, 3]``."""
    q = np.asarray(q, np.float64)
    q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )
