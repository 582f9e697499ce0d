"""The expression reader: Face Mesh's landmarks, posed into the face model's frame, to expression weights. Pure
functions and one small shipped table.

Why: the face model's least-squares fit explains Face Mesh's landmarks by ICT's expression shapes at the
corresponded points, but Face Mesh does not move its landmarks the way ICT's surface moves (rendered with known
weights, an 0.8 brow lowerer was fitted at 0.14, a nose wrinkle with an upper-lip raise came out as a smile of
0.34). The reader learns how Face Mesh's landmarks DO move: a linear map from the frame's landmark offsets (the
landmarks in the fit's model space, less the fitted identity's neutral shape) to the weights, trained on renders
of the ICT face with known weights, on identities drawn for training only (``tools/train_expression_reader.py``;
never the round trip's development or test identities), with lights, backgrounds, distances and head turns
varied. Its ridge prior holds the directions in which real faces at rest differ from the renders' rest (talking
heads of the shared data's training side), so a person's own face does not read as an expression; the brows' channels
go without it (a person's brow height is left to the rest face, :mod:`anima.facemodel.neutral`).

It writes every channel but the eye-gaze ones (``eyeLook*``: the training renders never turn the eyes), which
stay the fit's.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data" / "expression_reader.npz"


@dataclass(frozen=True)
class ExpressionReader:
    """``weights = clip((D - mean_in) @ A + mean_out, 0, 1)`` on the channels ``channels``."""

    landmarks: np.ndarray  # (L,) Face Mesh landmark indices the reader reads
    channels: np.ndarray  # (C,) the face model's expression channels it writes
    mean_in: np.ndarray  # (L * 3,)
    mean_out: np.ndarray  # (C,)
    A: np.ndarray  # (L * 3, C)

    def __call__(self, D: np.ndarray) -> np.ndarray:
        """Offsets ``D [F, 478, 3]`` (model space, cm; rows by Face Mesh index) -> weights ``[F, C]`` in [0, 1]."""
        X = np.asarray(D, np.float64)[:, self.landmarks].reshape(len(D), -1)
        return np.clip((X - self.mean_in) @ self.A + self.mean_out, 0.0, 1.0)


def fit_reader(X: np.ndarray, Y: np.ndarray, prior: np.ndarray, lam: float) -> tuple:
    """Ridge regression ``Y ~ (X - mx) A + my`` on the per-sample averaged normal equations, with the prior
    ``lam I + prior`` (``prior [P, P]``: directions the reader must not respond to, e.g. ``sigma^2 J J^T``).
    ``X [N, P]``, ``Y [N, C]``. Returns ``(mx, my, A)``."""
    mx, my = X.mean(0), Y.mean(0)
    Xc = X - mx
    n = len(X)
    C = Xc.T @ Xc / n + lam * np.eye(X.shape[1]) + prior
    return mx, my, np.linalg.solve(C, Xc.T @ (Y - my) / n)


def landmark_offsets(Q: np.ndarray, index: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """``[F, 478, 3]`` offsets (NaN where a landmark is not in ``index``): the posed landmarks ``Q [F, K, 3]`` (model
    space) less the identity's neutral shape ``shape [K, 3]`` at the same points."""
    D = np.full((len(Q), 478, 3), np.nan)
    D[:, index] = Q - shape[None]
    return D


@lru_cache(maxsize=1)
def load_reader(path: str | None = None) -> ExpressionReader | None:
    """The shipped reader (None when the table is absent: the fit's weights are used as they are)."""
    p = Path(path) if path else DATA
    if not p.is_file():
        return None
    with np.load(p, allow_pickle=False) as z:
        return ExpressionReader(*(np.asarray(z[k]) for k in ("landmarks", "channels", "mean_in", "mean_out", "A")))
