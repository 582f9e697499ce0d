"""Skeleton videos: the tracked joints over the input video, and a 3D render of the cleaned skeleton."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from anima.core.skeleton import JOINT_NAMES, PARENTS
from anima.io.sequence import TrackedSequence
from anima.io.video import VideoWriter, iter_frames, probe_video
from anima.render.face import put_label


def _color(j: int) -> tuple[int, int, int]:
    n = JOINT_NAMES[j]
    if n.startswith("left"):
        return (255, 120, 40)  # RGB: subject's left in orange
    if n.startswith("right"):
        return (40, 160, 255)  # right in blue
    return (230, 230, 230)


def draw_skeleton(img: np.ndarray, uv: np.ndarray, thickness: int = 2) -> np.ndarray:
    out = np.ascontiguousarray(img).copy()
    for j in range(1, len(PARENTS)):
        p = PARENTS[j]
        a, b = uv[p], uv[j]
        if np.isfinite(a).all() and np.isfinite(b).all():
            t = thickness if j < 13 else max(1, thickness - 1)
            cv2.line(out, tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b), _color(j), t, cv2.LINE_AA)
    return out


def project_3d(J: np.ndarray, size: int, yaw: float) -> np.ndarray:
    """Orthographic view of metre-space joints rotated by ``yaw`` about +y, 1.4 m across the image."""
    c, s = np.cos(yaw), np.sin(yaw)
    x = c * J[..., 0] + s * J[..., 2]
    y = J[..., 1]
    scale = size / 1.4
    return np.stack([size / 2 + scale * x, size * 0.72 - scale * y], -1)


def skeleton_views(J: np.ndarray, size: int = 512) -> np.ndarray:
    """Front and 3/4 views of one frame of metre-space joints ``[55, 3]``: an RGB image ``(size, 2 size, 3)``."""
    canvas = np.full((size, 2 * size, 3), 28, np.uint8)
    for k, yaw in enumerate((0.0, np.deg2rad(-60))):
        canvas[:, k * size : (k + 1) * size] = draw_skeleton(
            canvas[:, k * size : (k + 1) * size], project_3d(J, size, yaw), 3
        )
    return canvas


def render_skeleton_videos(
    seq: TrackedSequence,
    video: str | None,
    overlay_path: str | Path | None,
    render3d_path: str | Path | None,
    progress: bool = True,
    size3d: int = 512,
    audio: str | None = None,
) -> None:
    """Write the skeleton overlay (raw 2D joints over the input ``video``) and a 3D render (front and 3/4 views
    of the cleaned skeleton). The source's audio track, if any (else ``audio``, e.g. the speech gestures were
    made from), is muxed into both."""
    if seq.body_joints is None:
        return
    frames = None
    if video is not None:
        info = probe_video(video)
        audio = video if info.has_audio else audio
        frames = iter_frames(info)
    with ExitStack() as stack:
        if frames is not None:
            stack.callback(frames.close)
        w_ov = (
            stack.enter_context(VideoWriter(overlay_path, seq.fps, (seq.width, seq.height), audio))
            if overlay_path and frames is not None and seq.body_image is not None
            else None
        )
        w_3d = (
            stack.enter_context(VideoWriter(render3d_path, seq.fps, (2 * size3d, size3d), audio))
            if render3d_path
            else None
        )
        for f in tqdm(range(seq.n_frames), desc="skeleton", unit="fr", disable=not progress, leave=False):
            frame = next(frames, None) if frames is not None else None
            if w_ov is not None and frame is not None:
                w_ov.write(draw_skeleton(frame, seq.body_image[f], max(2, seq.width // 256)))
            if w_3d is not None:
                w_3d.write(
                    put_label(skeleton_views(seq.body_joints[f], size3d), f"{f / seq.fps:5.2f} s   front | 3/4 view")
                )
