"""Geometry, rasterization and blending of the re-enacted region (seed 001 §3.3-3.4). Pure functions on
arrays, no I/O."""

from __future__ import annotations

import time

import cv2
import numpy as np

from anima.render.raster import rasterize


def posed_uvz(V: np.ndarray, scale: float, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Model vertices (cm) -> image ``(u, v, depth)`` under the weak-perspective camera (depth: larger is
    closer, as the rasterizer expects)."""
    X = scale * V @ R.T + t
    return np.stack([X[:, 0], -X[:, 1], X[:, 2]], -1)


def visible_vertices(uvz: np.ndarray, tris: np.ndarray, eps: float = 1.0) -> np.ndarray:
    """Which vertices the z-buffer shows: ``(V,)`` bool, a vertex being visible where its depth is within
    ``eps`` (depth units = pixels) of the nearest surface at one of the four pixels around it. Rasterizes the
    region's box only."""
    uv = uvz[:, :2]
    if not np.isfinite(uvz).all():
        return np.zeros(len(uvz), bool)
    x0, y0 = np.floor(uv.min(0)).astype(int) - 1
    w, h = (np.ceil(uv.max(0)).astype(int) + 2 - (x0, y0)).tolist()
    local = uvz - np.array([x0, y0, 0.0])
    _, mask, zbuf = rasterize(local, tris, np.zeros((len(uvz), 1), np.float32), (w, h))
    # the four pixels whose centres surround the vertex (its bilinear footprint): a vertex on a pixel edge
    # or corner is judged by the surface drawn next to it
    vis = np.zeros(len(uvz), bool)
    x0 = np.floor(local[:, 0] - 0.5).astype(int)
    y0 = np.floor(local[:, 1] - 0.5).astype(int)
    for dx in (0, 1):
        for dy in (0, 1):
            px, py = np.clip(x0 + dx, 0, w - 1), np.clip(y0 + dy, 0, h - 1)
            vis |= mask[py, px] & (local[:, 2] >= zbuf[py, px] - eps)
    return vis


def bbox(uv: np.ndarray, size: tuple[int, int], pad: int, align: int) -> tuple[int, int, int, int]:
    """Integer box around ``uv`` padded by ``pad`` px, clipped to the image, with width and height rounded
    up to a multiple of ``align`` where the image allows (pyramid levels)."""
    W, H = size
    x0, y0 = np.floor(uv.min(0)).astype(int) - pad
    x1, y1 = np.ceil(uv.max(0)).astype(int) + pad
    x0, y0 = max(x0, 0), max(y0, 0)
    x1, y1 = min(x1, W), min(y1, H)
    w = min(-(-(x1 - x0) // align) * align, W)
    h = min(-(-(y1 - y0) // align) * align, H)
    x0, y0 = min(x0, W - w), min(y0, H - h)
    return int(x0), int(y0), int(w), int(h)


def render_region(uvz: np.ndarray, tris: np.ndarray, colors: np.ndarray, box) -> tuple[np.ndarray, np.ndarray]:
    """Rasterize the region into the crop ``box`` = (x0, y0, w, h): RGB float32 and coverage mask."""
    x0, y0, w, h = box
    local = uvz - np.array([x0, y0, 0.0])
    img, mask, _ = rasterize(local, tris, colors, (w, h))
    return img, mask


def feather(mask: np.ndarray, erode_px: int, blur_px: int) -> np.ndarray:
    """Soft blending mask in [0, 1]: the coverage eroded (keeps the seam off the region's border) and
    blurred."""
    m = mask.astype(np.uint8)
    if erode_px > 0:
        m = cv2.erode(m, np.ones((2 * erode_px + 1, 2 * erode_px + 1), np.uint8))
    m = m.astype(np.float32)
    if blur_px > 0:
        k = 2 * blur_px + 1
        m = cv2.GaussianBlur(m, (k, k), blur_px / 2)
    return m


def laplacian_blend(a: np.ndarray, b: np.ndarray, mask: np.ndarray, levels: int) -> np.ndarray:
    """Laplacian pyramid blend (Burt & Adelson; seed §3.4): ``mask`` = 1 takes ``a``, 0 takes ``b``. Images
    float32 (H, W, 3); H and W divisible by 2**levels for exact reconstruction."""
    return b + laplacian_blend_delta(a - b, mask, levels)


def laplacian_blend_delta(d: np.ndarray, mask: np.ndarray, levels: int) -> np.ndarray:
    """The change a Laplacian blend makes to ``b`` given ``d = a - b``: collapse(L(d) * G(mask)).

    The pyramid is linear, so L(a) G(m) + L(b) (1 - G(m)) = L(b) + L(d) G(m), and collapsing L(b) gives
    ``b`` back exactly: one pyramid instead of two (the blend's cost halves; same result up to float
    rounding)."""
    gd, gm = [d], [mask[..., None] if mask.ndim == 2 else mask]
    for _ in range(levels):
        gd.append(cv2.pyrDown(gd[-1]))
        m = cv2.pyrDown(gm[-1])
        gm.append(m[..., None] if m.ndim == 2 else m)
    out = gd[-1] * gm[-1]
    for i in range(levels - 1, -1, -1):
        size = (gd[i].shape[1], gd[i].shape[0])
        out = cv2.pyrUp(out, dstsize=size) + (gd[i] - cv2.pyrUp(gd[i + 1], dstsize=size)) * gm[i]
    return out


def composite(
    target: np.ndarray,
    uvz: np.ndarray,
    tris: np.ndarray,
    colors: np.ndarray,
    levels: int = 4,
    erode: float = 0.04,
    blur: float = 0.10,
    alpha: float = 1.0,
    times: dict | None = None,
) -> np.ndarray:
    """Render the region with ``colors`` (V, 3, 0..255) and blend it into ``target`` (uint8 RGB) within the
    face box only. The mask is eroded by ``erode`` and feathered by ``blur`` times the region's height
    (scale-free: the same look at any resolution). ``alpha`` scales the mask (fading to the target's own
    frame)."""
    H, W = target.shape[:2]
    if alpha <= 0 or not np.isfinite(uvz).all():
        return target
    rh = float(np.ptp(uvz[:, 1]))
    erode_px, blur_px = max(1, int(round(erode * rh))), max(2, int(round(blur * rh)))
    align = 2**levels
    box = bbox(uvz[:, :2], (W, H), pad=blur_px + 2 * align, align=align)
    x0, y0, w, h = box
    if w < align or h < align:
        return target
    t0 = time.perf_counter()
    img, mask = render_region(uvz, tris, colors.astype(np.float32), box)
    t1 = time.perf_counter()
    m = feather(mask, erode_px, blur_px) * float(alpha)
    crop = target[y0 : y0 + h, x0 : x0 + w].astype(np.float32)
    # the rendered region minus the target, 0 outside the coverage (no black to bleed through the pyramid)
    d = np.zeros_like(crop)
    cv2.subtract(img, crop, dst=d, mask=mask.view(np.uint8))
    lv = levels if (w % align == 0 and h % align == 0) else 0
    out = crop + (laplacian_blend_delta(d, m, lv) if lv else d * m[..., None])
    res = target.copy()
    res[y0 : y0 + h, x0 : x0 + w] = np.clip(out, 0, 255).astype(np.uint8)
    if times is not None:
        times.setdefault("raster_ms", []).append(1e3 * (t1 - t0))
        times.setdefault("blend_ms", []).append(1e3 * (time.perf_counter() - t1))
    return res
