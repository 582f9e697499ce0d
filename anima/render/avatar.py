"""The avatar preview: the skinned character (:func:`render_character_video`), front and 3/4 views side by side,
and the face close up beside them (a camera mounted on the head, looking it in the face)."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import cv2
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
FACE_SUPERSAMPLE = 2
"""The face close-up's eyes are drawn at this many times its pixels a side and averaged back
(:func:`draw_smooth`, :func:`draw_close_up`)."""
SMOOTH_MARGIN = 3
"""Pixels around the box of an eye's vertices drawn anti-aliased too (the lids' skin above and below)."""
LABEL_PX = 30
"""Rows kept free above the figure for the time label."""


def draw_smooth(img: np.ndarray, X: np.ndarray, tris: np.ndarray, paint, supersample: int = FACE_SUPERSAMPLE,
                boxes=None) -> np.ndarray:  # fmt: skip
    """:func:`anima.render.raster.draw_shaded` (front faces) of ``X`` (``img``'s pixels) over the uint8 ``img`` in
    place, its pixels in ``boxes`` (``(x0, y0, x1, y1)`` each; default: all) anti-aliased: drawn at ``supersample``
    times the pixels a side and each block averaged back into one pixel, so an edge (a lid's, a lip's) that moves
    by less than a pixel still moves the picture. Pixels nothing covers keep their value exactly."""
    h, w = img.shape[:2]
    n = int(supersample)
    boxes = [(0, 0, w, h)] if boxes is None else boxes
    boxes = [(max(int(x0), 0), max(int(y0), 0), min(int(x1), w), min(int(y1), h)) for x0, y0, x1, y1 in boxes]
    boxes = [b for b in boxes if b[2] > b[0] and b[3] > b[1]]
    if n <= 1 or not boxes:
        return draw_shaded(img, X, tris, paint, back_faces=False)
    X = np.asarray(X, np.float64)
    under = [img[y0:y1, x0:x1].copy() for x0, y0, x1, y1 in boxes]
    if boxes != [(0, 0, w, h)]:
        draw_shaded(img, X, tris, paint, back_faces=False)  # the rest at the picture's own pixels
    for (x0, y0, x1, y1), u in zip(boxes, under):
        big = cv2.resize(u, ((x1 - x0) * n, (y1 - y0) * n), interpolation=cv2.INTER_NEAREST)
        draw_shaded(big, (X - [x0, -y0, 0.0]) * n, tris, paint, back_faces=False)  # scaled alike: the same normals
        img[y0:y1, x0:x1] = cv2.resize(big, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    return img


def draw_close_up(img: np.ndarray, V: np.ndarray, head: np.ndarray, centre: np.ndarray, tris: np.ndarray, paint,
                  smooth=None) -> np.ndarray:  # fmt: skip
    """The head's vertices ``V [n, 3]`` (metres) close up over the square uint8 ``img`` in place (a view into a
    larger canvas works): :data:`FACE_M` across, seen from in front of the head (rotation ``head``, ``centre`` in
    the middle: :func:`head_view`), drawing ``tris``. The box around each group of vertices in ``smooth`` (index
    arrays into ``V``: the eyes, :func:`anima.facemodel.character.eye_vertices`; default: the whole square) is
    drawn anti-aliased (:func:`draw_smooth`): a lid that opens or shuts by a few per cent of the eye moves by less
    than a pixel, and drawn plain the picture jumps a pixel at a time. Read back by a face tracker on five talking
    clips whose eyes hardly move (``benchmarks/face_readback.py``, docs/rig.md), the eyes anti-aliased followed
    the video's at r 0.68-0.87 where drawn plain they did at 0.50-0.79; the mouth's box anti-aliased too, or the
    whole square, read back the same, and the eyes alone cost about a quarter of the whole square drawn so
    (``avatar.mp4`` of d0: 0.05 s against 0.22 s more). ``avatar.mp4``'s face panel and the read-back
    benchmark's close-up."""
    size = img.shape[0]
    X = head_view(V, size, head, centre, size / FACE_M)
    boxes = None
    if smooth is not None:
        boxes, m = [], SMOOTH_MARGIN
        for group in smooth:
            P = X[np.asarray(group)]
            P = P[np.isfinite(P).all(-1)]
            if len(P):
                boxes.append((int(np.floor(P[:, 0].min())) - m, int(np.floor(-P[:, 1].max())) - m,
                              int(np.ceil(P[:, 0].max())) + m + 1, int(np.ceil(-P[:, 1].min())) + m + 1))  # fmt: skip
    return draw_smooth(img, X, tris, paint, boxes=boxes)


