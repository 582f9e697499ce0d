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

import numpy as np

from anima.core.camera import camera_to_image, umeyama
from anima.core.rotations import matrix_to_euler
from anima.facemodel.correspondence import Correspondence
from anima.facemodel.ict import FaceModel


@dataclass
class FitConfig:
    z_weight: float = 0.5
    """Weight of MediaPipe's depth residual relative to the image-plane residual."""
    lam_expr: float = 0.5
    """L2 regularisation of expression weights (cm^2 per unit weight^2, summed over landmarks)."""
    lam_expr_l1: float = 0.05
    """L1 (sparsity) regularisation of expression weights."""
    lam_id: float = 2.0
    """L2 regularisation of identity coefficients (PCA modes, prior N(0, 1))."""
    n_keyframes: int = 12
    """Frames used to fit the per-clip identity."""
    n_alternations: int = 4
    """Pose / expression alternations per frame."""
    qp_iters: int = 60
    """FISTA iterations of the bounded expression solve."""
    use_iris: bool = True
    """Use MediaPipe's 10 iris landmarks (468-477) for the eye-gaze shapes."""
    huber_cm: float = 0.3
    """Huber threshold (cm) of the robust identity fit."""


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
    def build(cls, model: FaceModel, corr: Correspondence, use_iris: bool = True) -> "LandmarkBasis":
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


def solve_expression(Q: np.ndarray, base: np.ndarray, basis: LandmarkBasis, M: np.ndarray, cfg: FitConfig,
                     e0: np.ndarray | None = None) -> np.ndarray:
    """Bounded least squares for expression weights, batched over frames.

    Q ``[F, K, 3]`` observations in model space, base ``[K, 3]`` identity shape, M ``[F, 3, 3]`` weight
    matrices. Returns ``[F, 53]`` in [0, 1].
    """
    F, n = Q.shape[0], basis.expr.shape[-1]
    K = Q.shape[1]
    N = (M.reshape(F, 9) @ basis.G.reshape(9, n * n)).reshape(F, n, n) + cfg.lam_expr * np.eye(n)[None]
    MD = (Q - base[None]) @ M  # M is symmetric: row k of (D M) = M D_k
    g = MD.reshape(F, K * 3) @ basis.expr.reshape(K * 3, n) - cfg.lam_expr_l1
    # Lipschitz constant: power iteration on N
    v = np.ones((F, n)) / np.sqrt(n)
    for _ in range(12):
        v = (N @ v[:, :, None])[:, :, 0]
        v /= np.linalg.norm(v, axis=1, keepdims=True) + 1e-12
    L = ((N @ v[:, :, None])[:, :, 0] * v).sum(1) * 1.05 + 1e-9
    step = (1.0 / L)[:, None]
    x = np.clip(e0, 0, 1) if e0 is not None else np.zeros((F, n))
    y, tk = x.copy(), 1.0
    for _ in range(cfg.qp_iters):
        grad = (N @ y[:, :, None])[:, :, 0] - g
        x_new = np.clip(y - step * grad, 0.0, 1.0)
        t_new = 0.5 * (1 + np.sqrt(1 + 4 * tk * tk))
        y = x_new + ((tk - 1) / t_new) * (x_new - x)
        x, tk = x_new, t_new
    return x


def to_model_space(P: np.ndarray, scale, R, t) -> np.ndarray:
    return ((P - t[:, None]) @ R) / scale[:, None, None]


def fit_frames(P: np.ndarray, basis: LandmarkBasis, identity: np.ndarray | None, cfg: FitConfig,
               e0: np.ndarray | None = None) -> FrameFit:
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


def fit_identity(P: np.ndarray, basis: LandmarkBasis, cfg: FitConfig, n_rounds: int = 4) -> np.ndarray:
    """Identity coefficients ``[100]`` from keyframes ``P [J, K, 3]`` (IRLS with Huber weights)."""
    J, K, _ = P.shape
    n_id = basis.ident.shape[-1]
    identity = np.zeros(n_id)
    W = np.diag([1.0, 1.0, cfg.z_weight])
    for _ in range(n_rounds):
        fit = fit_frames(P, basis, identity, cfg)
        Q = to_model_space(P, fit.scale, fit.R, fit.t)
        R = fit.R
        # residual in camera axes (model units): W R (Q - mean - Id id - E e)
        target = Q - basis.points(None, fit.expr)  # (J, K, 3)
        WR = W[None] @ R  # (J, 3, 3)
        A = WR[:, None] @ basis.ident[None]  # (J, K, 3, 100)
        b = target @ WR.transpose(0, 2, 1)
        r = np.linalg.norm(A @ identity - b, axis=-1)
        w = np.where(r <= cfg.huber_cm, 1.0, cfg.huber_cm / np.maximum(r, 1e-12))  # (J, K)
        sw = np.sqrt(w)[..., None, None]
        Am = (A * sw).reshape(-1, n_id)
        bm = (b * np.sqrt(w)[..., None]).ravel()
        identity = np.linalg.solve(Am.T @ Am + cfg.lam_id * J * np.eye(n_id), Am.T @ bm)
    return identity
