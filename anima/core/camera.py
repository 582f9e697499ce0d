"""Scaled-orthographic (weak-perspective) camera and batched similarity alignment.

Convention (see ``anima.core``): camera-space point ``X = s * R @ V + t`` with V in model units (cm),
X in pixels; the image point is ``(u, v) = (X[0], -X[1])``. So ``t[0]`` is the image column of the model
origin and ``-t[1]`` its row; ``t[2]`` only orders depth. MediaPipe landmarks map into the same space by
:func:`mediapipe_to_camera`.
"""

from __future__ import annotations

import numpy as np


def mediapipe_to_camera(lm: np.ndarray, width: int, height: int) -> np.ndarray:
    """MediaPipe normalised landmarks ``[..., 3]`` (x, y in [0,1], z ~ x-scale, larger = farther)
    -> camera space pixels ``(x*W, -y*H, -z*W)``."""
    out = np.empty(lm.shape, dtype=np.float64)
    out[..., 0] = lm[..., 0] * width
    out[..., 1] = -lm[..., 1] * height
    out[..., 2] = -lm[..., 2] * width
    return out


def camera_to_image(X: np.ndarray) -> np.ndarray:
    """Camera-space pixels ``[..., 3]`` -> image ``(u, v) [..., 2]``."""
    return np.stack([X[..., 0], -X[..., 1]], -1)


def transform(V: np.ndarray, scale: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``s R V + t`` batched over a leading frame axis. V ``[F, N, 3]`` or ``[N, 3]``; scale ``[F]``;
    R ``[F, 3, 3]``; t ``[F, 3]`` -> ``[F, N, 3]``."""
    return np.asarray(scale)[:, None, None] * np.einsum("fij,...nj->fni", R, V) + np.asarray(t)[:, None, :]


def project(V: np.ndarray, scale: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Model points -> image pixels ``[F, N, 2]`` under the weak-perspective camera."""
    return camera_to_image(transform(V, scale, R, t))


def umeyama(src: np.ndarray, dst: np.ndarray, w: np.ndarray | None = None):
    """Batched weighted similarity ``dst ~ s R src + t`` (Umeyama 1991).

    src, dst ``[F, N, 3]``; w ``[F, N]`` or None. Returns scale ``[F]``, R ``[F, 3, 3]`` (proper
    rotation), t ``[F, 3]``.
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if w is None:
        w = np.ones(dst.shape[:-1])
    w = w / np.maximum(w.sum(-1, keepdims=True), 1e-12)
    mu_s = (w[:, None, :] @ src)[:, 0]
    mu_d = (w[:, None, :] @ dst)[:, 0]
    s0 = src - mu_s[:, None]
    d0 = dst - mu_d[:, None]
    cov = (d0 * w[..., None]).transpose(0, 2, 1) @ s0
    U, S, Vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones_like(S)
    D[:, 2] = d
    R = U @ (D[:, :, None] * Vt)
    var_s = (w * (s0 * s0).sum(-1)).sum(-1)
    scale = (S * D).sum(-1) / np.maximum(var_s, 1e-12)
    t = mu_d - scale[:, None] * (R @ mu_s[:, :, None])[:, :, 0]
    return scale, R, t