def figure_bounds(posed, n_frames: int, yaws, positions: np.ndarray | None = None, head: int | None = None,
                  head_radius: float = 0.0, chunk: int = 64) -> np.ndarray:  # fmt: skip
    """Where the figure goes during the whole clip, seen from each yaw: ``[len(yaws), 4]`` rows of ``(x_lo, x_hi,
    y_lo, y_hi)`` (metres; x along the view's right as :func:`_view` turns it, y up) around every vertex of
    ``posed(f0, f1)`` (``[n, V, 3]``, frames ``f0:f1``) on every frame, the joints ``positions [F, J, 3]`` and
    a ``head_radius`` ball around the joint ``head``. NaN where nothing is finite."""
    out = np.tile(np.array([np.inf, -np.inf, np.inf, -np.inf]), (len(yaws), 1))
    turns = np.array([[np.cos(y), np.sin(y)] for y in yaws])  # x' = cos * x + sin * z

    def add(P: np.ndarray, pad: float = 0.0) -> None:
        P = P[np.isfinite(P).all(-1)]
        if not len(P):
            return
        u = P[:, [0, 2]] @ turns.T  # [n, views]
        out[:, 0] = np.minimum(out[:, 0], u.min(0) - pad)
        out[:, 1] = np.maximum(out[:, 1], u.max(0) + pad)
        out[:, 2] = np.minimum(out[:, 2], P[:, 1].min() - pad)
        out[:, 3] = np.maximum(out[:, 3], P[:, 1].max() + pad)

    for f0 in range(0, n_frames, chunk):
        add(np.asarray(posed(f0, min(n_frames, f0 + chunk))).reshape(-1, 3))
    if positions is not None:
        add(np.asarray(positions).reshape(-1, 3))
        if head is not None:
            add(np.asarray(positions)[:, head], head_radius)
    out[~np.isfinite(out).all(1)] = np.nan
    return out


