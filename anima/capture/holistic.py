"""MediaPipe Holistic (legacy ``solutions`` API, models in the wheel): face (478 refined), pose (33, image and
world coordinates with visibility), and both hands (21 each) in one pass, in video mode."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anima.core.contract import N_FACE_LANDMARKS


@dataclass
class HolisticFrame:
    face: np.ndarray | None  # (478, 3) normalised
    pose: np.ndarray | None  # (33, 4) normalised x, y, z + visibility
    pose_world: np.ndarray | None  # (33, 4) metres (MediaPipe axes: y down) + visibility
    left_hand: np.ndarray | None  # (21, 3) normalised (subject's left hand)
    right_hand: np.ndarray | None
    camera_step: np.ndarray | None = None  # (3,) the background's shift (pixels) and log scale since the last frame


def _arr(lms, vis: bool = False):
    if lms is None:
        return None
    if vis:
        return np.array([(p.x, p.y, p.z, p.visibility) for p in lms.landmark], np.float32)
    return np.array([(p.x, p.y, p.z) for p in lms.landmark], np.float32)


class HolisticTracker:
    def __init__(
        self,
        static_image_mode: bool = False,
        model_complexity: int = 1,
        min_detection_confidence: float = 0.5,
        min_tracking_confidence: float = 0.5,
    ):
        import mediapipe as mp

        self._h = mp.solutions.holistic.Holistic(
            static_image_mode=static_image_mode,
            model_complexity=model_complexity,
            refine_face_landmarks=True,
            min_detection_confidence=min_detection_confidence,
            min_tracking_confidence=min_tracking_confidence,
        )

    def __call__(self, rgb: np.ndarray) -> HolisticFrame:
        if rgb.ndim == 2:
            rgb = np.repeat(rgb[..., None], 3, -1)
        r = self._h.process(np.ascontiguousarray(rgb))
        face = _arr(r.face_landmarks)
        if face is not None and face.shape[0] != N_FACE_LANDMARKS:
            face = None
        return HolisticFrame(
            face,
            _arr(r.pose_landmarks, True),
            _arr(r.pose_world_landmarks, True),
            _arr(r.left_hand_landmarks),
            _arr(r.right_hand_landmarks),
        )

    def close(self) -> None:
        self._h.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
