"""MediaPipe face mesh (legacy ``solutions`` API, models inside the wheel): 478 refined landmarks.

Video mode (``static_image_mode=False``) detects once and then tracks from the previous frame's
landmarks, re-detecting when tracking is lost. With several faces in view it follows one face: the
one MediaPipe's detector ranks first when tracking (re)starts, kept until it is lost.
"""

from __future__ import annotations

import os

os.environ.setdefault("GLOG_minloglevel", "2")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

import numpy as np

from anima.core.contract import N_FACE_LANDMARKS

N_LANDMARKS = N_FACE_LANDMARKS


class FaceMeshTracker:
    def __init__(
        self,
        static_image_mode: bool = False,
        refine_landmarks: bool = True,
        min_detection_confidence: float = 0.5,
        min_tracking_confidence: float = 0.5,
    ):
        import mediapipe as mp

        self._mesh = mp.solutions.face_mesh.FaceMesh(
            static_image_mode=static_image_mode,
            max_num_faces=1,
            refine_landmarks=refine_landmarks,
            min_detection_confidence=min_detection_confidence,
            min_tracking_confidence=min_tracking_confidence,
        )

    def __call__(self, rgb: np.ndarray) -> np.ndarray | None:
        """``rgb (H, W, 3) uint8`` -> normalised landmarks ``(478, 3)`` float32 or None (no face)."""
        if rgb.ndim == 2:
            rgb = np.repeat(rgb[..., None], 3, -1)
        res = self._mesh.process(np.ascontiguousarray(rgb))
        if not res.multi_face_landmarks:
            return None
        lm = res.multi_face_landmarks[0].landmark
        return np.array([(p.x, p.y, p.z) for p in lm], np.float32)

    def close(self) -> None:
        self._mesh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
