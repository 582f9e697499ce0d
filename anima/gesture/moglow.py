"""A MoGlow-style speech-to-gesture baseline (Henter et al. 2020; for gestures Alexanderson et al. 2020, which
seed 004 compares against), sized for minutes of data.

The pose of each frame (face, body and hands together, z-normalised as for the §4.4 generator) is reduced to
its first ``flow_dim`` principal components (fitted on the training frames): with a few thousand training
frames, a flow over all 221 values would have more dimensions than it has evidence for. Over these
components, an autoregressive normalising flow: ``flow_steps`` Glow steps (activation normalisation, an
invertible linear map, an affine coupling whose network reads the condition), and a condition per frame from
an LSTM over the previous ``history`` poses and the speech features from ``speech_past`` frames before to
``speech_future`` frames after. As in MoGlow, the whole pose history of a training frame is dropped (set to
zero) with probability ``history_dropout``, so that the model listens to the speech instead of continuing
the past. Trained by exact likelihood; sampled frame by frame at ``temperature`` with a seeded generator,
so one speech always gives one motion. Departure from MoGlow: one LSTM shared by all coupling layers
(MoGlow gives each its own), and principal components instead of joint angles.

Pure torch, no I/O.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn


def fit_pca(Y: np.ndarray, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Principal components of the frames ``Y [N, D]``: (mean ``[D]``, basis ``[D, dim]``, orthonormal
    columns, largest variance first)."""
    mean = Y.mean(0)
    _, _, vt = np.linalg.svd(Y - mean, full_matrices=False)
    return mean.astype(np.float32), vt[:dim].T.astype(np.float32)


class _ActNorm(nn.Module):
    def __init__(self, d: int):
        super().__init__()
        self.bias = nn.Parameter(torch.zeros(d))
        self.logs = nn.Parameter(torch.zeros(d))
        self.register_buffer("ready", torch.tensor(False))

    def forward(self, x):
        if not self.ready:  # Glow's data-dependent initialisation: unit variance on the first batch
            with torch.no_grad():
                self.bias.copy_(-x.mean(0))
                self.logs.copy_(-torch.log(x.std(0) + 1e-6))
                self.ready.fill_(True)
        return (x + self.bias) * torch.exp(self.logs), self.logs.sum().expand(len(x))

    def inverse(self, y):
        return y * torch.exp(-self.logs) - self.bias


class _InvLinear(nn.Module):
    def __init__(self, d: int, seed: int):
        super().__init__()
        q, _ = torch.linalg.qr(torch.randn(d, d, generator=torch.Generator().manual_seed(seed)))
        self.W = nn.Parameter(q)

    def forward(self, x):
        return x @ self.W.T, torch.linalg.slogdet(self.W)[1].expand(len(x))

    def inverse(self, y, w_inv=None):
        return y @ (torch.linalg.inv(self.W) if w_inv is None else w_inv).T


