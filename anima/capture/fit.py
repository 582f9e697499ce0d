"""Fit the ICT face model to MediaPipe landmarks: identity per clip, pose + camera + 53 expressions per frame.

Observation model (conventions in ``anima.core``): MediaPipe landmark k of frame f, in camera-space pixels
``P[f, k] = (x W, -y H, -z W)``, is explained by the ICT surface point ``L_k(id, e)`` (barycentric point of
the dense correspondence) under a scaled-orthographic camera: ``P ~ s R L + t``.

Objective per frame (all in model units, cm, so that it does not depend on image size):

    E(e) = sum_k | W_f (Q_fk - L_k(id, e)) |^2 + lam2 |e|^2 + lam1 sum(e),   0 <= e <= 1,
    Q_fk = R_f^T (P_fk - t_f) / s_f,   W_f = R_f^T diag(1, 1, z_weight) R_f,

i.e. image-plane x/y residuals at full weight and MediaPipe's (less reliable) depth at ``z_weight``.
Because ``W_f`` only depends on the view direction, the normal matrix is
``sum_{c,c'} M_f[c,c'] G[c,c']`` with ``G`` precomputed once: a frame's 53x53 system costs ~25k flops.
The bounded problem is solved by batched accelerated projected gradient (FISTA) over all frames at once.
Pose (s, R, t) is a closed-form weighted Umeyama alignment. Pose and expression alternate a few times.

Identity: from ``n_keyframes`` frames spread over the clip (preferring frontal ones), alternating pose,
expressions and a ridge solve of the 100 identity coefficients with Huber-reweighted landmarks (robust to
a bad keyframe or a badly tracked landmark).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba as nb
import numpy as np

from anima.capture.config import FitConfig
from anima.core.camera import camera_to_image, umeyama
from anima.core.rotations import matrix_to_euler
from anima.facemodel.correspondence import Correspondence
from anima.facemodel.ict import FaceModel
from anima.facemodel.reader import ExpressionReader, landmark_offsets

_BASIS_CACHE: dict = {}


@dataclass
class LandmarkBasis:
    """The face model evaluated only at the corresponded landmarks."""

    index: np.ndarray  # (K,) indices into MediaPipe's 478 landmarks
    mean: np.ndarray  # (K, 3)
    ident: np.ndarray  # (K, 3, 100)
    expr: np.ndarray  # (K, 3, 53)
    G: np.ndarray  # (3, 3, 53, 53): sum_k expr[k, c]^T expr[k, c']
    outer_eyes: tuple[int, int]  # positions in `index` of landmarks 33 and 263 (inter-ocular distance)

    @classmethod
    def build(cls, model: FaceModel, corr: Correspondence, use_iris: bool = True) -> LandmarkBasis:
        key = (id(model), id(corr), use_iris)
        if key not in _BASIS_CACHE:
            _BASIS_CACHE[key] = cls._build(model, corr, use_iris)
        return _BASIS_CACHE[key]

    @classmethod
    def _build(cls, model: FaceModel, corr: Correspondence, use_iris: bool) -> LandmarkBasis:
        keep = corr.valid.copy()
        if not use_iris:
            keep[468:] = False
        index = np.flatnonzero(keep)
        ids, bary = corr.vertex_ids[index], corr.bary[index].astype(np.float64)

        def gather(B):  # (n, V, 3) -> (K, 3, n)
            return np.einsum("nkcd,kc->kdn", B[:, ids].astype(np.float64), bary)

        mean = np.einsum("kcd,kc->kd", model.neutral[ids].astype(np.float64), bary)
        expr = gather(model.expr_deltas)
        G = np.einsum("kci,kdj->cdij", expr, expr)
        pos = {int(v): i for i, v in enumerate(index)}
        return cls(index, mean, gather(model.id_deltas), expr, G, (pos[33], pos[263]))

    def shape(self, identity: np.ndarray | None) -> np.ndarray:
        return self.mean if identity is None else self.mean + self.ident @ identity

    def points(self, identity: np.ndarray | None, expr: np.ndarray) -> np.ndarray:
        """``[F, 53]`` -> landmark positions in model space ``[F, K, 3]``."""
        K = self.mean.shape[0]
        return self.shape(identity)[None] + (expr @ self.expr.reshape(K * 3, -1).T).reshape(len(expr), K, 3)


@dataclass
class FrameFit:
    scale: np.ndarray  # (F,) pixels per cm
    R: np.ndarray  # (F, 3, 3)
    t: np.ndarray  # (F, 3) pixels
    expr: np.ndarray  # (F, 53)
    err_px: np.ndarray = field(default=None)  # (F,) mean 2D landmark error
    nme: np.ndarray = field(default=None)  # (F,) err_px / sqrt(bbox area of the landmarks)


def _weight_matrices(R: np.ndarray, z_weight: float) -> np.ndarray:
    """``M_f = R^T diag(1, 1, z_weight^2) R`` = I - (1 - z_weight^2) r3 r3^T."""
    r3 = R[:, 2, :]
    return np.eye(3)[None] - (1 - z_weight**2) * r3[:, :, None] * r3[:, None, :]


@nb.njit(cache=True, parallel=True, fastmath=False, nogil=True)
def _box_qp_gauss_seidel(N, g, x, sweeps, tol):
    """Projected Gauss-Seidel (coordinate descent) for min 1/2 x'Nx - g'x, 0 <= x <= 1, per frame.
    Exact minimisation along each coordinate; converges for SPD N. Warm-started from x (in place)."""
    F, n = g.shape
    for f in nb.prange(F):
        Nf = N[f]
        grad = np.empty(n)
        for i in range(n):
            acc = -g[f, i]
            for j in range(n):
                acc += Nf[i, j] * x[f, j]
            grad[i] = acc
        for _ in range(sweeps):
            change = 0.0
            for i in range(n):
                xi = x[f, i]
                new = xi - grad[i] / Nf[i, i]
                new = 0.0 if new < 0.0 else (1.0 if new > 1.0 else new)
                d = new - xi
                if d != 0.0:
                    x[f, i] = new
                    for j in range(n):
                        grad[j] += Nf[j, i] * d
                    if abs(d) > change:
                        change = abs(d)
            if change < tol:
                break
    return x


def solve_expression(
    Q: np.ndarray, base: np.ndarray, basis: LandmarkBasis, M: np.ndarray, cfg: FitConfig, e0: np.ndarray | None = None
) -> np.ndarray:
    """Bounded least squares for expression weights, batched over frames.

    Q ``[F, K, 3]`` observations in model space, base ``[K, 3]`` identity shape, M ``[F, 3, 3]`` weight
    matrices. Returns ``[F, 53]`` in [0, 1].

    Solver: projected Gauss-Seidel (exact coordinate descent with clamping) in numba, one frame per
    thread, warm-started from the previous alternation; stops when no weight moves by more than 1e-5.
    The problem is a strictly convex QP, so it converges to the unique minimum.
    """
    F, n = Q.shape[0], basis.expr.shape[-1]
    K = Q.shape[1]
    N = (M.reshape(F, 9) @ basis.G.reshape(9, n * n)).reshape(F, n, n) + cfg.lam_expr * np.eye(n)[None]
    MD = (Q - base[None]) @ M  # M is symmetric: row k of (D M) = M D_k
    g = MD.reshape(F, K * 3) @ basis.expr.reshape(K * 3, n) - cfg.lam_expr_l1
    x = np.zeros((F, n)) if e0 is None else np.clip(e0, 0.0, 1.0).astype(np.float64)
    return _box_qp_gauss_seidel(
        np.ascontiguousarray(N), np.ascontiguousarray(g), np.ascontiguousarray(x), cfg.qp_sweeps, 1e-5
    )


def to_model_space(P: np.ndarray, scale, R, t) -> np.ndarray:
    return ((P - t[:, None]) @ R) / scale[:, None, None]


def fit_frames(
    P: np.ndarray, basis: LandmarkBasis, identity: np.ndarray | None, cfg: FitConfig, e0: np.ndarray | None = None
) -> FrameFit:
    """Pose + expression for frames ``P [F, K, 3]`` (camera-space pixels of ``basis.index``)."""
    base = basis.shape(identity)
    F = P.shape[0]
    expr = np.zeros((F, basis.expr.shape[-1])) if e0 is None else e0.copy()
    wz = np.ones(P.shape[:2])
    for _ in range(cfg.n_alternations):
        V = basis.points(identity, expr)
        s, R, t = umeyama(V, P, wz)
        M = _weight_matrices(R, cfg.z_weight)
        Q = to_model_space(P, s, R, t)
        expr = solve_expression(Q, base, basis, M, cfg, expr)
    V = basis.points(identity, expr)
    s, R, t = umeyama(V, P, wz)
    fit = FrameFit(s, R, t, expr)
    fit.err_px, fit.nme = landmark_error(P, V, s, R, t)
    return fit


def landmark_error(P: np.ndarray, V: np.ndarray, s, R, t):
    """Mean 2D error (px) between observed and fitted landmarks, and NME by sqrt(bbox area)."""
    X = s[:, None, None] * (V @ R.transpose(0, 2, 1)) + t[:, None]
    e = np.linalg.norm(camera_to_image(X) - camera_to_image(P), axis=-1).mean(1)
    uv = camera_to_image(P)
    wh = uv.max(1) - uv.min(1)
    return e, e / np.sqrt(np.maximum(wh[:, 0] * wh[:, 1], 1e-9))


def choose_keyframes(P: np.ndarray, basis: LandmarkBasis, n: int) -> np.ndarray:
    """Up to ``n`` frames spread over the clip, each the most frontal of its time slice."""
    F = P.shape[0]
    s, R, t = umeyama(np.broadcast_to(basis.mean, P.shape), P)
    yaw_pitch = np.abs(matrix_to_euler(R)[:, :2]).sum(1)
    bins = np.array_split(np.arange(F), min(n, F))
    return np.array([b[np.argmin(yaw_pitch[b])] for b in bins if len(b)])


def fit_identity(P: np.ndarray, basis: LandmarkBasis, cfg: FitConfig, n_rounds: int = 2) -> np.ndarray:
    """Identity coefficients ``[100]`` from keyframes ``P [J, K, 3]`` (IRLS with Huber weights)."""
    J, K, _ = P.shape
    n_id = basis.ident.shape[-1]
    identity = np.zeros(n_id)
    expr = None
    for _ in range(n_rounds):
        fit = fit_frames(P, basis, identity, cfg, e0=expr)
        expr = fit.expr
        Q = to_model_space(P, fit.scale, fit.R, fit.t)
        R = fit.R
        # residual in camera axes (model units): W R (Q - mean - Id id - E e)
        target = Q - basis.points(None, fit.expr)  # (J, K, 3), model space
        M = _weight_matrices(R, cfg.z_weight)  # (J, 3, 3) = R^T W^2 R
        resid = target - basis.ident @ identity  # (J, K, 3)
        r = np.sqrt(np.einsum("jkc,jcd,jkd->jk", resid, M, resid))
        w = np.where(r <= cfg.huber_cm, 1.0, cfg.huber_cm / np.maximum(r, 1e-12))  # (J, K)
        # normal equations sum_jk w_jk Id_k^T M_j Id_k without forming the (J*K*3, 100) matrix
        Wk = np.einsum("jk,jcd->kcd", w, M)  # (K, 3, 3)
        B = Wk @ basis.ident  # (K, 3, 100)
        lhs = basis.ident.reshape(-1, n_id).T @ B.reshape(-1, n_id)
        rhs = basis.ident.reshape(-1, n_id).T @ np.einsum("jk,jcd,jkd->kc", w, M, target).reshape(-1)
        identity = np.linalg.solve(lhs + cfg.lam_id * J * np.eye(n_id), rhs)
    return identity


def read_expression(P: np.ndarray, fit: FrameFit, basis: LandmarkBasis, identity: np.ndarray,
                    reader: ExpressionReader | None) -> np.ndarray:  # fmt: skip
    """The frames' weights ``[F, 53]`` as ``reader`` reads the landmarks ``P`` posed by ``fit`` (its channels; the
    others, the gaze, stay the fit's); the fit's own weights where ``reader`` is None."""
    if reader is None:
        return fit.expr
    D = landmark_offsets(to_model_space(P, fit.scale, fit.R, fit.t), basis.index, basis.shape(identity))
    out = np.array(fit.expr, copy=True)
    out[:, reader.channels] = reader(D)
    return out
