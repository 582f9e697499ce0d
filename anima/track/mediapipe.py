"""MediaPipe (the legacy ``solutions`` API, whose models ship inside the wheel): face mesh (478 refined
landmarks), Holistic (face, pose and hands in one pass), Pose, Hands and face detection. The library loads on
the first model opened (``pip install anima[capture]``), so importing this module stays light.

Face mesh in video mode detects once and then tracks from the previous frame's landmarks, re-detecting when
tracking is lost. With several faces in view it follows one face: the one MediaPipe's detector ranks first when
tracking (re)starts, kept until it is lost.
"""

from __future__ import annotations

import os

os.environ.setdefault("GLOG_minloglevel", "2")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

import numpy as np

from anima.core.contract import N_FACE_LANDMARKS
from anima.errors import require
from anima.track.base import FaceBox, Hand, HolisticFrame, PoseFrame

N_LANDMARKS = N_FACE_LANDMARKS
HOLISTIC_COMPLEXITY = 1


def _mp():
    return require("mediapipe", extra="capture", what="tracking")


def _rgb3(rgb: np.ndarray) -> np.ndarray:
    return np.repeat(rgb[..., None], 3, -1) if rgb.ndim == 2 else rgb


class _Closing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class FaceMeshTracker(_Closing):
    """Face mesh: ``rgb (H, W, 3) uint8`` -> normalised landmarks ``(478, 3)`` float32, or None (no face)."""

    def __init__(
        self,
        static_image_mode: bool = False,
        refine_landmarks: bool = True,
        min_detection_confidence: float = 0.5,
        min_tracking_confidence: float = 0.5,
    ):
        self._mesh = _mp().solutions.face_mesh.FaceMesh(
            static_image_mode=static_image_mode,
            max_num_faces=1,
            refine_landmarks=refine_landmarks,
            min_detection_confidence=min_detection_confidence,
            min_tracking_confidence=min_tracking_confidence,
        )

    def __call__(self, rgb: np.ndarray) -> np.ndarray | None:
        res = self._mesh.process(np.ascontiguousarray(_rgb3(rgb)))
        if not res.multi_face_landmarks:
            return None
        lm = res.multi_face_landmarks[0].landmark
        return np.array([(p.x, p.y, p.z) for p in lm], np.float32)

    def close(self) -> None:
        self._mesh.close()


def _arr(lms, vis: bool = False):
    if lms is None:
        return None
    if vis:
        return np.array([(p.x, p.y, p.z, p.visibility) for p in lms.landmark], np.float32)
    return np.array([(p.x, p.y, p.z) for p in lms.landmark], np.float32)


class HolisticTracker(_Closing):
    """Holistic: face (478 refined), pose (33, image and world coordinates with visibility) and both hands (21
    each) in one pass -> :class:`HolisticFrame`."""

    def __init__(
        self,
        static_image_mode: bool = False,
        model_complexity: int = HOLISTIC_COMPLEXITY,
        min_detection_confidence: float = 0.5,
        min_tracking_confidence: float = 0.5,
    ):
        self._h = _mp().solutions.holistic.Holistic(
            static_image_mode=static_image_mode,
            model_complexity=model_complexity,
            refine_face_landmarks=True,
            min_detection_confidence=min_detection_confidence,
            min_tracking_confidence=min_tracking_confidence,
        )

    def __call__(self, rgb: np.ndarray) -> HolisticFrame:
        r = self._h.process(np.ascontiguousarray(_rgb3(rgb)))
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


class PoseTracker(_Closing):
    """Pose: one person's 33 body points -> :class:`PoseFrame`, or None (nobody)."""

    def __init__(self, static_image_mode: bool = True, model_complexity: int = 1):
        self._p = _mp().solutions.pose.Pose(
            static_image_mode=static_image_mode, model_complexity=model_complexity, min_detection_confidence=0.5
        )

    def __call__(self, rgb: np.ndarray) -> PoseFrame | None:
        r = self._p.process(np.ascontiguousarray(rgb))
        if r.pose_landmarks is None:
            return None
        return PoseFrame(_arr(r.pose_landmarks, True), _arr(r.pose_world_landmarks, True))

    def close(self) -> None:
        self._p.close()


