"""The lifter network (seed 004 §3.3, fig. 3.2) on 2D keypoint evidence instead of an RGB backbone. No I/O.

Seed -> here:
* f_RGB (ResNet-50 on 350k images, 16x16x64 feature map) is replaced by MediaPipe Pose: its 2D keypoints
  and per-joint confidences b_k are the input evidence ``e`` (17 x (u, v, b)).
* F_3D = [h_2D, d]: ``h_2D`` is an explicit 2D pose (17 x 2, the role of the 14 heatmap channels), trained
  towards the ground-truth 2D pose with the latent 2D loss (eq. 3.3, weight 0.1, masked by b_k); ``d`` is a
  128-d vector of unconstrained features (the other 50 channels), supervised only through the losses
  downstream. Both come from an evidence encoder (FC 1024, residual block).
  Vectors rather than heatmaps: without a convolutional backbone a 16x16 heatmap would only quantise
  MediaPipe's sub-pixel keypoints; Martinez et al. (2017), on which f_3D is modelled, lift vectors.
* z = FC([h_2D, d]) in R^1024; f_3D: four FC-1024 + ReLU layers, residual from z to the output of the second
  (§3.3.1), then a linear layer to the root-relative 3D pose (17 x 3, in units of ``pose_scale`` mm).
* f_c: an MLP on z predicting the weak-perspective camera (c_x, c_y, alpha_x, alpha_y); eq. 3.2 projects the
  3D pose into the normalised image frame.
"""

from __future__ import annotations

import torch
from torch import nn

from anima.pose3d.config import LifterConfig


class _Res(nn.Module):
    def __init__(self, w: int, p: float):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(w, w),
            nn.BatchNorm1d(w),
            nn.ReLU(),
            nn.Dropout(p),
            nn.Linear(w, w),
            nn.BatchNorm1d(w),
            nn.ReLU(),
            nn.Dropout(p),
        )

    def forward(self, x):
        return x + self.net(x)


class Lifter(nn.Module):
    def __init__(self, cfg: LifterConfig | None = None):
        super().__init__()
        self.cfg = cfg = cfg or LifterConfig()
        k, w = cfg.joints, cfg.width
        self.encoder = nn.Sequential(
            nn.Linear(3 * k, w), nn.BatchNorm1d(w), nn.ReLU(), nn.Dropout(cfg.dropout), _Res(w, cfg.dropout)
        )
        self.h2d = nn.Linear(w, 2 * k)
        self.d = nn.Linear(w, cfg.latent)
        self.z = nn.Sequential(nn.Linear(2 * k + cfg.latent, w), nn.BatchNorm1d(w), nn.ReLU())
        # f_3D: four FC-1024 layers; the residual connects z with the output of the second
        self.f3d_a = nn.Sequential(
            nn.Linear(w, w),
            nn.BatchNorm1d(w),
            nn.ReLU(),
            nn.Dropout(cfg.dropout),
            nn.Linear(w, w),
            nn.BatchNorm1d(w),
            nn.ReLU(),
            nn.Dropout(cfg.dropout),
        )
        self.f3d_b = nn.Sequential(
            nn.Linear(w, w),
            nn.BatchNorm1d(w),
            nn.ReLU(),
            nn.Dropout(cfg.dropout),
            nn.Linear(w, w),
            nn.BatchNorm1d(w),
            nn.ReLU(),
        )
        self.out3d = nn.Linear(w, 3 * k)
        self.fc = nn.Sequential(nn.Linear(w, 256), nn.ReLU(), nn.Linear(256, 4))

    def forward(self, uv: torch.Tensor, conf: torch.Tensor) -> dict[str, torch.Tensor]:
        """``uv`` (B, K, 2) normalised 2D evidence, ``conf`` (B, K) in [0, 1]. Masked joints (conf 0) are
        zeroed, so the network never sees a position it was told not to trust."""
        B, k = conf.shape
        x = torch.cat([uv * conf[..., None], conf[..., None]], -1).reshape(B, 3 * k)
        f = self.encoder(x)
        h2d = self.h2d(f).reshape(B, k, 2)
        z = self.z(torch.cat([h2d.reshape(B, -1), self.d(f)], -1))
        y = self.f3d_b(self.f3d_a(z) + z)
        p3d = self.out3d(y).reshape(B, k, 3)
        p3d = p3d - p3d[:, :1]  # root-relative
        cam = self.fc(z)
        c, alpha = cam[:, :2], nn.functional.softplus(cam[:, 2:]) + 1e-3
        proj = alpha[:, None, :] * p3d[..., :2] + c[:, None, :]  # eq. 3.2
        return {"h2d": h2d, "p3d": p3d, "cam": torch.cat([c, alpha], -1), "proj": proj}

    @torch.no_grad()
    def predict_mm(self, uv: torch.Tensor, conf: torch.Tensor) -> torch.Tensor:
        return self.forward(uv, conf)["p3d"] * self.cfg.pose_scale
