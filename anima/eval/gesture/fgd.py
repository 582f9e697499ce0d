"""Fréchet Gesture Distance (Yoon et al. 2020): the Fréchet distance between Gaussians fitted to features of
real and generated gesture windows, the features coming from the encoder of a motion autoencoder trained on
the training split's captured gestures.

Autoencoder: a 1D convolutional encoder (4 [Conv-BN-LeakyReLU] blocks, kernel 3, stride 2 after the first)
from the normalised 55-joint gesture ``[T, 165]`` to a ``latent``-wide code per 8 frames, and a mirrored
decoder; trained to reconstruct (L1). The feature of a window is its code averaged over time. Pure torch
and numpy.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import torch
from torch import nn

from anima.core.contract import BODY_DIM

G_DIM = BODY_DIM


def frechet_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Fréchet distance between Gaussians fitted to feature sets ``a [N, D]`` and ``b [M, D]``; NaN (said in the
    result, not raised) when a set has fewer than two rows (no covariance) or a non-finite feature (a diverged
    model's output): one fold or seed must not end a whole evaluation row."""
    if len(a) < 2 or len(b) < 2 or not (np.isfinite(a).all() and np.isfinite(b).all()):
        return float("nan")
    mu1, mu2 = a.mean(0), b.mean(0)
    s1, s2 = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    covmean, _ = scipy.linalg.sqrtm(s1 @ s2, disp=False)
    if not np.isfinite(covmean).all():  # near-singular product: regularise as in the FID reference code
        eps = np.eye(len(s1)) * 1e-6
        covmean = scipy.linalg.sqrtm((s1 + eps) @ (s2 + eps))
    covmean = np.real(covmean)
    return float(((mu1 - mu2) ** 2).sum() + np.trace(s1) + np.trace(s2) - 2 * np.trace(covmean))


class MotionAutoencoder(nn.Module):
    def __init__(self, latent: int = 32, width: int = 64):
        super().__init__()

        def blk(cin, cout, stride):
            return nn.Sequential(nn.Conv1d(cin, cout, 3, stride, 1), nn.BatchNorm1d(cout), nn.LeakyReLU(0.2))

        self.encoder = nn.Sequential(
            blk(G_DIM, width, 1), blk(width, width, 2), blk(width, width, 2), nn.Conv1d(width, latent, 3, 2, 1)
        )
        self.decoder = nn.Sequential(
            nn.Upsample(scale_factor=2),
            blk(latent, width, 1),
            nn.Upsample(scale_factor=2),
            blk(width, width, 1),
            nn.Upsample(scale_factor=2),
            blk(width, width, 1),
            nn.Conv1d(width, G_DIM, 3, 1, 1),
        )

    def forward(self, g):
        """``g [B, T, 165]`` (normalised, T a multiple of 8) -> reconstruction."""
        return self.decoder(self.encoder(g.transpose(1, 2))).transpose(1, 2)


class FGD:
    """``distance(real [N, T, 165], generated [M, T, 165])`` in the trained autoencoder's feature space."""

    def __init__(self, ae: MotionAutoencoder, mean: np.ndarray, std: np.ndarray, info: dict):
        self.ae, self.mean, self.std, self.info = ae.eval(), mean, std, info

    @torch.inference_mode()
    def features(self, G: np.ndarray) -> np.ndarray:
        x = torch.from_numpy(((G.reshape(len(G), G.shape[1], -1) - self.mean) / self.std).astype(np.float32))
        return self.ae.encoder(x.transpose(1, 2)).mean(-1).numpy().astype(np.float64)

    def distance(self, real: np.ndarray, generated: np.ndarray) -> float:
        return frechet_distance(self.features(real), self.features(generated))

    @torch.inference_mode()
    def frame_features(self, G: np.ndarray) -> np.ndarray:
        """The code at each of its time steps (T / 8 per window), not averaged: ``[N * T / 8, latent]``."""
        x = torch.from_numpy(((G.reshape(len(G), G.shape[1], -1) - self.mean) / self.std).astype(np.float32))
        z = self.ae.encoder(x.transpose(1, 2)).transpose(1, 2)
        return z.reshape(-1, z.shape[-1]).numpy().astype(np.float64)

    def frame_distance(self, real: np.ndarray, generated: np.ndarray) -> float:
        """Fréchet distance of the codes' time steps: for a handful of windows (a validation split), where
        one averaged code per window is too few samples for a covariance."""
        return frechet_distance(self.frame_features(real), self.frame_features(generated))


def train_fgd(G: np.ndarray, steps: int = 1500, batch: int = 16, latent: int = 8, seed: int = 0) -> FGD:
    """Train the autoencoder on captured windows ``G [N, T, 165]`` (T a multiple of 8). The code is 8 wide
    (Yoon et al. use 32): with tens of windows per method, a 32 x 32 covariance is mostly noise."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    X = G.reshape(len(G), G.shape[1], -1)
    mean, std = X.reshape(-1, G_DIM).mean(0), X.reshape(-1, G_DIM).std(0) + 1e-4
    x = torch.from_numpy(((X - mean) / std).astype(np.float32))
    ae = MotionAutoencoder(latent)
    opt = torch.optim.Adam(ae.parameters(), lr=1e-3)
    for _ in range(steps):
        i = torch.from_numpy(rng.integers(0, len(x), batch))
        loss = (ae(x[i]) - x[i]).abs().mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
    return FGD(
        ae,
        mean,
        std,
        {
            "windows": int(len(G)),
            "steps": steps,
            "latent": latent,
            "final_l1_normalised": round(float(loss.detach()), 4),
        },
    )