class HandsTracker(_Closing):
    """Hands: every hand found (up to ``max_num_hands``) -> a list of :class:`Hand`."""

    def __init__(self, static_image_mode: bool = True, max_num_hands: int = 2, model_complexity: int = 1):
        self._h = _mp().solutions.hands.Hands(
            static_image_mode=static_image_mode, max_num_hands=max_num_hands, model_complexity=model_complexity
        )

    def __call__(self, rgb: np.ndarray) -> list[Hand]:
        r = self._h.process(np.ascontiguousarray(rgb))
        return [
            Hand(_arr(lm), h.classification[0].label, h.classification[0].score)
            for lm, h in zip(r.multi_hand_landmarks or [], r.multi_handedness or [])
        ]

    def close(self) -> None:
        self._h.close()


class FaceBoxTracker(_Closing):
    """Face detection (the full-range model: faces up to ~5 m) -> a list of :class:`FaceBox`."""

    def __init__(self, model_selection: int = 1, min_detection_confidence: float = 0.5):
        self._d = _mp().solutions.face_detection.FaceDetection(
            model_selection=model_selection, min_detection_confidence=min_detection_confidence
        )

    def __call__(self, rgb: np.ndarray) -> list[FaceBox]:
        out = []
        for d in self._d.process(rgb).detections or []:
            b = d.location_data.relative_bounding_box
            out.append(FaceBox(b.xmin, b.ymin, b.width, b.height, d.score[0] if d.score else 0.0))
        return out

    def close(self) -> None:
        self._d.close()


class MediaPipe:
    """The ``mediapipe`` tracker (:class:`anima.track.base.Tracker`)."""

    name = "mediapipe"

    def check(self) -> None:
        _mp()

    def version(self) -> str:
        return getattr(_mp(), "__version__", "?")

    def face_mesh(self, static: bool = False) -> FaceMeshTracker:
        return FaceMeshTracker(static_image_mode=static)

    def holistic(self, static: bool = False) -> HolisticTracker:
        return HolisticTracker(static_image_mode=static)

    def pose(self, static: bool = True) -> PoseTracker:
        return PoseTracker(static_image_mode=static, model_complexity=1)

    def hands(self, static: bool = True, max_hands: int = 2) -> HandsTracker:
        return HandsTracker(static_image_mode=static, max_num_hands=max_hands, model_complexity=1)

    def face_boxes(self) -> FaceBoxTracker:
        return FaceBoxTracker(model_selection=1, min_detection_confidence=0.5)

    def face_mesh_triangles(self) -> np.ndarray:
        return face_mesh_triangles()

    def lip_landmarks(self) -> np.ndarray:
        return np.array(sorted({i for e in _mp().solutions.face_mesh.FACEMESH_LIPS for i in e}))

    def face_provenance(self) -> dict:
        return {
            "name": "mediapipe.face_mesh",
            "version": self.version(),
            "refine_landmarks": True,
            "mode": "video",
            "landmarks": N_LANDMARKS,
        }

    def body_provenance(self) -> str:
        return f"mediapipe.holistic (model_complexity={HOLISTIC_COMPLEXITY})"


def face_mesh_triangles() -> np.ndarray:
    """Triangles of MediaPipe's face mesh from its tessellation edges (3-cliques), ``(T, 3)`` int32."""
    edges = _mp().solutions.face_mesh_connections.FACEMESH_TESSELATION
    nb: dict[int, set] = {}
    for a, b in edges:
        nb.setdefault(a, set()).add(b)
        nb.setdefault(b, set()).add(a)
    tris = set()
    for a, b in edges:
        for c in nb[a] & nb[b]:
            tris.add(tuple(sorted((a, b, c))))
    return np.array(sorted(tris), np.int32)
