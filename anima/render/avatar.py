"""The avatar preview: the rig's bones and the animated head mesh, front and 3/4 views side by side."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from anima.io.video import VideoWriter, even_size, to_i420
from anima.render.face import SKIN, label_width, put_label
from anima.render.lod import decimate_morph_mesh
from anima.render.parallel import ordered_map
from anima.render.raster import draw_shaded


def _view(
    X: np.ndarray, size: int, yaw: float, centre: np.ndarray, scale: float, corner: tuple[int, int] = (0, 0)
) -> np.ndarray:
    """Metre-space points ``[..., 3]`` turned by ``yaw`` about +y -> camera-space pixels (+y up, +z to the
    viewer), ``scale`` pixels per metre, ``centre`` at the centre of a ``size`` square whose pixel ``corner``
    (x, y from its top left) is the image's top left."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return (np.asarray(X) - centre) @ R.T * scale + np.array([size / 2 - corner[0], corner[1] - size / 2, 0.0])


LABEL_PX = 30
"""Rows kept free above the figure for the time label."""


def framing(
    positions: np.ndarray, head: int, head_radius: float, yaws, size: int, centre, scale: float, margin: int = 12
) -> tuple[int, list[tuple[int, int, int]]]:
    """Where each view of a ``size`` square (1.4 m across) the figure moves in, over the whole clip: the
    joints and a ``head_radius`` ball around the head joint, plus ``margin`` pixels and the label's rows.
    Returns ``(height, [(x0, width, y0) per view])``: the crop of each square that is drawn, widths and the
    height rounded up to multiples of 8 and never beyond the square. The figure keeps its size in pixels;
    the empty floor and sky are not drawn (or encoded: about half the pixels of two full squares)."""
    J = positions[np.isfinite(positions).all(-1).all(-1)]
    if not len(J):
        return size, [(0, size, 0) for _ in yaws]
    pad = head_radius * scale + margin
    crops, tops, bottoms = [], [], []
    for yaw in yaws:
        P = _view(J.reshape(-1, 3), size, yaw, centre, scale)
        H = _view(J[:, head], size, yaw, centre, scale)
        lo_x = min(P[:, 0].min() - margin, H[:, 0].min() - pad)
        hi_x = max(P[:, 0].max() + margin, H[:, 0].max() + pad)
        tops.append(min(-P[:, 1].max() - margin, -H[:, 1].max() - pad) - LABEL_PX)
        bottoms.append(max(-P[:, 1].min() + margin, -H[:, 1].min() + pad))
        crops.append((lo_x, hi_x))
    y0 = int(np.clip(np.floor(min(tops)), 0, size))
    height = min(size - y0, -(-int(np.ceil(max(bottoms) - y0)) // 8) * 8)
    out = []
    for lo_x, hi_x in crops:
        x0 = int(np.clip(np.floor(lo_x), 0, size))
        width = min(size - x0, -(-int(np.ceil(hi_x - x0)) // 8) * 8)
        out.append((x0, max(width, 8), y0))
    return max(height, 8), out


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
    at ``weights [F, E]``. Front and 3/4 views at ``size`` pixels for 1.4 m, each cropped to where the figure
    moves during the clip (:func:`framing`), the speech ``audio`` muxed in. The head is drawn about 90 px
    tall, so it is decimated to ``head_triangles`` first (:mod:`anima.render.lod`)."""
    head_verts, tris, deltas = decimate_morph_mesh(head_verts, tris, deltas, head_triangles)
    centre = np.nanmedian(positions[:, head], axis=0) - np.array([0.0, 0.35, 0.0])
    scale = size / 1.4
    D = np.asarray(deltas, np.float32).reshape(len(deltas), -1)
    base = np.asarray(head_verts, np.float32)
    tris = np.ascontiguousarray(tris, np.int64)
    yaws = (0.0, np.deg2rad(-60))
    radius = float(np.linalg.norm(base, axis=1).max()) + 0.03  # the head about its joint, 3 cm for expressions
    height, crops = framing(positions, head, radius, yaws, size, centre, scale)
    x_at = np.cumsum([0] + [w for _, w, _ in crops])  # each view's first column in the canvas
    blank = np.full((height, int(x_at[-1]), 3), 28, np.uint8)
    put_label(blank, "front | 3/4 view", inplace=True, x=8 + label_width("000.00 s  "))  # once; the time per frame
    frame_size = even_size((blank.shape[1], height))

    def chunk_geometry(f0: int, f1: int):
        """Frames ``f0:f1`` in bulk (one matrix product for the expressions, no per-frame Python): per frame
        the expressive head around its joint, and per view the head's pose as one affine map into the view's
        pixels (``X = V @ M + t``) and the bones as integer segments."""
        n = f1 - f0
        V = base + (np.asarray(weights[f0:f1], np.float32) @ D).reshape(n, -1, 3)
        views = []
        for yaw, (x0, _, y0) in zip(yaws, crops):
            M = head_rot[f0:f1].transpose(0, 2, 1) @ _view(np.eye(3), 0, yaw, np.zeros(3), scale)  # [n, 3, 3]
            t = _view(positions[f0:f1, head], size, yaw, centre, scale, (x0, y0))  # [n, 3]
            P = _view(positions[f0:f1], size, yaw, centre, scale, (x0, y0))
            uv = np.stack([P[..., 0], -P[..., 1]], -1)
            a, b = uv[:, parents[1:]], uv[:, 1:]
            ok = np.isfinite(a).all(-1) & np.isfinite(b).all(-1) & (np.abs(a - b).sum(-1) > 0.5)
            segs = np.round(np.nan_to_num(np.stack([a, b], 2))).astype(np.int32)  # [n, S, 2, 2]
            bones = [segs[i] if ok[i].all() else segs[i][ok[i]] for i in range(n)]  # OpenCV: [S, 2, 2] = S lines
            views.append((bones, M, t))
        for i in range(n):
            yield f0 + i, V[i], [(bones[i], M[i], t[i]) for bones, M, t in views]

    def frames(chunk: int = 128):
        for f0 in range(0, len(positions), chunk):
            yield from chunk_geometry(f0, min(len(positions), f0 + chunk))

    def frame(item) -> np.ndarray:
        """One frame drawn into one canvas (each view a slice of it), returned as I420: one full-size copy
        and one conversion per frame, on the rendering threads."""
        f, V, views = item
        canvas = blank.copy()
        for k, (segs, M, t) in enumerate(views):
            X = V @ M + t  # the head in the view's pixels (float64, as the rasterizer takes it)
            img = canvas[:, x_at[k] : x_at[k + 1]]  # a view: OpenCV and the rasterizer draw into the canvas
            if len(segs):
                cv2.polylines(img, segs, False, (255, 170, 60), 2, cv2.LINE_AA)
            draw_shaded(img, X, tris, SKIN, back_faces=False)
        put_label(canvas, f"{f / fps:5.2f} s", inplace=True)
        return to_i420(canvas, frame_size)

    with ExitStack() as stack:
        w = stack.enter_context(VideoWriter(path, fps, frame_size, audio, quality=6, drawn=True))
        for img in tqdm(
            ordered_map(frame, frames()),
            total=len(positions),
            desc="avatar",
            unit="fr",
            disable=not progress,
            leave=False,
        ):
            w.write_i420(img)
