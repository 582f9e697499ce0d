"""Landmark and temporal-stability metrics."""

from __future__ import annotations

import numpy as np


def nme_bbox(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """3DDFA_V2 / AFLW2000-3D protocol: mean point-to-point 2D error normalised by ``sqrt(w * h)`` of the
    ground-truth landmarks' bounding box. pred, gt ``[..., N, 2]`` -> ``[...]``."""
    wh = gt.max(-2) - gt.min(-2)
    d = np.sqrt(wh[..., 0] * wh[..., 1])
    return np.linalg.norm(pred - gt, axis=-1).mean(-1) / d


def mean_acceleration(x: np.ndarray, norm: np.ndarray | None = None) -> float:
    """Mean magnitude of the second temporal difference of points ``[T, N, D]`` (jitter), optionally
    divided per frame by ``norm [T]`` (e.g. inter-ocular distance), over frames where all are finite."""
    a = x[2:] - 2 * x[1:-1] + x[:-2]
    m = np.linalg.norm(a, axis=-1).mean(-1)
    if norm is not None:
        m = m / norm[1:-1]
    return float(np.nanmean(m))


def pct(x) -> str:
    """A fraction as a percentage for tables (``-`` for None)."""
    return "-" if x is None else f"{100 * x:.2f} %"
