"""The avatar preview: the skinned character (:func:`render_character_video`), front and 3/4 views side by side,
and the face close up beside them (a camera mounted on the head, looking it in the face)."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima.io.video import VideoWriter, even_size, to_i420
from anima.render.face import SKIN, label_width, put_label
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


def head_view(X: np.ndarray, size: int, head: np.ndarray, centre: np.ndarray, scale: float) -> np.ndarray:
    """Metre-space points ``[..., 3]`` seen by a camera mounted in front of a head whose rotation is ``head
    [3, 3]`` (columns: its axes in the world; its +z the way the face looks) -> pixels as :func:`_view` gives
    them, ``centre`` at the middle of the ``size`` square."""
    return (np.asarray(X) - centre) @ np.asarray(head) * scale + np.array([size / 2, -size / 2, 0.0])


FACE_M = 0.30
"""The face close-up's width, metres."""
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


def render_character_video(
    path: str | Path,
    fps: float,
    positions: np.ndarray,
    head: int,
    posed,
    tris: np.ndarray,
    audio: str | None = None,
    size: int = 512,
    progress: bool = False,
    face: tuple | None = None,
    colors: np.ndarray | None = None,
    lod: tuple | None = None,
) -> None:
    """The skinned character, front and 3/4 views side by side: ``posed(f0, f1)`` gives the posed vertices
    ``[n, V, 3]`` (metres) of frames ``f0:f1`` and ``positions [F, J, 3]`` its joints (the framing: each view
    cropped to where the figure moves during the clip, :func:`framing`). ``size`` pixels for 2.1 m; the speech
    ``audio`` muxed in. ``face``: ``(centre [F, 3], head [F, 3, 3], tris)``: a close-up of :data:`FACE_M`
    across, the square of the views' height, centred on ``centre`` and seen from in front of the head (its
    rotation ``head``, :func:`head_view`), drawing ``tris`` (the head's triangles) only. ``colors [V, 3]``: the
    vertices' colours (default: one skin). ``lod``: ``(A [n, V] sparse, tris [t, 3])`` from
    :func:`anima.render.lod.cluster_mean`: the front and 3/4 views draw the decimated mesh ``A @ V`` (the figure
    is a few hundred pixels tall there), the close-up the full head."""
    paint = SKIN if colors is None else np.ascontiguousarray(colors, np.float32)
    centre = np.nanmedian(positions[:, 0], axis=0) + np.array([0.0, 0.05, 0.0])
    scale = size / 2.1
    tris = np.ascontiguousarray(tris, np.int64)
    yaws = (0.0, np.deg2rad(-60))
    height, crops = framing(positions, head, 0.16, yaws, size, centre, scale, margin=20)
    x_at = np.cumsum([0] + [w for _, w, _ in crops] + ([height] if face is not None else []))
    blank = np.full((height, int(x_at[-1]), 3), 28, np.uint8)
    put_label(blank, "front | 3/4 view" + (" | face" if face is not None else ""), inplace=True,
              x=8 + label_width("000.00 s  "))  # fmt: skip
    frame_size = even_size((blank.shape[1], height))
    F = len(positions)
    if face is not None:
        fc, frot, ftris = face
        head_v = np.unique(ftris)
        head_tris = np.ascontiguousarray(np.searchsorted(head_v, ftris), np.int64)
        head_paint = paint if paint.ndim == 1 else np.ascontiguousarray(paint[head_v])
    body_tris, body_paint, A = tris, paint, None
    if lod is not None:
        A, body_tris = lod[0], np.ascontiguousarray(lod[1], np.int64)
        body_paint = paint if paint.ndim == 1 else np.ascontiguousarray(A @ paint, np.float32)

    def frames(chunk: int = 32):
        for f0 in range(0, F, chunk):
            V = posed(f0, min(F, f0 + chunk))
            for i in range(len(V)):
                yield f0 + i, V[i]

    def frame(item) -> np.ndarray:
        f, V = item
        canvas = blank.copy()
        B = V if A is None else A @ V
        for k, (yaw, (x0, _, y0)) in enumerate(zip(yaws, crops)):
            X = _view(B, size, yaw, centre, scale, (x0, y0))
            draw_shaded(canvas[:, x_at[k] : x_at[k + 1]], X, body_tris, body_paint, back_faces=False)
        if face is not None:  # the head's own vertices only
            X = head_view(V[head_v], height, frot[f], fc[f], height / FACE_M)
            draw_shaded(canvas[:, x_at[-2] : x_at[-1]], X, head_tris, head_paint, back_faces=False)
        put_label(canvas, f"{f / fps:5.2f} s", inplace=True)
        return to_i420(canvas, frame_size)

    with ExitStack() as stack:
        w = stack.enter_context(VideoWriter(path, fps, frame_size, audio, quality=6, drawn=True))
        for img in tqdm(
            ordered_map(frame, frames()), total=F, desc="avatar", unit="fr", disable=not progress, leave=False
        ):
            w.write_i420(img)
