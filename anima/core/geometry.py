"""Mesh geometry helpers on arrays: closest points on triangles and on meshes."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def closest_point_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Closest point to ``p`` on triangles ``(a, b, c)``, all ``[..., 3]`` (Ericson, Real-Time Collision
    Detection §5.1.5). Returns barycentric weights ``[..., 3]`` and distance ``[...]``."""
    ab, ac, ap = b - a, c - a, p - a
    d1 = (ab * ap).sum(-1)
    d2 = (ac * ap).sum(-1)
    bp = p - b
    d3 = (ab * bp).sum(-1)
    d4 = (ac * bp).sum(-1)
    cp = p - c
    d5 = (ab * cp).sum(-1)
    d6 = (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    denom = np.where(np.abs(denom) < 1e-20, 1e-20, denom)
    v = vb / denom
    w = vc / denom
    bary = np.stack([1 - v - w, v, w], -1)

    def setb(mask, val):
        nonlocal bary
        bary = np.where(mask[..., None], val, bary)

    # edge regions (order matters: later assignments win for vertex regions)
    e_bc = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
    wbc = (d4 - d3) / np.where((d4 - d3) + (d5 - d6) == 0, 1, (d4 - d3) + (d5 - d6))
    setb(e_bc, np.stack([np.zeros_like(wbc), 1 - wbc, wbc], -1))
    e_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    wac = d2 / np.where(d2 - d6 == 0, 1, d2 - d6)
    setb(e_ac, np.stack([1 - wac, np.zeros_like(wac), wac], -1))
    e_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    vab = d1 / np.where(d1 - d3 == 0, 1, d1 - d3)
    setb(e_ab, np.stack([1 - vab, vab, np.zeros_like(vab)], -1))
    one = np.ones_like(d1)
    zero = np.zeros_like(d1)
    setb((d6 >= 0) & (d5 <= d6), np.stack([zero, zero, one], -1))
    setb((d3 >= 0) & (d4 <= d3), np.stack([zero, one, zero], -1))
    setb((d1 <= 0) & (d2 <= 0), np.stack([one, zero, zero], -1))
    q = bary[..., 0:1] * a + bary[..., 1:2] * b + bary[..., 2:3] * c
    return bary, np.linalg.norm(p - q, axis=-1)


def closest_points_on_mesh(points: np.ndarray, verts: np.ndarray, tris: np.ndarray, k: int = 8):
    """Closest surface point of ``verts/tris`` to each of ``points [Q, 3]``, searching the triangles
    incident to the ``k`` nearest vertices. Returns (vertex ids ``[Q, 3]``, barycentrics ``[Q, 3]``,
    distances ``[Q]``)."""
    used = np.unique(tris)
    tree = cKDTree(verts[used])
    _, near = tree.query(points, k=min(k, len(used)))
    near = used[np.atleast_2d(near)]
    # vertex -> incident triangles (CSR)
    order = np.argsort(tris.ravel(), kind="stable")
    tri_of = order // 3
    counts = np.bincount(tris.ravel(), minlength=len(verts))
    start = np.concatenate([[0], np.cumsum(counts)])
    best_ids = np.zeros((len(points), 3), np.int64)
    best_bary = np.zeros((len(points), 3))
    best_d = np.full(len(points), np.inf)
    for q in range(len(points)):
        cand = np.unique(np.concatenate([tri_of[start[v] : start[v + 1]] for v in near[q]]))
        if len(cand) == 0:
            continue
        t = tris[cand]
        bary, d = closest_point_on_triangles(points[q][None], verts[t[:, 0]], verts[t[:, 1]], verts[t[:, 2]])
        i = int(np.argmin(d))
        best_ids[q], best_bary[q], best_d[q] = t[i], bary[i], d[i]
    return best_ids, best_bary, best_d
