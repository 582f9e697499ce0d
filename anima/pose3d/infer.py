"""Using a trained lifter in capture (``anima capture --body-3d lifter``)."""

from __future__ import annotations

import numpy as np

from anima.core.skeleton import BODY_JOINTS, LEFT_HAND, RIGHT_HAND
from anima.pose3d.joints import H36M_NAMES, mediapipe_to_h36m

# the 13 body joints of anima's skeleton <- H36M-17 (the H36M head is the head top, anima's the ear midpoint)
SKELETON_FROM_H36M = {
    "pelvis": "pelvis",
    "left_hip": "l_hip",
    "right_hip": "r_hip",
    "spine": "spine",
    "neck": "thorax",
    "head": "head",
    "nose": "neck_nose",
    "left_shoulder": "l_shoulder",
    "left_elbow": "l_elbow",
    "left_wrist": "l_wrist",
    "right_shoulder": "r_shoulder",
    "right_elbow": "r_elbow",
    "right_wrist": "r_wrist",
}
_IDX = np.array([H36M_NAMES.index(SKELETON_FROM_H36M[n]) for n in BODY_JOINTS])


def lift_frames(model, pose_px: np.ndarray, visibility: np.ndarray) -> np.ndarray:
    """MediaPipe Pose pixels ``(F, 33, 2)`` + visibility ``(F, 33)`` -> H36M-17 ``(F, 17, 3)`` in metres,
    anima axes (x right, y up, z towards the camera), pelvis at the origin. NaN rows stay NaN."""
    from anima.pose3d.train import predict

    F = len(pose_px)
    out = np.full((F, 17, 3), np.nan)
    ok = np.isfinite(pose_px).all((1, 2))
    if ok.any():
        uv, conf = mediapipe_to_h36m(pose_px[ok].astype(np.float64), visibility[ok].astype(np.float64))
        out[ok] = predict(model, uv, conf) / 1000.0 * np.array([1.0, -1.0, -1.0])
    return out


def replace_body(joints: np.ndarray, lifted: np.ndarray) -> np.ndarray:
    """Put the lifter's body into the 55-joint skeleton ``(F, 55, 3)``; each hand moves with its wrist."""
    J = joints.copy()
    ok = np.isfinite(lifted).all((1, 2))
    for hand, wrist in ((LEFT_HAND, BODY_JOINTS.index("left_wrist")), (RIGHT_HAND, BODY_JOINTS.index("right_wrist"))):
        shift = lifted[ok][:, _IDX[wrist]] - J[ok][:, wrist]
        J[np.flatnonzero(ok)[:, None], np.arange(55)[hand][None]] += shift[:, None]
    J[ok, :13] = lifted[ok][:, _IDX]
    return J
