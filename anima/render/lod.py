"""Level of detail for small renders: a mesh with morph targets decimated by quadric edge collapse
(fast-simplification, Garland & Heckbert). A 22k-triangle head drawn 90 pixels tall has several triangles
per pixel; the rasterizer's cost is per triangle, so previews draw a decimated copy. Pure function, no I/O."""

from __future__ import annotations

import numpy as np


def cluster_mean(verts: np.ndarray, tris: np.ndarray, max_triangles: int):
    """Quadric edge collapse of the mesh ``(verts [V, 3], tris [T, 3])`` to at most about ``max_triangles``
    triangles, as ``(A, new_tris)``: ``A`` a sparse ``[n, V]`` matrix whose row ``i`` averages the original
    vertices collapsed into new vertex ``i`` (so ``A @ X`` decimates any per-vertex array ``X``: a posed copy of
    the mesh, its colours, a morph target), ``new_tris [t, 3]`` indices into the ``n`` new vertices."""
    import fast_simplification
    from scipy.sparse import csr_matrix

    pts = np.ascontiguousarray(verts, np.float64)
    tri32 = np.ascontiguousarray(tris, np.int32)
    reduction = max(0.0, 1.0 - max_triangles / max(len(tri32), 1))
    _, _, collapses = fast_simplification.simplify(pts, tri32, target_reduction=reduction, return_collapses=True)
    _, new_tris, mapping = fast_simplification.replay_simplification(pts, tri32, collapses)
    n = int(new_tris.max()) + 1 if len(new_tris) else 0
    src = np.flatnonzero(mapping >= 0)  # vertices on no triangle map to -1
    dst = mapping[src]
    counts = np.maximum(np.bincount(dst, minlength=n), 1)
    A = csr_matrix((1.0 / counts[dst], (dst, src)), shape=(n, len(pts)))
    return A, np.asarray(new_tris, np.int64)


def decimate_morph_mesh(
    verts: np.ndarray, tris: np.ndarray, deltas: np.ndarray, max_triangles: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(verts [V, 3], tris [T, 3], deltas [E, V, 3])`` -> the same with at most about ``max_triangles``
    triangles. Each kept vertex is the mean of the original vertices collapsed into it, at rest and in every
    morph target, so the decimated mesh at any weights is the cluster mean of the original mesh at those
    weights (blendshapes stay linear). Returns the input unchanged when it is already small enough."""
    tris = np.asarray(tris)
    if len(tris) <= max_triangles:
        return verts, tris, deltas
    pts = np.ascontiguousarray(verts, np.float64)
    A, new_tris = cluster_mean(pts, tris, max_triangles)
    d = np.asarray(deltas)
    E, n = len(d), A.shape[0]
    stacked = np.concatenate([pts, d.transpose(1, 0, 2).reshape(len(pts), E * 3)], 1)  # [V, 3 + 3E]
    mean = np.asarray(A @ stacked)
    new_verts = mean[:, :3].astype(np.asarray(verts).dtype)
    new_deltas = mean[:, 3:].reshape(n, E, 3).transpose(1, 0, 2).astype(d.dtype)
    return new_verts, new_tris, np.ascontiguousarray(new_deltas)
