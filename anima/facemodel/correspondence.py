"""Dense correspondence between MediaPipe's 478 face-mesh landmarks and the ICT-FaceKit mesh.

Each MediaPipe landmark k is a fixed point on the ICT surface: ``sum_c bary[k, c] * V[vertex_ids[k, c]]``.
Computed once by ``anima facemodel correspondence`` (see :func:`build_correspondence`) and shipped as
``anima/facemodel/data/mediapipe_ict_correspondence.npz`` (a project-made artifact, ~40 KB):

1. a MediaPipe template: MediaPipe run on real, roughly frontal portraits from the shared data, brought
   to camera space, aligned by generalised Procrustes and averaged;
2. a similarity alignment of the template to the ICT neutral mesh from 8 unambiguous anchor points
   (eye corners, nose tip, mouth corners, chin: MediaPipe 33/133/362/263/1/61/291/152 = iBUG
   36/39/42/45/30/48/54/8);
3. non-rigid ICP: alternate closest points on the ICT skin (face region; iris landmarks 468-477 on the
   ICT irises), a ridge fit of ICT identity and expression to the template, and a new similarity;
4. the final closest points (triangle corners + barycentrics), their distance, and a validity mask
   (distance <= 0.5 cm); plus the reverse map: each of ICT's 68 iBUG vertices as a barycentric point
   of MediaPipe's mesh ("raw MediaPipe, 68 points").
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from anima.core.camera import umeyama
from anima.core.geometry import closest_points_on_mesh
from anima.errors import AssetNotFound, InputError
from anima.facemodel.ict import FaceModel
from anima.io.assets import package_data
from anima.io.atomic import write_npz
from anima.track.mediapipe import face_mesh_triangles

FILENAME = "mediapipe_ict_correspondence.npz"
ANCHORS_MP = np.array([33, 133, 362, 263, 1, 61, 291, 152])
ANCHORS_IBUG = np.array([36, 39, 42, 45, 30, 48, 54, 8])
N_MESH = 468  # the first 468 are surface points; 468-477 are iris points (refine_landmarks=True)
VALID_DIST_CM = 0.5

# Default template images: real, roughly frontal faces from the shared data (paths under the data root).
DEFAULT_TEMPLATE_IMAGES = [
    f"styletalk-samples/samples/source_video/image/{n}.png"
    for n in (
        "KristiNoem",
        "Obama_clip1",
        "Obama_clip2",
        "Obama_clip3",
        "andrew_clip_1",
        "andrew_clip_2",
        "feifeili_clip1",
        "feifeili_clip2_short",
        "feifeili_clip3",
        "reagan_clip1",
    )
] + [f"liveportrait-examples/assets/examples/source/{n}.jpg" for n in ("s0", "s5", "s9", "s11", "s12", "s42")]


@dataclass(frozen=True)
class Correspondence:
    vertex_ids: np.ndarray  # (478, 3) int32 ICT vertex indices (full model)
    bary: np.ndarray  # (478, 3) float32
    dist_cm: np.ndarray  # (478,) residual of the ICP fit
    valid: np.ndarray  # (478,) bool: usable for fitting
    ibug_mp_ids: np.ndarray  # (68, 3) MediaPipe landmark indices
    ibug_mp_bary: np.ndarray  # (68, 3)
    template: np.ndarray  # (478, 3) MediaPipe template in ICT model space (cm)
    meta: dict

    def mediapipe_to_ibug68(self, lm: np.ndarray) -> np.ndarray:
        """MediaPipe landmarks ``[..., 478, D]`` -> the 68 iBUG points ``[..., 68, D]``."""
        return np.einsum("...kcd,kc->...kd", lm[..., self.ibug_mp_ids, :], self.ibug_mp_bary)

    def reverse_map(self, model: FaceModel, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Any ICT ``vertices`` as barycentric points of MediaPipe's mesh ``(ids [Q, 3], bary [Q, 3])``:
        each MediaPipe landmark's ICT surface point (on the neutral face) makes a mesh with MediaPipe's
        triangles, and each vertex is placed at its closest point on it (what :attr:`ibug_mp_ids` is for
        ICT's own 68, made with the fitted rather than the neutral face)."""
        V = model.neutral.astype(np.float64)
        P = np.einsum("kcd,kc->kd", V[self.vertex_ids[:N_MESH]], self.bary[:N_MESH].astype(np.float64))
        ids, bary, _ = closest_points_on_mesh(V[np.asarray(vertices)], P, mediapipe_triangles(), k=6)
        return ids, bary


def mediapipe_triangles() -> np.ndarray:
    """Triangles of MediaPipe's face mesh from its tessellation edges (3-cliques), ``(T, 3)``."""
    return face_mesh_triangles()


def procrustes_mean(shapes: list[np.ndarray]) -> np.ndarray:
    """Generalised-Procrustes mean of MediaPipe landmark sets in camera space ``[478, 3]`` each (the
    template of step 1; ``anima.capture.correspondence`` runs MediaPipe on the portraits)."""
    if len(shapes) < 3:
        raise InputError(f"need at least 3 faces for the template, found {len(shapes)}")
    S = np.stack(shapes)
    ref = S[0]
    for _ in range(5):
        s, R, t = umeyama(S, np.broadcast_to(ref, S.shape))
        A = s[:, None, None] * np.einsum("fij,fnj->fni", R, S) + t[:, None]
        ref = A.mean(0)
    return ref


