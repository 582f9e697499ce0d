"""What a tracker gives: the :class:`Tracker` protocol (the models a tracker runs on RGB frames) and what each
model returns per frame. Light: no tracker library is imported here."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, NamedTuple, Protocol, TypeVar

import numpy as np

T = TypeVar("T", covariant=True)


@dataclass
class HolisticFrame:
    """One frame of face, body and hands. Coordinates are normalised to the image (x right, y down, in [0, 1]
    inside the picture; z in the tracker's depth units) unless said otherwise."""

    face: np.ndarray | None  # (478, 3) normalised
    pose: np.ndarray | None  # (33, 4) normalised x, y, z + visibility
    pose_world: np.ndarray | None  # (33, 4) metres (y down) + visibility
    left_hand: np.ndarray | None  # (21, 3) normalised (subject's left hand)
    right_hand: np.ndarray | None
    camera_step: np.ndarray | None = None  # (3,) the background's shift (pixels) and log scale since the last frame


@dataclass
class PoseFrame:
    """One person's body: ``image (33, 4)`` normalised x, y, z + visibility; ``world (33, 4)`` metres (y down)
    + visibility."""

    image: np.ndarray
    world: np.ndarray


class Hand(NamedTuple):
    landmarks: np.ndarray  # (21, 3) normalised
    side: str  # "Left" or "Right", as the tracker labels it
    score: float  # the tracker's confidence in the side


class FaceBox(NamedTuple):
    """A detected face's box, relative to the image's size."""

    xmin: float
    ymin: float
    width: float
    height: float
    score: float


class Model(Protocol, Generic[T]):
    """One opened model: call it with an RGB frame ``(H, W, 3) uint8`` (a grey ``(H, W)`` is repeated to 3
    channels by the face and holistic models); close it when done (or use it as a context manager). In video
    mode a model carries state from one frame to the next: one model per video."""

    def __call__(self, rgb: np.ndarray) -> T: ...

    def close(self) -> None: ...

    def __enter__(self): ...

    def __exit__(self, *exc): ...


class Tracker(Protocol):
    """A tracker: the models anima runs on frames, opened on demand (each call opens a new model).

    * :meth:`face_mesh`: per frame the face's 478 landmarks ``(478, 3)`` float32 normalised (468 surface points
      in MediaPipe's face-mesh order, then 10 iris points), or None where no face is found. The face model's
      correspondence (``anima.facemodel.correspondence``) is defined on these 478 points;
    * :meth:`holistic`: per frame a :class:`HolisticFrame` (face, 33 body points with visibility in the image and
      in metres, 21 points per hand);
    * :meth:`pose`: per frame a :class:`PoseFrame` or None (no person);
    * :meth:`hands`: per image the :class:`Hand` s found;
    * :meth:`face_boxes`: per frame the :class:`FaceBox` es found.

    ``static``: each frame on its own (photos) instead of video mode (tracking from the previous frame).
    """

    name: str

    def check(self) -> None:
        """Load the tracker's library now: :class:`anima.errors.MissingExtra` (exit 3, naming the extra to
        install) where it is absent, before a command does any work."""
        ...

    def version(self) -> str: ...

    def face_mesh(self, static: bool = False) -> Model[np.ndarray | None]: ...

    def holistic(self, static: bool = False) -> Model[HolisticFrame]: ...

    def pose(self, static: bool = True) -> Model[PoseFrame | None]: ...

    def hands(self, static: bool = True, max_hands: int = 2) -> Model[list[Hand]]: ...

    def face_boxes(self) -> Model[list[FaceBox]]: ...

    def face_mesh_triangles(self) -> np.ndarray:
        """``(T, 3)`` int32: the triangles of the face mesh's 468 surface points."""
        ...

    def lip_landmarks(self) -> np.ndarray:
        """The indices of the face mesh's lip landmarks, sorted."""
        ...

    def face_provenance(self) -> dict:
        """What a capture records of the face tracking (``meta.tracker``)."""
        ...

    def body_provenance(self) -> str:
        """What a capture records of the body tracking (``meta.skeleton.tracker``)."""
        ...
