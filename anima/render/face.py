"""Renders of a fitted face: shaded mesh alone, mesh over the video frame, landmarks."""

from __future__ import annotations

import cv2
import numpy as np

from anima.render.raster import rasterize, vertex_normals

SKIN = np.array([0.80, 0.82, 0.86], np.float32)


def shade(verts_cam: np.ndarray, tris: np.ndarray, base=SKIN) -> np.ndarray:
    """Per-vertex Lambert + ambient colour (light from the camera), ``[V, 3]`` in [0, 1]."""
    n = vertex_normals(verts_cam, tris)
    lam = np.clip(n[:, 2], 0.0, 1.0)
    return (0.25 + 0.75 * lam)[:, None] * base[None]


def raster_mesh(verts_cam: np.ndarray, tris: np.ndarray, size: tuple[int, int], back_faces: bool = True):
    """Rasterize camera-space vertices (pixels, +y up) as a shaded mesh, within the mesh's own box only:
    ``(box, rgb, mask)`` with ``box = (x0, y0, w, h)`` inside ``size`` (W, H), ``rgb`` uint8 and ``mask``
    bool of the box's size; None when the mesh is off the image. ``back_faces=False``: see
    :func:`anima.render.raster.rasterize`."""
    W, H = size
    uvz = np.stack([verts_cam[:, 0], -verts_cam[:, 1], verts_cam[:, 2]], -1)
    ok = np.isfinite(uvz).all(1)
    if not ok.any():
        return None
    lo = np.floor(uvz[ok, :2].min(0)).astype(int)
    hi = np.ceil(uvz[ok, :2].max(0)).astype(int) + 1
    x0, y0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    x1, y1 = min(int(hi[0]), W), min(int(hi[1]), H)
    if x1 <= x0 or y1 <= y0:
        return None
    col, mask, _ = rasterize(
        uvz - np.array([x0, y0, 0.0]), tris, shade(verts_cam, tris), (x1 - x0, y1 - y0), back_faces
    )
    return (x0, y0, x1 - x0, y1 - y0), (col * 255).astype(np.uint8), mask


def compose(
    raster, size: tuple[int, int], background: np.ndarray | None = None, alpha: float = 1.0, inplace: bool = False
) -> np.ndarray:
    """An RGB uint8 image of ``size`` (W, H) with a :func:`raster_mesh` result over ``background`` (alpha
    blended) or over a dark grey; ``inplace`` draws into ``background`` itself."""
    W, H = size
    if background is None:
        out = np.full((H, W, 3), 24, np.uint8)
    else:
        out = background if inplace else background.copy()
    if raster is None:
        return out
    (x0, y0, w, h), rgb, mask = raster
    crop = out[y0 : y0 + h, x0 : x0 + w]
    if background is not None and alpha < 1.0:
        rgb = cv2.addWeighted(rgb, float(alpha), crop, 1.0 - float(alpha), 0.0)
    cv2.copyTo(rgb, mask.view(np.uint8), crop)  # in place into the view (50x np.copyto's masked copy)
    return out


def render_mesh(
    verts_cam: np.ndarray,
    tris: np.ndarray,
    size: tuple[int, int],
    background: np.ndarray | None = None,
    alpha: float = 1.0,
) -> np.ndarray:
    """Render camera-space vertices (pixels, +y up) as a shaded mesh into an RGB uint8 image of ``size``
    (W, H), optionally alpha-blended over ``background``."""
    return compose(raster_mesh(verts_cam, tris, size), size, background, alpha)


def draw_points(img: np.ndarray, uv: np.ndarray, color=(0, 255, 0), radius: int = 1) -> np.ndarray:
    out = np.ascontiguousarray(img).copy()
    for u, v in np.asarray(uv):
        if np.isfinite(u) and np.isfinite(v):
            cv2.circle(out, (int(round(u)), int(round(v))), radius, color, -1, lineType=cv2.LINE_AA)
    return out


def put_label(img: np.ndarray, text: str, inplace: bool = False, x: int = 8) -> np.ndarray:
    """``text`` on the top row from column ``x``, white on a black outline; on a copy unless ``inplace``."""
    out = img if inplace else np.ascontiguousarray(img).copy()
    cv2.putText(out, text, (x, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, (x, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def label_width(text: str) -> int:
    """The width in pixels :func:`put_label` gives ``text``."""
    return cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.55, 3)[0][0]
