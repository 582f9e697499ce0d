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


def render_mesh(
    verts_cam: np.ndarray,
    tris: np.ndarray,
    size: tuple[int, int],
    background: np.ndarray | None = None,
    alpha: float = 1.0,
) -> np.ndarray:
    """Render camera-space vertices (pixels, +y up) as a shaded mesh into an RGB uint8 image of ``size``
    (W, H), optionally alpha-blended over ``background``."""
    W, H = size
    uvz = np.stack([verts_cam[:, 0], -verts_cam[:, 1], verts_cam[:, 2]], -1)
    col, mask, _ = rasterize(uvz, tris, shade(verts_cam, tris), (W, H))
    rgb = (col * 255).astype(np.uint8)
    if background is None:
        out = np.full((H, W, 3), 24, np.uint8)
        out[mask] = rgb[mask]
        return out
    out = background.copy()
    out[mask] = (alpha * rgb[mask] + (1 - alpha) * background[mask]).astype(np.uint8)
    return out


def draw_points(img: np.ndarray, uv: np.ndarray, color=(0, 255, 0), radius: int = 1) -> np.ndarray:
    out = np.ascontiguousarray(img).copy()
    for u, v in np.asarray(uv):
        if np.isfinite(u) and np.isfinite(v):
            cv2.circle(out, (int(round(u)), int(round(v))), radius, color, -1, lineType=cv2.LINE_AA)
    return out


def put_label(img: np.ndarray, text: str) -> np.ndarray:
    out = np.ascontiguousarray(img).copy()
    cv2.putText(out, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(out, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return out
