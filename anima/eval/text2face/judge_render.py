"""The judge's own render of face motion: a path that shares no code with the generator's
previews (``anima.render``: a z-buffer rasterizer with per-vertex shading, framed by
``anima.export.framing``), so that a change there cannot move the judge.

What is shared is only what defines the motion: the ICT face model's skin mesh, its 53 expression deltas and
the head rotation as an axis-angle. Everything after is the judge's own:

* the head rotation by OpenCV's Rodrigues formula;
* an orthographic camera framing the neutral head at 80 % of a 512-pixel square;
* the mesh's polygons (quads as drawn, not split) drawn far to near with ``cv2.fillConvexPoly`` (the painter's
  algorithm, no depth buffer), back faces culled, each polygon flat-shaded in a skin tone under a light from
  above the camera.

Variants tried and not kept (``python benchmarks/judge_calibrate.py`` with each; chosen by the mean
leave-one-clip-out event F1 over the six fitted events on the training/validation clips only): this skin-only
head 0.59; ICT's whole head with eyeballs (iris and pupil), teeth, gums and mouth socket 0.51; that head with
brows and lips painted on the skin at the 68 landmarks' contours 0.50 (the previews' renderer: 0.57).

Pure functions of arrays; the model is read once per call of :func:`render_frames`.
"""

from __future__ import annotations

import cv2
import numpy as np

from anima.facemodel.ict import load_face_model

SIZE = 512
HEAD_FILL = 0.8  # the neutral head's height over the image's
SKIN_BGR = np.array([0.62, 0.72, 0.87])  # RGB (0.87, 0.72, 0.62): a light skin tone, as OpenCV draws (BGR)
LIGHT = np.array([0.0, 0.35, 1.0]) / np.linalg.norm([0.0, 0.35, 1.0])  # toward the light, model axes
BACKGROUND = 60


def polygons(faces: np.ndarray) -> np.ndarray:
    """The mesh's polygons as quads ``[P, 4]`` (a triangle repeats its last corner)."""
    faces = np.asarray(faces, np.int64)
    return np.where(faces[:, 3:] >= 0, faces, faces[:, [0, 1, 2, 2]])


def outward_sign(verts: np.ndarray, quads: np.ndarray) -> float:
    """+1 when the polygons' winding gives normals that point away from the mesh's centre (the face mask's
    outside), -1 when the winding is the other way."""
    n = _normals(verts, quads)
    centre = verts.mean(0)
    return 1.0 if float(np.sum(n * (verts[quads].mean(1) - centre))) >= 0 else -1.0


def _normals(verts: np.ndarray, quads: np.ndarray) -> np.ndarray:
    a, b, c, d = (verts[quads[:, i]] for i in range(4))
    return np.cross(c - a, d - b)  # a quad's diagonals (a triangle's: its two edges from a)


def frame_image(
    verts: np.ndarray, quads: np.ndarray, sign: float, scale: float, centre: np.ndarray, size: int = SIZE
) -> np.ndarray:
    """One RGB uint8 image of posed vertices ``[V, 3]`` (cm, +y up, +z toward the camera)."""
    img = np.full((size, size, 3), BACKGROUND, np.uint8)
    n = sign * _normals(verts, quads)
    length = np.linalg.norm(n, axis=1)
    front = (n[:, 2] > 0) & (length > 0)
    n = n[front] / length[front, None]
    q = quads[front]
    depth = verts[q][:, :, 2].mean(1)
    light = np.clip(n @ LIGHT, 0.0, 1.0)
    colour = (0.3 + 0.7 * light)[:, None] * SKIN_BGR[None] * 255.0
    uv = np.empty((len(verts), 2), np.float64)
    uv[:, 0] = size / 2 + scale * (verts[:, 0] - centre[0])
    uv[:, 1] = size / 2 - scale * (verts[:, 1] - centre[1])
    pts = np.round(uv * 16).astype(np.int32)[q]  # 4 bits of sub-pixel precision
    order = np.argsort(depth, kind="stable")  # far to near
    for p, c in zip(pts[order], colour[order].tolist()):
        cv2.fillConvexPoly(img, p, c, cv2.LINE_8, 4)
    return np.ascontiguousarray(img[:, :, ::-1])


def render_frames(expression: np.ndarray, rotation: np.ndarray, size: int = SIZE):
    """RGB frames of expression weights ``[F, 53]`` and head axis-angles ``[F, 3]`` on the neutral head."""
    model = load_face_model().skin()
    quads = polygons(model.faces)
    neutral = model.neutral.astype(np.float64)
    deltas = model.expr_deltas.astype(np.float64).reshape(len(model.expr_deltas), -1)
    lo, hi = neutral.min(0), neutral.max(0)
    centre = (lo + hi) / 2
    scale = HEAD_FILL * size / float(hi[1] - lo[1])
    sign = outward_sign(neutral, quads)
    for w, r in zip(np.asarray(expression, np.float64), np.asarray(rotation, np.float64)):
        R, _ = cv2.Rodrigues(r.reshape(3, 1))
        v = (neutral + (w @ deltas).reshape(-1, 3) - centre) @ R.T + centre
        yield frame_image(v, quads, sign, scale, centre, size)
