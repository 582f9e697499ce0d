"""Kinematics of a joint tree, in one place (pure functions): forward kinematics, local and global rotations,
aiming a bone, fitting a rotation to point sets (Kabsch) and two-bone IK.

Convention: a skeleton is ``parents [J]`` (-1 for a root; parents precede children) and ``offsets [J, 3]``
(a joint's rest position minus its parent's). A global rotation ``G_j`` maps a bone's rest-pose vector to the
current one; the local rotation is ``L_j = G_parent^-1 G_j``; forward kinematics places a child at
``p_child = p_j + G_j @ offset_child``.
"""

from __future__ import annotations

import numpy as np


def unit(v: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """``v [..., 3]`` over its length (lengths under ``eps`` count as ``eps``)."""
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), eps)


# ---- rotation fitting -----------------------------------------------------------------------------------------


def kabsch(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Rotations R ``[F, 3, 3]`` minimising sum |R a_i - b_i|^2 for A, B ``[F, n, 3]``."""
    H = A.transpose(0, 2, 1) @ B
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.transpose(0, 2, 1) @ U.transpose(0, 2, 1)))
    D = np.ones((len(A), 3))
    D[:, 2] = d
    return Vt.transpose(0, 2, 1) @ (D[:, :, None] * U.transpose(0, 2, 1))


def min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vectors a to b, batched ``[F, 3]`` -> ``[F, 3, 3]``."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    v = np.cross(a, b)
    c = (a * b).sum(-1)
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    f = 1.0 / np.maximum(1.0 + c, 1e-9)
    R = np.eye(3) + K + (K @ K) * f[..., None, None]
    # opposite vectors: rotate pi about any axis orthogonal to a
    opp = c < -1 + 1e-9
    if opp.any():
        axis = np.cross(a[opp], np.array([1.0, 0.0, 0.0]))
        small = np.linalg.norm(axis, axis=-1) < 1e-6
        axis[small] = np.cross(a[opp][small], np.array([0.0, 1.0, 0.0]))
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        R[opp] = 2 * axis[:, :, None] * axis[:, None, :] - np.eye(3)
    return R


def aim(parent_G: np.ndarray, rest_vec: np.ndarray, target_vec: np.ndarray) -> np.ndarray:
    """The parent's rotation ``[F, 3, 3]`` followed by the smallest rotation that points ``rest_vec`` (carried
    by the parent) along ``target_vec [F, 3]`` (the bone keeps its parent's twist). NaN where the target is
    unseen."""
    cur = np.einsum("fij,j->fi", parent_G, rest_vec)
    G = min_rotation(cur, target_vec) @ parent_G
    G[~np.isfinite(target_vec).all(-1)] = np.nan
    return G


def fit_rotation(rest_vecs: np.ndarray, target_vecs: np.ndarray) -> np.ndarray:
    """Best rigid rotation ``[F, 3, 3]`` of the rest vectors ``[n, 3]`` onto the targets ``[F, n, 3]`` (both
    made unit: every direction weighs the same); NaN where a target is unseen."""
    ok = np.isfinite(target_vecs).all((-1, -2))
    A = np.broadcast_to(unit(rest_vecs), target_vecs.shape)
    G = np.full(target_vecs.shape[:1] + (3, 3), np.nan)
    if ok.any():
        G[ok] = kabsch(A[ok], unit(target_vecs[ok]))
    return G


# ---- forward and inverse kinematics -----------------------------------------------------------------------------


def parents_first(parents: np.ndarray) -> list[int]:
    """Joint (or node) indices with every parent before its children (breadth first from the roots: linear
    time, no recursion; the hierarchy must be a forest)."""
    kids: dict[int, list[int]] = {}
    for i, p in enumerate(parents):
        kids.setdefault(int(p), []).append(i)
    out = list(kids.get(-1, []))
    k = 0
    while k < len(out):
        out.extend(kids.get(out[k], []))
        k += 1
    return out


def forward(
    L: np.ndarray, parents: np.ndarray, offsets: np.ndarray, root: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations ``[F, J, 3, 3]`` and positions ``[F, J, 3]`` of local rotations ``L [F, J, 3, 3]``
    (parents precede children). ``offsets``: ``[J, 3]``, or ``[F, J, 3]`` where they change with the frame (a
    BVH's position channels). A root joint sits at ``root [F, 3]``, or at its own offset when ``root`` is None."""
    G = np.empty_like(L)
    P = np.empty(L.shape[:2] + (3,))
    per_frame = np.ndim(offsets) == 3
    for j in range(L.shape[1]):
        p = parents[j]
        off = offsets[:, j] if per_frame else offsets[j]
        if p < 0:
            G[:, j] = L[:, j]
            P[:, j] = off if root is None else root
        else:
            G[:, j] = G[:, p] @ L[:, j]
            P[:, j] = P[:, p] + np.einsum("fij,fj->fi" if per_frame else "fij,j->fi", G[:, p], off)
    return G, P


def local_rotations(G: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Local rotations ``[F, J, 3, 3]`` of global ones (a root's local is its global)."""
    L = G.copy()
    for j in range(G.shape[1]):
        if parents[j] >= 0:
            L[:, j] = G[:, parents[j]].transpose(0, 2, 1) @ G[:, j]
    return L


def positions_to_rotations(P: np.ndarray, parents: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Global rotations ``[F, J, 3, 3]`` that pose the rest skeleton (``offsets [J, 3]``) like positions ``P
    [F, J, 3]``. Joints with several children: best rigid fit of their child bones (Kabsch); one child: the
    parent's rotation followed by the smallest rotation aligning the bone (stable twist); no child: the
    parent's rotation."""
    F, J, _ = P.shape
    G = np.tile(np.eye(3), (F, J, 1, 1))
    kids = [np.flatnonzero(parents == j) for j in range(J)]
    for j in range(J):  # parents precede children
        base = G[:, parents[j]] if parents[j] >= 0 else np.tile(np.eye(3), (F, 1, 1))
        c = kids[j]
        c = c[np.linalg.norm(offsets[c], axis=-1) > 1e-9] if len(c) else c
        if len(c) == 0:
            G[:, j] = base
        elif len(c) == 1:
            rest = base @ offsets[c[0]]
            G[:, j] = min_rotation(rest, P[:, c[0]] - P[:, j]) @ base
        else:
            A = np.broadcast_to(offsets[c], (F, len(c), 3))
            G[:, j] = kabsch(A, P[:, c] - P[:, j][:, None])
    return G


def two_bone(hip: np.ndarray, target: np.ndarray, a: float, b: float, pole: np.ndarray) -> np.ndarray:
    """Middle-joint positions ``[F, 3]`` (a knee, an elbow) of a two-bone chain of lengths ``a`` (thigh) and
    ``b`` (shin) from ``hip`` reaching for ``target`` (clamped to the reachable range) with the middle joint
    bending towards ``pole`` (``[F, 3]``; its part along the chain is ignored)."""
    d = target - hip
    n = np.linalg.norm(d, axis=-1)
    n_c = np.clip(n, abs(a - b) + 1e-4, a + b - 1e-4)
    u = d / np.maximum(n, 1e-9)[:, None]
    x = (a * a - b * b + n_c * n_c) / (2 * n_c)
    h = np.sqrt(np.maximum(a * a - x * x, 0.0))
    side = unit(pole - (pole * u).sum(-1, keepdims=True) * u)
    return hip + u * x[:, None] + side * h[:, None]


def forward_kinematics(
    L: np.ndarray, parents: np.ndarray, offsets: np.ndarray, root_pos: np.ndarray | None = None
) -> np.ndarray:
    """Positions ``[F, J, 3]`` of local rotations ``[F, J, 3, 3]`` as BVH places them: a root joint at its own
    offset moved by ``root_pos [F, 3]`` (the root's channels)."""
    if root_pos is None:
        return forward(L, parents, offsets)[1]
    roots = np.flatnonzero(np.asarray(parents) < 0)
    if len(roots) == 1:
        return forward(L, parents, offsets, offsets[roots[0]] + root_pos)[1]
    return forward(L, parents, offsets)[1] + np.asarray(root_pos)[:, None]
