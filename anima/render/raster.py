"""A z-buffer triangle rasterizer with barycentric colour interpolation (numba, CPU).

Input vertices are in image space ``(u, v, depth)`` with larger depth = closer to the viewer (camera +z).
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def _raster(uvz, tris, colors, img, zbuf, mask):
    H, W = zbuf.shape
    for t in range(tris.shape[0]):
        i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
        x0, y0, z0 = uvz[i0, 0], uvz[i0, 1], uvz[i0, 2]
        x1, y1, z1 = uvz[i1, 0], uvz[i1, 1], uvz[i1, 2]
        x2, y2, z2 = uvz[i2, 0], uvz[i2, 1], uvz[i2, 2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        xmin = max(int(np.floor(min(x0, min(x1, x2)))), 0)
        xmax = min(int(np.ceil(max(x0, max(x1, x2)))), W - 1)
        ymin = max(int(np.floor(min(y0, min(y1, y2)))), 0)
        ymax = min(int(np.ceil(max(y0, max(y1, y2)))), H - 1)
        inv = 1.0 / area
        for y in range(ymin, ymax + 1):
            py = y + 0.5
            for x in range(xmin, xmax + 1):
                px = x + 0.5
                w0 = ((x1 - px) * (y2 - py) - (x2 - px) * (y1 - py)) * inv
                w1 = ((x2 - px) * (y0 - py) - (x0 - px) * (y2 - py)) * inv
                w2 = 1.0 - w0 - w1
                if w0 < 0 or w1 < 0 or w2 < 0:
                    continue
                z = w0 * z0 + w1 * z1 + w2 * z2
                if z > zbuf[y, x]:
                    zbuf[y, x] = z
                    mask[y, x] = True
                    for c in range(colors.shape[1]):
                        img[y, x, c] = w0 * colors[i0, c] + w1 * colors[i1, c] + w2 * colors[i2, c]


def rasterize(uvz: np.ndarray, tris: np.ndarray, colors: np.ndarray, size: tuple[int, int]):
    """Render triangles. uvz ``[V, 3]``, tris ``[T, 3]``, colors ``[V, C]`` float, size ``(W, H)``.
    Returns (image ``[H, W, C]`` float32, coverage mask ``[H, W]`` bool, depth ``[H, W]``)."""
    W, H = size
    img = np.zeros((H, W, colors.shape[1]), np.float32)
    zbuf = np.full((H, W), -np.inf, np.float64)
    mask = np.zeros((H, W), np.bool_)
    _raster(
        np.ascontiguousarray(uvz, np.float64),
        np.ascontiguousarray(tris, np.int64),
        np.ascontiguousarray(colors, np.float32),
        img,
        zbuf,
        mask,
    )
    return img, mask, zbuf


@nb.njit(cache=True)
def _normals(verts, tris, out):
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        e1 = verts[b] - verts[a]
        e2 = verts[c] - verts[a]
        n = np.cross(e1, e2)
        out[a] += n
        out[b] += n
        out[c] += n


def vertex_normals(verts: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``[V, 3]``."""
    out = np.zeros(verts.shape, np.float64)
    _normals(np.ascontiguousarray(verts, np.float64), np.ascontiguousarray(tris, np.int64), out)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
