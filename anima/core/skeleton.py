"""The upper-body + hands skeleton of seed 004 (§4.3): 13 body joints + 21 per hand = 55 joints (165 values).

Positions are pelvis-relative, in metres, in the camera-aligned convention of ``anima.core`` (+x image
right, +y up, +z towards the camera). Joint names and parents are defined here once.

Body (13): pelvis, left_hip, right_hip, spine, neck, head, nose, left/right shoulder, elbow, wrist.
Hands (2 x 21, MediaPipe hand order): wrist, thumb_cmc/mcp/ip/tip, index_mcp/pip/dip/tip,
middle_..., ring_..., pinky_.... A hand's wrist joint is attached to the body's wrist (same position).
"Left" is the subject's left.
"""

from __future__ import annotations

import numpy as np

BODY_JOINTS = [
    "pelvis",
    "left_hip",
    "right_hip",
    "spine",
    "neck",
    "head",
    "nose",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
]
BODY_PARENTS = [-1, 0, 0, 0, 3, 4, 5, 4, 7, 8, 4, 10, 11]

HAND_JOINTS = [
    "wrist",
    "thumb_cmc",
    "thumb_mcp",
    "thumb_ip",
    "thumb_tip",
    "index_mcp",
    "index_pip",
    "index_dip",
    "index_tip",
    "middle_mcp",
    "middle_pip",
    "middle_dip",
    "middle_tip",
    "ring_mcp",
    "ring_pip",
    "ring_dip",
    "ring_tip",
    "pinky_mcp",
    "pinky_pip",
    "pinky_dip",
    "pinky_tip",
]
HAND_PARENTS = [-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19]


def _build():
    names = list(BODY_JOINTS)
    parents = list(BODY_PARENTS)
    for side, wrist in (("left", BODY_JOINTS.index("left_wrist")), ("right", BODY_JOINTS.index("right_wrist"))):
        off = len(names)
        names += [f"{side}_hand_{n}" for n in HAND_JOINTS]
        parents += [wrist if p < 0 else off + p for p in HAND_PARENTS]
    return names, np.array(parents, np.int64)


JOINT_NAMES, PARENTS = _build()
N_JOINTS = len(JOINT_NAMES)
assert N_JOINTS == 55 and N_JOINTS * 3 == 165
LEFT_HAND = slice(13, 34)
RIGHT_HAND = slice(34, 55)
BODY = slice(0, 13)

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
