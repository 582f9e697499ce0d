"""The avatar preview: the rig's bones and the animated head mesh, front and 3/4 views side by side."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from anima.io.video import VideoWriter
from anima.render.face import compose, put_label, raster_mesh
from anima.render.lod import decimate_morph_mesh
from anima.render.parallel import ordered_map


def _view(X: np.ndarray, size: int, yaw: float, centre: np.ndarray, scale: float) -> np.ndarray:
    """Metre-space points ``[..., 3]`` turned by ``yaw`` about +y -> camera-space pixels (+y up, +z to the
    viewer), ``scale`` pixels per metre, ``centre`` at the image centre."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return (np.asarray(X) - centre) @ R.T * scale + np.array([size / 2, -size / 2, 0.0])


def render_avatar_video(
    path: str | Path,
    fps: float,
    positions: np.ndarray,
    parents: np.ndarray,
    head: int,
    head_rot: np.ndarray,
    head_verts: np.ndarray,
    deltas: np.ndarray,
    weights: np.ndarray,
    tris: np.ndarray,
    audio: str | None = None,
    size: int = 512,
    progress: bool = False,
    head_triangles: int = 4000,
) -> None:
    """Rig joints ``positions [F, J, 3]`` (metres) with ``parents``; the head mesh hangs on joint ``head``:
    ``head_verts [V, 3]`` around that joint, turned by ``head_rot [F, 3, 3]``, with morph ``deltas [E, V, 3]``
    at ``weights [F, E]``. Front and 3/4 views, 1.4 m across, the speech ``audio`` muxed in. The head is
    drawn about 90 px tall, so it is decimated to ``head_triangles`` first (:mod:`anima.render.lod`)."""
    head_verts, tris, deltas = decimate_morph_mesh(head_verts, tris, deltas, head_triangles)
    centre = np.nanmedian(positions[:, head], axis=0) - np.array([0.0, 0.35, 0.0])
    scale = size / 1.4
    D = np.asarray(deltas, np.float32).reshape(len(deltas), -1)

    def frame(f: int) -> np.ndarray:
        canvas = np.empty((size, 2 * size, 3), np.uint8)
        V = (head_verts + (np.asarray(weights[f], np.float32) @ D).reshape(-1, 3)) @ head_rot[f].T
        V = V + positions[f, head]
        for k, yaw in enumerate((0.0, np.deg2rad(-60))):
            img = np.full((size, size, 3), 28, np.uint8)
            P = _view(positions[f], size, yaw, centre, scale)
            uv = np.stack([P[:, 0], -P[:, 1]], -1)
            a, b = uv[parents[1:]], uv[1:]
            ok = np.isfinite(a).all(1) & np.isfinite(b).all(1) & (np.abs(a - b).sum(1) > 0.5)
            segs = np.round(np.stack([a[ok], b[ok]], 1)).astype(np.int32)  # [S, 2, 2]
            cv2.polylines(img, list(segs.reshape(-1, 2, 1, 2)), False, (255, 170, 60), 2, cv2.LINE_AA)
            X = _view(V, size, yaw, centre, scale).astype(np.float32)  # the head over its bones
            compose(raster_mesh(X, tris, (size, size)), (size, size), background=img, inplace=True)
            canvas[:, k * size : (k + 1) * size] = img
        return put_label(canvas, f"{f / fps:5.2f} s   front | 3/4 view")

    with ExitStack() as stack:
        w = stack.enter_context(VideoWriter(path, fps, (2 * size, size), audio))
        for img in tqdm(
            ordered_map(frame, range(len(positions))),
            total=len(positions),
            desc="avatar",
            unit="fr",
            disable=not progress,
            leave=False,
        ):
            w.write(img)
