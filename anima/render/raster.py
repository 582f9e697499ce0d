"""A z-buffer triangle rasterizer with barycentric colour interpolation (numba, CPU).

Input vertices are in image space ``(u, v, depth)`` with larger depth = closer to the viewer (camera +z).
"""

from __future__ import annotations

import numba as nb
import numpy as np

NARROW = 8
"""Triangles whose box is narrower than this many pixels test every pixel of each row of the box."""


@nb.njit(cache=True, nogil=True)
def _raster(uvz, tris, colors, img, zbuf, mask, band_lo, band_hi, cull=0.0):
    """All triangles into the rows ``band_lo <= y < band_hi`` (triangles in their given order); ``cull``
    -1 or 1 skips the triangles whose signed image-space area has that sign (0: draw both sides)."""
    H, W = zbuf.shape
    C = colors.shape[1]
    for t in range(tris.shape[0]):
        i0, i1, i2 = tris[t, 0], tris[t, 1], tris[t, 2]
        x0, y0, z0 = uvz[i0, 0], uvz[i0, 1], uvz[i0, 2]
        x1, y1, z1 = uvz[i1, 0], uvz[i1, 1], uvz[i1, 2]
        x2, y2, z2 = uvz[i2, 0], uvz[i2, 1], uvz[i2, 2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12 or area * cull > 0:
            continue
        xmin = max(int(np.floor(min(x0, min(x1, x2)))), 0)
        xmax = min(int(np.ceil(max(x0, max(x1, x2)))), W - 1)
        ymin = max(int(np.floor(min(y0, min(y1, y2)))), band_lo)
        ymax = min(int(np.ceil(max(y0, max(y1, y2)))), band_hi - 1)
        if xmin > xmax or ymin > ymax:
            continue
        inv = 1.0 / area
        # barycentric weights as affine functions of the pixel centre: w = a * px + b * py + c
        a0, b0, c0 = (y1 - y2) * inv, (x2 - x1) * inv, (x1 * y2 - x2 * y1) * inv
        a1, b1, c1 = (y2 - y0) * inv, (x0 - x2) * inv, (x2 * y0 - x0 * y2) * inv
        for y in range(ymin, ymax + 1):
            py = y + 0.5
            r0 = b0 * py + c0
            r1 = b1 * py + c1
            xs, xe = xmin, xmax
            if xmax - xmin >= NARROW:
                # the span of pixel centres inside the triangle on this row (w0, w1, w2 >= 0), widened by one
                # pixel against rounding; the exact test below decides (a narrow box is tested whole: the
                # same pixels, without the divisions)
                lo, hi = xmin + 0.5, xmax + 0.5
                for a, r in ((a0, r0), (a1, r1), (-(a0 + a1), 1.0 - r0 - r1)):
                    if a > 0:
                        lo = max(lo, -r / a - 1.0)
                    elif a < 0:
                        hi = min(hi, -r / a + 1.0)
                    elif r < 0:
                        hi = lo - 1.0
                if hi < lo:
                    continue
                xs = max(xmin, int(np.floor(lo - 0.5)))
                xe = min(xmax, int(np.ceil(hi - 0.5)))
            for x in range(xs, xe + 1):
                px = x + 0.5
                w0 = a0 * px + r0
                w1 = a1 * px + r1
                w2 = 1.0 - w0 - w1
                if w0 < 0 or w1 < 0 or w2 < 0:
                    continue
                z = w0 * z0 + w1 * z1 + w2 * z2
                if z > zbuf[y, x]:
                    zbuf[y, x] = z
                    mask[y, x] = True
                    for c in range(C):
                        img[y, x, c] = w0 * colors[i0, c] + w1 * colors[i1, c] + w2 * colors[i2, c]


@nb.njit(cache=True, nogil=True, parallel=True)
def _raster_bands(uvz, tris, colors, img, zbuf, mask, n_bands, cull=0.0):
    """The image in ``n_bands`` horizontal bands, one per thread: every band draws the triangles that reach
    it in the same order, so the result equals one pass over the whole image (no pixel is shared)."""
    H = zbuf.shape[0]
    step = (H + n_bands - 1) // n_bands
    for b in nb.prange(n_bands):
        _raster(uvz, tris, colors, img, zbuf, mask, b * step, min(H, (b + 1) * step), cull)


BACK = 1.0
"""The sign of a back-facing triangle's area in :func:`_raster` (image space, +y down): the mesh's fronts are
counter-clockwise seen from the camera, so their image-space area is negative (checked on the head mesh by
``tests/render/test_render.py``)."""

BAND_MIN_PIXELS = 40_000
"""Boxes smaller than this are drawn in one band (the threads cost more than they save)."""


def rasterize(uvz: np.ndarray, tris: np.ndarray, colors: np.ndarray, size: tuple[int, int], back_faces: bool = True):
    """Render triangles. uvz ``[V, 3]``, tris ``[T, 3]``, colors ``[V, C]`` float, size ``(W, H)``.
    Returns (image ``[H, W, C]`` float32, coverage mask ``[H, W]`` bool, depth ``[H, W]``). Large images are
    drawn in horizontal bands on numba's threads (the same result). ``back_faces=False`` skips triangles
    that face away from the viewer (counter-clockwise seen from +z, the mesh convention, is the front): for
    closed meshes, where the z-buffer would hide them anyway."""
    W, H = size
    img = np.zeros((H, W, colors.shape[1]), np.float32)
    zbuf = np.full((H, W), -np.inf, np.float64)
    mask = np.zeros((H, W), np.bool_)
    args = (
        np.ascontiguousarray(uvz, np.float64),
        np.ascontiguousarray(tris, np.int64),
        np.ascontiguousarray(colors, np.float32),
        img,
        zbuf,
        mask,
    )
    cull = 0.0 if back_faces else BACK
    if W * H < BAND_MIN_PIXELS or nb.get_num_threads() < 2:
        _raster(*args, 0, H, cull)
    else:
        _raster_bands(*args, 2 * nb.get_num_threads(), cull)
    return img, mask, zbuf


@nb.njit(cache=True, nogil=True)
def _draw_shaded(img, verts, tris, base, cull):
    """The mesh ``verts [V, 3]`` (camera pixels, +y up, +z to the viewer) shaded as
    :func:`anima.render.face.shade` (Lambert + ambient, light from the camera) and drawn over ``img [H, W, 3]``
    uint8 in place: the same pixels as ``compose(raster_mesh(...), inplace=True)``, with no Python between
    the steps (the avatar preview draws two heads a frame). Triangles with a non-finite vertex are skipped."""
    H, W = img.shape[0], img.shape[1]
    nv = verts.shape[0]
    finite = np.empty(nv, np.bool_)
    lo_u, lo_v, hi_u, hi_v = np.inf, np.inf, -np.inf, -np.inf
    for v in range(nv):
        finite[v] = np.isfinite(verts[v, 0]) and np.isfinite(verts[v, 1]) and np.isfinite(verts[v, 2])
        if finite[v]:
            lo_u, hi_u = min(lo_u, verts[v, 0]), max(hi_u, verts[v, 0])
            lo_v, hi_v = min(lo_v, -verts[v, 1]), max(hi_v, -verts[v, 1])
    if not np.isfinite(lo_u):
        return
    x0, y0 = max(int(np.floor(lo_u)), 0), max(int(np.floor(lo_v)), 0)
    x1, y1 = min(int(np.ceil(hi_u)) + 1, W), min(int(np.ceil(hi_v)) + 1, H)
    if x1 <= x0 or y1 <= y0:
        return
    keep = np.empty(tris.shape[0], np.bool_)
    for t in range(tris.shape[0]):
        keep[t] = finite[tris[t, 0]] and finite[tris[t, 1]] and finite[tris[t, 2]]
    tk = tris[keep]
    n = np.zeros((nv, 3))
    _normals(verts, tk, n)
    _normalize_rows(n)
    colors = np.empty((nv, 3), np.float32)
    uvz = np.empty((nv, 3))
    for v in range(nv):
        lam = min(max(n[v, 2], 0.0), 1.0)
        for c in range(3):
            colors[v, c] = (0.25 + 0.75 * lam) * base[v, c]
        uvz[v, 0], uvz[v, 1], uvz[v, 2] = verts[v, 0] - x0, -verts[v, 1] - y0, verts[v, 2]
    h, w = y1 - y0, x1 - x0
    col = np.zeros((h, w, 3), np.float32)
    zbuf = np.full((h, w), -np.inf)
    mask = np.zeros((h, w), np.bool_)
    _raster(uvz, tk, colors, col, zbuf, mask, 0, h, cull)
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                for c in range(3):
                    img[y0 + y, x0 + x, c] = np.uint8(col[y, x, c] * np.float32(255))


@nb.njit(cache=True, nogil=True)
def _normals(verts, tris, out):
    for t in range(tris.shape[0]):
        a, b, c = tris[t, 0], tris[t, 1], tris[t, 2]
        e1x, e1y, e1z = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
        e2x, e2y, e2z = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        for v in (a, b, c):
            out[v, 0] += nx
            out[v, 1] += ny
            out[v, 2] += nz


@nb.njit(cache=True, nogil=True)
def _normalize_rows(out):
    for v in range(out.shape[0]):
        n = np.sqrt(out[v, 0] ** 2 + out[v, 1] ** 2 + out[v, 2] ** 2)
        n = max(n, 1e-12)
        out[v, 0] /= n
        out[v, 1] /= n
        out[v, 2] /= n


def draw_shaded(img: np.ndarray, verts_cam: np.ndarray, tris: np.ndarray, base: np.ndarray, back_faces: bool = True):
    """Draw ``verts_cam`` (camera pixels, +y up) as a Lambert-shaded mesh of colour ``base`` (RGB in [0, 1]: one
    colour, or one per vertex ``[V, 3]``) over the uint8 image ``img`` in place (a view into a larger canvas
    works); see :func:`_draw_shaded`."""
    base = np.asarray(base, np.float32)
    if base.ndim == 1:
        base = np.broadcast_to(base, (len(verts_cam), 3))
    _draw_shaded(
        img,
        np.ascontiguousarray(verts_cam, np.float64),
        np.ascontiguousarray(tris, np.int64),
        np.ascontiguousarray(base, np.float32),
        0.0 if back_faces else BACK,
    )
    return img


def vertex_normals(verts: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``[V, 3]``."""
    out = np.zeros(verts.shape, np.float64)
    _normals(np.ascontiguousarray(verts, np.float64), np.ascontiguousarray(tris, np.int64), out)
    _normalize_rows(out)
    return out