def _fit_model_to_points(model: FaceModel, ids, bary, X, w, lam_id=1.0, lam_e=0.1):
    """Ridge fit of identity+expression so that the barycentric points match X (model space)."""

    def gather(B):  # B (n, V, 3) -> (n, Q, 3)
        return np.einsum("nqcd,qc->nqd", B[:, ids], bary)

    n0 = np.einsum("qcd,qc->qd", model.neutral[ids], bary)
    A = np.concatenate([gather(model.id_deltas), gather(model.expr_deltas)], 0)  # (153, Q, 3)
    sw = np.sqrt(w)[None, :, None]
    Am = (A * sw).reshape(A.shape[0], -1).T
    b = ((X - n0) * sw[0]).ravel()
    reg = np.concatenate([np.full(model.id_deltas.shape[0], lam_id), np.full(model.expr_deltas.shape[0], lam_e)])
    x = np.linalg.solve(Am.T @ Am + np.diag(reg), Am.T @ b)
    nid = model.id_deltas.shape[0]
    return x[:nid], np.clip(x[nid:], 0, 1)


def build_correspondence(template: np.ndarray, model: FaceModel, n_iter: int = 12) -> Correspondence:
    face = model.region("face")
    face_set = np.zeros(model.n_vertices, bool)
    face_set[face] = True
    tris_all = model.triangles()
    tris_face = tris_all[face_set[tris_all].all(1)]
    iris = np.concatenate([model.region("iris_left"), model.region("iris_right")])
    iris_set = np.zeros(model.n_vertices, bool)
    iris_set[iris] = True
    tris_iris = tris_all[iris_set[tris_all].all(1)]

    lm_v = model.neutral[model.landmarks68[ANCHORS_IBUG]]
    s, R, t = umeyama(template[None, ANCHORS_MP], lm_v[None])
    X = s[0] * template @ R[0].T + t[0]
    identity = np.zeros(model.id_deltas.shape[0])
    expr = np.zeros(model.expr_deltas.shape[0])
    for it in range(n_iter):
        V = model.vertices(identity, expr).astype(np.float64)
        ids_m, bary_m, d_m = closest_points_on_mesh(X[:N_MESH], V, tris_face)
        ids_i, bary_i, d_i = closest_points_on_mesh(X[N_MESH:], V, tris_iris)
        ids = np.concatenate([ids_m, ids_i])
        bary = np.concatenate([bary_m, bary_i])
        d = np.concatenate([d_m, d_i])
        w = 1.0 / np.maximum(1.0, d / 0.3)  # Huber-like: down-weight far points
        if it < n_iter - 1:
            identity, expr = _fit_model_to_points(model, ids, bary, X, w)
            V = model.vertices(identity, expr).astype(np.float64)
            P = np.einsum("qcd,qc->qd", V[ids], bary)
            s, R, t = umeyama(template[None], P[None], w[None])
            X = s[0] * template @ R[0].T + t[0]
    # reverse map: ICT iBUG vertices onto MediaPipe's mesh (in the aligned template)
    V = model.vertices(identity, expr).astype(np.float64)
    mp_tris = mediapipe_triangles()
    rid, rbary, rdist = closest_points_on_mesh(V[model.landmarks68], X, mp_tris, k=6)
    meta = {
        "n_iter": n_iter,
        "valid_dist_cm": VALID_DIST_CM,
        "mean_dist_cm": float(d.mean()),
        "median_dist_cm": float(np.median(d)),
        "ibug_reverse_mean_dist_cm": float(rdist.mean()),
        "fitted_identity_norm": float(np.linalg.norm(identity)),
    }
    return Correspondence(
        ids.astype(np.int32),
        bary.astype(np.float32),
        d.astype(np.float32),
        d <= VALID_DIST_CM,
        rid.astype(np.int32),
        rbary.astype(np.float32),
        X.astype(np.float32),
        meta,
    )


def save_correspondence(c: Correspondence, path: str | Path) -> None:
    write_npz(
        path,
        vertex_ids=c.vertex_ids,
        bary=c.bary,
        dist_cm=c.dist_cm,
        valid=c.valid,
        ibug_mp_ids=c.ibug_mp_ids,
        ibug_mp_bary=c.ibug_mp_bary,
        template=c.template,
        meta=np.asarray(json.dumps(c.meta)),
    )


@lru_cache(maxsize=1)
def load_correspondence(path: str | None = None) -> Correspondence:
    p = Path(path) if path else package_data(FILENAME)
    if not p.is_file():
        raise AssetNotFound(
            f"landmark correspondence not found: {p}\n  rebuild it with "
            "`anima facemodel correspondence` (see docs/face_capture.md)"
        )
    with np.load(p, allow_pickle=False) as z:
        return Correspondence(
            z["vertex_ids"],
            z["bary"],
            z["dist_cm"],
            z["valid"],
            z["ibug_mp_ids"],
            z["ibug_mp_bary"],
            z["template"],
            json.loads(str(z["meta"])),
        )