class _Coupling(nn.Module):
    def __init__(self, d: int, d_cond: int, hidden: int):
        super().__init__()
        self.na = d // 2
        self.net = nn.Sequential(
            nn.Linear(self.na + d_cond, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
            nn.Linear(hidden, 2 * (d - self.na)),
        )  # fmt: skip
        nn.init.zeros_(self.net[-1].weight)
        nn.init.zeros_(self.net[-1].bias)

    def _shift_scale(self, xa, c):
        shift, raw = self.net(torch.cat([xa, c], -1)).chunk(2, -1)
        return shift, torch.sigmoid(raw + 2.0)  # Glow's bounded scale; 0.88 at initialisation

    def forward(self, x, c):
        xa, xb = x[:, : self.na], x[:, self.na :]
        shift, scale = self._shift_scale(xa, c)
        return torch.cat([xa, (xb + shift) * scale], -1), torch.log(scale).sum(-1)

    def inverse(self, y, c):
        ya, yb = y[:, : self.na], y[:, self.na :]
        shift, scale = self._shift_scale(ya, c)
        return torch.cat([ya, yb / scale - shift], -1)


class MoGlow(nn.Module):
    """``nll(pose [B, T, D], speech [B, T, S])`` (normalised) for training; ``forward(speech [B, T, S])`` ->
    {part: [B, T, dim]} sampled poses (normalised), as the other generators return them."""

    def __init__(self, cfg, parts: dict[str, int], speech_dim: int, pca_mean=None, pca_basis=None):
        super().__init__()
        self.cfg, self.parts = cfg, dict(parts)
        D, d = sum(parts.values()), cfg.flow_dim
        self.register_buffer("pca_mean", torch.zeros(D) if pca_mean is None else torch.as_tensor(pca_mean))
        self.register_buffer("pca_basis", torch.zeros(D, d) if pca_basis is None else torch.as_tensor(pca_basis))
        self.d = d
        self.ctx = cfg.speech_past + 1 + cfg.speech_future
        self.lstm = nn.LSTM(cfg.history * d + self.ctx * speech_dim, cfg.flow_hidden, batch_first=True)
        self.steps = nn.ModuleList()
        for k in range(cfg.flow_steps):
            self.steps.append(
                nn.ModuleList([_ActNorm(d), _InvLinear(d, k), _Coupling(d, cfg.flow_hidden, cfg.flow_hidden)])
            )

    # ---- conditioning ----
    def _speech_windows(self, speech):
        """``[B, T, S]`` -> each frame's speech context ``[B, T, ctx * S]`` (edges repeated)."""
        p, f = self.cfg.speech_past, self.cfg.speech_future
        s = torch.cat([speech[:, :1].expand(-1, p, -1), speech, speech[:, -1:].expand(-1, f, -1)], 1)
        return s.unfold(1, self.ctx, 1).transpose(2, 3).reshape(speech.shape[0], speech.shape[1], -1)

    def _history(self, x):
        """``x [B, T, d]`` -> the previous ``history`` frames of each frame ``[B, T, history * d]`` (zeros
        before the start)."""
        h = self.cfg.history
        padded = torch.cat([torch.zeros(x.shape[0], h, x.shape[2]), x], 1)
        return padded[:, :-1].unfold(1, h, 1).transpose(2, 3).reshape(x.shape[0], x.shape[1], -1)

    # ---- flow ----
    def _flow(self, x, c):
        logdet = torch.zeros(len(x))
        for norm, lin, coup in self.steps:
            x, a = norm(x)
            x, b = lin(x)
            x, e = coup(x, c)
            logdet = logdet + a + b + e
        return x, logdet

    def _inverse(self, z, c, w_inv=None):
        """The flow backwards; ``w_inv``: the inverses of the steps' 1x1 weights, computed once by a caller that
        inverts many frames with fixed weights (sampling inverts every frame: 16 inverses a frame otherwise)."""
        w_inv = w_inv or [None] * len(self.steps)
        for (norm, lin, coup), wi in zip(reversed(self.steps), reversed(w_inv)):
            z = norm.inverse(lin.inverse(coup.inverse(z, c), wi))
        return z

    def encode(self, pose):
        return (pose - self.pca_mean) @ self.pca_basis

    def nll(self, pose, speech, generator: torch.Generator | None = None):
        """Mean negative log-likelihood per frame and dimension (nats) of ``pose`` given ``speech`` and the
        pose history (teacher forcing, the history dropped per frame with ``history_dropout``)."""
        x = self.encode(pose)
        hist = self._history(x)
        if self.training and self.cfg.history_dropout:
            keep = torch.rand(x.shape[0], x.shape[1], 1, generator=generator) >= self.cfg.history_dropout
            hist = hist * keep
        c, _ = self.lstm(torch.cat([hist, self._speech_windows(speech)], -1))
        z, logdet = self._flow(x.reshape(-1, self.d), c.reshape(-1, c.shape[-1]))
        ll = -0.5 * (z**2).sum(-1) - 0.5 * self.d * math.log(2 * math.pi) + logdet
        return -ll.mean() / self.d

    @torch.inference_mode()
    def forward(self, speech, seed: int = 0):
        B, T, _ = speech.shape
        g = torch.Generator().manual_seed(seed)
        ctx = self._speech_windows(speech)
        hist = torch.zeros(B, self.cfg.history, self.d)
        w_inv = [torch.linalg.inv(lin.W) for _, lin, _ in self.steps]
        state, out = None, []
        for t in range(T):
            c, state = self.lstm(torch.cat([hist.reshape(B, 1, -1), ctx[:, t : t + 1]], -1), state)
            z = self.cfg.temperature * torch.randn(B, self.d, generator=g)
            x = self._inverse(z, c[:, 0], w_inv)
            out.append(x)
            hist = torch.cat([hist[:, 1:], x[:, None]], 1)
        pose = torch.stack(out, 1) @ self.pca_basis.T + self.pca_mean
        res, k = {}, 0
        for p, n in self.parts.items():
            res[p], k = pose[..., k : k + n], k + n
        return res
