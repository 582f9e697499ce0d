"""Joint sets and the mappings between them, defined once.

H36M-17 (VideoPose3D / Martinez order) is the lifter's output skeleton. MediaPipe Pose's 33 landmarks and
HumanEva's 15 joints are mapped onto it by fixed linear combinations (one matrix each), so the same mapping
applies to 2D pixels, 3D world landmarks and confidences.
"""

from __future__ import annotations

import numpy as np

H36M_NAMES = [
    "pelvis",
    "r_hip",
    "r_knee",
    "r_ankle",
    "l_hip",
    "l_knee",
    "l_ankle",
    "spine",
    "thorax",
    "neck_nose",
    "head",
    "l_shoulder",
    "l_elbow",
    "l_wrist",
    "r_shoulder",
    "r_elbow",
    "r_wrist",
]
H36M_PARENTS = np.array([-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15])
K = len(H36M_NAMES)
BONES = np.array([(j, p) for j, p in enumerate(H36M_PARENTS) if p >= 0])  # (16, 2) child, parent
FLIP = np.array([0, 4, 5, 6, 1, 2, 3, 7, 8, 9, 10, 14, 15, 16, 11, 12, 13])  # left <-> right

# MediaPipe Pose landmark indices used by the mapping
_MP = dict(
    nose=0,
    l_eye=2,
    r_eye=5,
    l_ear=7,
    r_ear=8,
    mouth_l=9,
    mouth_r=10,
    l_shoulder=11,
    r_shoulder=12,
    l_elbow=13,
    r_elbow=14,
    l_wrist=15,
    r_wrist=16,
    l_hip=23,
    r_hip=24,
    l_knee=25,
    r_knee=26,
    l_ankle=27,
    r_ankle=28,
)

# Where the H36M spine and head-top sit relative to MediaPipe's points. SPINE_T: fraction of the way from
# the pelvis to the thorax (measured on the H36M training subjects' mocap, see `spine_fraction`).
# HEAD_K: the head top is extrapolated from the mid-ear point away from the mouth by HEAD_K times the
# ear-to-mouth distance (MediaPipe has no head-top landmark).
SPINE_T = 0.45
HEAD_K = 1.0


def mediapipe_matrix(spine_t: float = SPINE_T, head_k: float = HEAD_K) -> np.ndarray:
    """``(17, 33)`` matrix M with ``h36m = M @ mediapipe`` (rows sum to 1: affine combinations)."""
    M = np.zeros((K, 33))
    hip = {_MP["l_hip"]: 0.5, _MP["r_hip"]: 0.5}
    sho = {_MP["l_shoulder"]: 0.5, _MP["r_shoulder"]: 0.5}
    rows = {"pelvis": hip, "thorax": sho, "neck_nose": {_MP["nose"]: 1.0}}
    rows["spine"] = {**{k: (1 - spine_t) * v for k, v in hip.items()}}
    for k, v in sho.items():
        rows["spine"][k] = rows["spine"].get(k, 0) + spine_t * v
    ears = {_MP["l_ear"]: 0.5, _MP["r_ear"]: 0.5}
    mouth = {_MP["mouth_l"]: 0.5, _MP["mouth_r"]: 0.5}
    rows["head"] = {**{k: (1 + head_k) * v for k, v in ears.items()}, **{k: -head_k * v for k, v in mouth.items()}}
    for n in (
        "r_hip",
        "r_knee",
        "r_ankle",
        "l_hip",
        "l_knee",
        "l_ankle",
        "l_shoulder",
        "l_elbow",
        "l_wrist",
        "r_shoulder",
        "r_elbow",
        "r_wrist",
    ):
        rows[n] = {_MP[n]: 1.0}
    for i, n in enumerate(H36M_NAMES):
        for j, w in rows[n].items():
            M[i, j] = w
    return M


def mediapipe_to_h36m(points: np.ndarray, visibility: np.ndarray | None = None, M: np.ndarray | None = None):
    """MediaPipe ``(..., 33, D)`` points (and ``(..., 33)`` visibility) -> H36M ``(..., 17, D)`` and
    ``(..., 17)`` confidence (a combined joint takes the lowest visibility of the points it uses)."""
    M = mediapipe_matrix() if M is None else M
    out = np.einsum("kj,...jd->...kd", M, points)
    if visibility is None:
        return out
    used = M != 0
    conf = np.where(used, visibility[..., None, :], np.inf).min(-1)
    return out, conf


# HumanEva-15 (VideoPose3D layout): pelvis, thorax, l_shoulder, l_elbow, l_wrist, r_shoulder, r_elbow,
# r_wrist, l_hip, l_knee, l_ankle, r_hip, r_knee, r_ankle, head. Side A = left (MANIFEST).
HUMANEVA_TO_H36M = {
    "pelvis": 0,
    "thorax": 1,
    "l_shoulder": 2,
    "l_elbow": 3,
    "l_wrist": 4,
    "r_shoulder": 5,
    "r_elbow": 6,
    "r_wrist": 7,
    "l_hip": 8,
    "l_knee": 9,
    "l_ankle": 10,
    "r_hip": 11,
    "r_knee": 12,
    "r_ankle": 13,
    "head": 14,
}
HUMANEVA_EVAL = [H36M_NAMES.index(n) for n in HUMANEVA_TO_H36M]  # the 15 joints both skeletons share


def humaneva_to_h36m(points: np.ndarray):
    """HumanEva ``(..., 15, D)`` -> H36M ``(..., 17, D)`` and confidence ``(..., 17)``: the spine is the
    pelvis-thorax midpoint; the nose has no HumanEva counterpart and is masked (confidence 0, NaN-free)."""
    sh = points.shape[:-2]
    out = np.zeros(sh + (K, points.shape[-1]), points.dtype)
    conf = np.ones(sh + (K,), np.float32)
    for n, j in HUMANEVA_TO_H36M.items():
        out[..., H36M_NAMES.index(n), :] = points[..., j, :]
    sp = H36M_NAMES.index("spine")
    out[..., sp, :] = SPINE_T * points[..., 1, :] + (1 - SPINE_T) * points[..., 0, :]
    nn = H36M_NAMES.index("neck_nose")
    out[..., nn, :] = points[..., 14, :]
    conf[..., nn] = 0.0
    return out, conf


def spine_fraction(joints: np.ndarray) -> float:
    """Mean fraction of the pelvis->thorax segment at which the H36M spine joint projects."""
    a = joints[..., 8, :] - joints[..., 0, :]
    b = joints[..., 7, :] - joints[..., 0, :]
    return float(np.mean((a * b).sum(-1) / (a * a).sum(-1)))
