"""The tracked skeleton drawn over a video frame (:func:`anima.render.videos.render_videos` writes the video)."""

from __future__ import annotations

import cv2
import numpy as np

from anima.core.skeleton import JOINT_NAMES, PARENTS


def _color(j: int) -> tuple[int, int, int]:
    n = JOINT_NAMES[j]
    if n.startswith("left"):
        return (255, 120, 40)  # RGB: subject's left in orange
    if n.startswith("right"):
        return (40, 160, 255)  # right in blue
    return (230, 230, 230)


def draw_skeleton(img: np.ndarray, uv: np.ndarray, thickness: int = 2) -> np.ndarray:
    """The bones of ``uv [J, 2]`` (image pixels; a non-finite joint is left out) drawn on a copy of ``img``."""
    out = np.ascontiguousarray(img).copy()
    for j in range(1, len(PARENTS)):
        p = PARENTS[j]
        a, b = uv[p], uv[j]
        if np.isfinite(a).all() and np.isfinite(b).all():
            t = thickness if j < 13 else max(1, thickness - 1)
            cv2.line(out, tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b), _color(j), t, cv2.LINE_AA)
    return out
