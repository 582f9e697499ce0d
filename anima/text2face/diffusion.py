"""The diffusion baseline in the style of MDM (Tevet et al.; seed 000's "HMDM (adapted)"): a transformer
encoder over the noisy motion with the text embedding and the diffusion step as one extra token, predicting
the clean motion x0; cosine noise schedule with 1000 steps, DDIM sampling in 50 steps, classifier-free
guidance (the text dropped for 10 % of training samples). Pure torch, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from anima.text2face.model import MOTION_DIM


@dataclass
class MDMConfig:
    d_c: int = 384
    d_model: int = 256
    n_heads: int = 4
    n_layers: int = 4
    ff: int = 1024
    dropout: float = 0.1
    steps: int = 1000
    ddim_steps: int = 50
    cond_drop: float = 0.1
    guidance: float = 2.5
    max_len: int = 300
    min_len: int = 30
    motion_dim: int = MOTION_DIM
    encoder: str = "minilm"

    def to_dict(self) -> dict:
        return asdict(self)


def cosine_alphas_cumprod(steps: int, s: float = 0.008) -> torch.Tensor:
    t = torch.arange(steps + 1, dtype=torch.float64) / steps
    f = torch.cos((t + s) / (1 + s) * math.pi / 2) ** 2
    ab = f / f[0]
    betas = (1 - ab[1:] / ab[:-1]).clamp(max=0.999)
    return torch.cumprod(1 - betas, 0).float()


def timestep_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    half = dim // 2
    freqs = torch.exp(-math.log(10000) * torch.arange(half, dtype=torch.float32, device=t.device) / half)
    a = t.float()[:, None] * freqs[None]
    return torch.cat([torch.cos(a), torch.sin(a)], 1)


class MDM(nn.Module):
    def __init__(self, cfg: MDMConfig):
        super().__init__()
        self.cfg = cfg
        d = cfg.d_model
        self.inp = nn.Linear(cfg.motion_dim, d)
        self.text = nn.Linear(cfg.d_c, d)
        self.time = nn.Sequential(nn.Linear(d, d), nn.SiLU(), nn.Linear(d, d))
        layer = nn.TransformerEncoderLayer(d, cfg.n_heads, cfg.ff, cfg.dropout, activation="gelu", batch_first=True)
        self.enc = nn.TransformerEncoder(layer, cfg.n_layers, enable_nested_tensor=False)
        self.out = nn.Linear(d, cfg.motion_dim)
        pos = torch.arange(cfg.max_len + 1, dtype=torch.float32)
        self.register_buffer("pos", timestep_embedding(pos, d), persistent=False)
        self.register_buffer("ab", cosine_alphas_cumprod(cfg.steps), persistent=False)

    def forward(self, x_t, t, text_emb, cond_mask, pad_mask=None):
        """Predict x0. ``cond_mask [B]`` 1 keeps the text, 0 drops it; ``pad_mask [B, T]`` True at padding."""
        B, T, _ = x_t.shape
        c = self.text(text_emb) * cond_mask[:, None] + self.time(timestep_embedding(t, self.cfg.d_model))
        h = torch.cat([c[:, None], self.inp(x_t)], 1) + self.pos[: T + 1]
        if pad_mask is not None:
            pad_mask = torch.cat([torch.zeros(B, 1, dtype=torch.bool, device=x_t.device), pad_mask], 1)
        return self.out(self.enc(h, src_key_padding_mask=pad_mask)[:, 1:])

    def q_sample(self, x0, t, noise):
        a = self.ab[t][:, None, None]
        return a.sqrt() * x0 + (1 - a).sqrt() * noise

    @torch.inference_mode()
    def sample(self, text_emb, T: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """DDIM (eta = 0) from pure noise with classifier-free guidance; ``[B, T, D]`` normalised motion."""
        if not self.cfg.min_len <= T <= self.cfg.max_len:
            raise ValueError(f"length {T} outside the trained range [{self.cfg.min_len}, {self.cfg.max_len}]")
        B = text_emb.shape[0]
        x = torch.randn(B, T, self.cfg.motion_dim, generator=generator)
        ts = torch.linspace(self.cfg.steps - 1, 0, self.cfg.ddim_steps).round().long()
        ones, zeros = torch.ones(B), torch.zeros(B)
        for i, t in enumerate(ts):
            tt = torch.full((B,), int(t))
            x0c = self(x, tt, text_emb, ones)
            x0u = self(x, tt, text_emb, zeros)
            x0 = x0u + self.cfg.guidance * (x0c - x0u)
            a = self.ab[t]
            eps = (x - a.sqrt() * x0) / (1 - a).sqrt()
            if i + 1 < len(ts):
                a_next = self.ab[ts[i + 1]]
                x = a_next.sqrt() * x0 + (1 - a_next).sqrt() * eps
            else:
                x = x0
        return x