def framing(bounds: np.ndarray, yaws, size: int, margin: int = 12) -> tuple[float, int, list[tuple]]:
    """The views of a figure that stays where ``bounds`` (:func:`figure_bounds`) says, over the whole clip: one
    still camera a view (a jump is seen as a jump), the figure at ``size`` pixels for 2.1 m, or smaller where its
    whole course would not fit a ``size`` square with ``margin`` pixels around it and the label's rows above.
    Returns ``(scale, height, [(centre [3], x0, width, y0) per view])``: pixels per metre, the views' common
    height, and each view's :func:`_view` centre and corner and its width, widths and the height rounded up to
    multiples of 8. Every point inside ``bounds`` lands ``margin`` pixels or more inside its view (and below the
    label's rows); the empty floor and sky around the figure are not drawn (or encoded)."""
    b = np.asarray(bounds, np.float64)
    if not np.isfinite(b).all():
        b = np.tile([-0.5, 0.5, 0.0, 1.9], (len(yaws), 1))  # nothing to frame: a standing person's place
    w_m = np.maximum(b[:, 1] - b[:, 0], 1e-3)
    h_m = max(b[0, 3] - b[0, 2], 1e-3)
    room = size - 2 * margin
    scale = float(min(size / 2.1, (room - LABEL_PX) / h_m, *(room / w_m)))
    ceil8 = lambda x: max(8, -(-int(np.ceil(x)) // 8) * 8)
    height = ceil8(h_m * scale + 2 * margin + LABEL_PX)
    views = []
    for yaw, (x_lo, x_hi, y_lo, y_hi) in zip(yaws, b):
        width = ceil8((x_hi - x_lo) * scale + 2 * margin)
        mid = np.array([(x_lo + x_hi) / 2, (y_lo + y_hi) / 2, 0.0])
        c, s_ = np.cos(yaw), np.sin(yaw)
        centre = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]]).T @ mid  # turned, it is ``mid``
        x0 = int(round(size / 2 - width / 2))  # the figure's middle in the middle of the view,
        y0 = int(round(size / 2 - (height + LABEL_PX) / 2))  # and of the rows under the label
        views.append((centre, x0, width, y0))
    return scale, height, views


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
    ``[n, V, 3]`` (metres) of frames ``f0:f1`` and ``positions [F, J, 3]`` its joints (``head``: the head's).
    Each view is a still camera around everywhere the figure goes during the clip, a jump's highest hands and
    head as its feet (:func:`figure_bounds`, :func:`framing`): ``size`` pixels for 2.1 m, less when that would
    not hold the figure's whole course in a ``size`` square. The speech ``audio`` muxed in. ``face``:
    ``(centre [F, 3], head [F, 3, 3], tris[, smooth])``: a close-up of :data:`FACE_M` across, the square of the
    views' height, centred on ``centre`` and seen from in front of the head (its rotation ``head``,
    :func:`head_view`), drawing ``tris`` (the head's triangles) only, the boxes
    around the vertex groups ``smooth`` (the eyes) anti-aliased (:func:`draw_close_up`). ``colors [V, 3]``: the
    vertices' colours (default: one skin). ``lod``: ``(A [n, V] sparse, tris [t, 3])`` from
    :func:`anima.render.lod.cluster_mean`: the front and 3/4 views draw the decimated mesh ``A @ V`` (the figure
    is a few hundred pixels tall there), the close-up the full head."""
    paint = SKIN if colors is None else np.ascontiguousarray(colors, np.float32)
    tris = np.ascontiguousarray(tris, np.int64)
    yaws = (0.0, np.deg2rad(-60))
    F = len(positions)
    bounds = figure_bounds(posed, F, yaws, positions, head, 0.16)
    scale, height, views = framing(bounds, yaws, size, margin=20)
    x_at = np.cumsum([0] + [w for _, _, w, _ in views] + ([height] if face is not None else []))
    blank = np.full((height, int(x_at[-1]), 3), 28, np.uint8)
    put_label(blank, "front | 3/4 view" + (" | face" if face is not None else ""), inplace=True,
              x=8 + label_width("000.00 s  "))  # fmt: skip
    frame_size = even_size((blank.shape[1], height))
    if face is not None:
        fc, frot, ftris, *more = face
        head_v = np.unique(ftris)
        smooth = [np.searchsorted(head_v, g[np.isin(g, head_v)]) for g in more[0]] if more else None
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
        for k, (yaw, (centre, x0, _, y0)) in enumerate(zip(yaws, views)):
            X = _view(B, size, yaw, centre, scale, (x0, y0))
            draw_shaded(canvas[:, x_at[k] : x_at[k + 1]], X, body_tris, body_paint, back_faces=False)
        if face is not None:  # the head's own vertices only
            draw_close_up(canvas[:, x_at[-2] : x_at[-1]], V[head_v], frot[f], fc[f], head_tris, head_paint, smooth)
        put_label(canvas, f"{f / fps:5.2f} s", inplace=True)
        return to_i420(canvas, frame_size)

    with ExitStack() as stack:
        w = stack.enter_context(VideoWriter(path, fps, frame_size, audio, quality=6, drawn=True))
        for img in tqdm(
            ordered_map(frame, frames()), total=F, desc="avatar", unit="fr", disable=not progress, leave=False
        ):
            w.write_i420(img)
