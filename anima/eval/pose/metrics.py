"""3D pose metrics (seed 004 §3.4.1): MPJPE, 3D PCK@150 mm and AUC under three protocols.

* ``unscaled``: root-relative prediction as predicted (pelvis at the origin for both);
* ``scaled`` (glob. scaled): prediction multiplied by the least-squares scale to the ground truth;
* ``procrustes``: full similarity alignment (rotation, scale, translation) per pose (Umeyama).
AUC: mean PCK over thresholds 0, 5, ..., 150 mm.
"""

from __future__ import annotations

import numpy as np

PROTOCOLS = ("unscaled", "scaled", "procrustes")


def root_relative(J: np.ndarray, root: int = 0) -> np.ndarray:
    return J - J[..., root : root + 1, :]


def align_scale(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per pose, the scale s minimising |s * pred - gt| (both root-relative)."""
    s = (pred * gt).sum((-1, -2), keepdims=True) / np.maximum((pred * pred).sum((-1, -2), keepdims=True), 1e-12)
    return s * pred


def align_procrustes(pred: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Per pose, the similarity transform of ``pred`` closest to ``gt`` (no reflection)."""
    mp, mg = pred.mean(-2, keepdims=True), gt.mean(-2, keepdims=True)
    P, G = pred - mp, gt - mg
    H = np.swapaxes(P, -1, -2) @ G
    U, S, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.ones_like(S)
    D[..., -1] = d
    R = (U * D[..., None, :]) @ Vt
    s = (S * D).sum(-1) / np.maximum((P**2).sum((-1, -2)), 1e-12)
    return s[..., None, None] * P @ R + mg


def aligned(pred: np.ndarray, gt: np.ndarray, protocol: str) -> tuple[np.ndarray, np.ndarray]:
    pred, gt = root_relative(pred), root_relative(gt)
    if protocol == "unscaled":
        return pred, gt
    if protocol == "scaled":
        return align_scale(pred, gt), gt
    if protocol == "procrustes":
        return align_procrustes(pred, gt), gt
    raise ValueError(f"unknown protocol {protocol!r}; one of {PROTOCOLS}")


def pose_metrics(pred: np.ndarray, gt: np.ndarray, joints=None) -> dict[str, dict[str, float]]:
    """``pred``, ``gt``: ``(N, J, 3)`` mm. Returns, per protocol, MPJPE (mm), PCK@150 (%) and AUC (%) over
    ``joints`` (default all)."""
    out = {}
    for prot in PROTOCOLS:
        p, g = aligned(np.asarray(pred, np.float64), np.asarray(gt, np.float64), prot)
        e = np.linalg.norm(p - g, axis=-1)
        if joints is not None:
            e = e[:, joints]
        thr = np.arange(0, 151, 5)
        out[prot] = {
            "mpjpe": float(e.mean()),
            "pck150": float(100 * (e <= 150).mean()),
            "auc": float(100 * np.mean([(e <= t).mean() for t in thr])),
        }
    return out
