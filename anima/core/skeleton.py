"""The upper-body + hands skeleton of seed 004 (§4.3): 13 body joints + 21 per hand = 55 joints (165 values).

Positions are pelvis-relative, in metres, in the camera-aligned convention of ``anima.core`` (+x image
right, +y up, +z towards the camera). Joint names and parents are defined here once.

Body (13): pelvis, left_hip, right_hip, spine, neck, head, nose, left/right shoulder, elbow, wrist.
Hands (2 x 21, MediaPipe hand order): wrist, thumb_cmc/mcp/ip/tip, index_mcp/pip/dip/tip,
middle_..., ring_..., pinky_.... A hand's wrist joint is attached to the body's wrist (same position).
"Left" is the subject's left. The names and parents are the data contract's (``anima.core.contract``).
"""

from __future__ import annotations

import numpy as np

from anima.core.contract import (
    BODY_JOINTS,
    HAND_JOINTS,
    JOINT_NAMES,
    JOINT_PARENTS,
    LEG_JOINTS,
    N_BODY_JOINTS,
    N_HAND_JOINTS,
    N_JOINTS,
)  # fmt: skip

PARENTS = np.array(JOINT_PARENTS, np.int64)
__all__ = ["BODY_JOINTS", "HAND_JOINTS", "JOINT_NAMES", "LEG_JOINTS", "N_JOINTS", "PARENTS"]
BODY = slice(0, N_BODY_JOINTS)  # the layout of the 55 joints: body, then the left hand, then the right
LEFT_HAND = slice(N_BODY_JOINTS, N_BODY_JOINTS + N_HAND_JOINTS)
RIGHT_HAND = slice(N_BODY_JOINTS + N_HAND_JOINTS, N_JOINTS)

# MediaPipe Pose (33 landmarks) indices used to build the body joints
MP_POSE = {
    "nose": 0,
    "left_ear": 7,
    "right_ear": 8,
    "left_shoulder": 11,
    "right_shoulder": 12,
    "left_elbow": 13,
    "right_elbow": 14,
    "left_wrist": 15,
    "right_wrist": 16,
    "left_hip": 23,
    "right_hip": 24,
}
# ... and for the legs (anima.core.contract.LEG_JOINTS, in order)
MP_LEGS = (25, 27, 29, 31, 26, 28, 30, 32)


def bone_lengths(joints: np.ndarray) -> np.ndarray:
    """``[..., 55, 3]`` -> ``[..., 55]`` distance of each joint to its parent (0 for the root)."""
    par = np.where(PARENTS < 0, np.arange(N_JOINTS), PARENTS)
    return np.linalg.norm(joints - joints[..., par, :], axis=-1)


def fix_bone_lengths(J: np.ndarray, lengths: np.ndarray | None = None, parents: np.ndarray = PARENTS) -> np.ndarray:
    """Re-impose per-bone lengths (default: the clip's median) along each bone's current direction, from
    the root outwards (parents must precede children). ``J [F, J, 3]``; missing joints stay NaN."""
    par = np.where(parents < 0, np.arange(len(parents)), parents)
    if lengths is None:
        lengths = np.nanmedian(np.linalg.norm(J - J[:, par], axis=-1), axis=0)
    out = J.copy()
    for j in range(1, J.shape[1]):
        p = parents[j]
        d = J[:, j] - J[:, p]
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        unit = np.where(n > 1e-9, d / np.maximum(n, 1e-9), 0.0)
        unit[~np.isfinite(d).all(-1)] = np.nan
        moved = out[:, p] + lengths[j] * unit
        # a bone whose parent is missing cannot be re-measured: keep the joint where it was
        out[:, j] = np.where(np.isfinite(out[:, p]).all(-1, keepdims=True), moved, J[:, j])
    return out


def children(j: int) -> list[int]:
    return [int(c) for c in np.flatnonzero(PARENTS == j)]
