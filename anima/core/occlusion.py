"""A hand over the lower face (the nose tip to the chin, cheek to cheek), from a capture's own landmarks and
skeleton: the dataset builder removes such clips (seed 000 removes occluded faces by hand), and the character's
mouth does not follow a fit that has no evidence under the hand."""

from __future__ import annotations

import numpy as np

from anima.core.skeleton import LEFT_HAND, RIGHT_HAND

# MediaPipe face-mesh points bounding the lower face: nose tip, chin, right and left cheek
NOSE_TIP, CHIN, CHEEK_R, CHEEK_L = 1, 152, 234, 454
HANDS = np.r_[LEFT_HAND.start : LEFT_HAND.stop, RIGHT_HAND.start : RIGHT_HAND.stop]


def hand_over_face(seq, min_joints: int = 3) -> np.ndarray:
    """Per frame: at least ``min_joints`` hand joints (pixels, ``body_image``) inside the lower-face box of
    the face landmarks. All False when the capture has no skeleton or no landmarks."""
    out = np.zeros(seq.n_frames, bool)
    if seq.body_image is None or seq.landmarks is None:
        return out
    lm = seq.landmarks[:, [NOSE_TIP, CHIN, CHEEK_R, CHEEK_L], :2] * np.array([seq.width, seq.height], np.float32)
    x0 = np.minimum(lm[:, 2, 0], lm[:, 3, 0])
    x1 = np.maximum(lm[:, 2, 0], lm[:, 3, 0])
    y0, y1 = lm[:, 0, 1], lm[:, 1, 1]
    h = seq.body_image[:, HANDS]  # [F, 42, 2]
    with np.errstate(invalid="ignore"):
        inside = (
            (h[..., 0] >= x0[:, None])
            & (h[..., 0] <= x1[:, None])
            & (h[..., 1] >= y0[:, None])
            & (h[..., 1] <= y1[:, None])
        )
    return inside.sum(1) >= min_joints
