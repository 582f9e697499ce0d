"""The diffusion baselines of seed 000's table 7.1.

:class:`MDM`: in the style of MDM (Tevet et al.; seed 000's "HMDM (adapted)"): a transformer encoder over
the noisy motion with the text embedding and the diffusion step as one extra token, predicting the clean
motion x0; cosine noise schedule with 1000 steps, DDIM sampling in 50 steps, classifier-free guidance (the
text dropped for 10 % of training samples).

:class:`SMF`: in the style of StableMoFusion (:class:`SMFConfig`).

Pure torch, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from anima.core.contract import FACE_DIM


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
    motion_dim: int = FACE_DIM
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


# ---- StableMoFusion-style baseline -------------------------------------------------------------------


@dataclass
class SMFConfig:
    """The diffusion baseline in the style of StableMoFusion (Huang et al. 2024; seed 000's "SMF (adapted)"):
    as the seed adapted it, a linear projection of the motion down to ``d_in`` and back up around the model; in
    between a Conv1D U-Net whose residual blocks are conditioned by adaptive group normalisation on the
    diffusion step plus the text; DPM-Solver++ (2M) sampling in ``solver_steps`` steps with classifier-free
    guidance. Departures, forced by this data and encoder: the text is one sentence vector (MiniLM), not a
    CLIP token sequence, so StableMoFusion's cross-attention over tokens becomes the text part of the AdaGN
    condition; the network predicts x0 with the loss every text2face model here uses (StableMoFusion's
    footskate clean-up has no face counterpart)."""

    d_c: int = 384
    d_in: int = 64
    channels: tuple = (128, 256, 256)
    kernel: int = 5
    groups: int = 8
    dropout: float = 0.1
    steps: int = 1000
    solver_steps: int = 10
    cond_drop: float = 0.1
    guidance: float = 2.5  # MDM's: the same guidance for both diffusion baselines, not tuned
    max_len: int = 300
    min_len: int = 30
    motion_dim: int = FACE_DIM
    encoder: str = "minilm"

    def to_dict(self) -> dict:
        return {**asdict(self), "channels": list(self.channels)}


def masked_group_norm(gn: nn.GroupNorm, x: torch.Tensor, m: torch.Tensor) -> torch.Tensor:
    """``gn`` over the valid frames only (``m [B, 1, T]`` 1 where valid), so a padded batch normalises each
    sequence as it would be alone."""
    B, C, T = x.shape
    xg = x.reshape(B, gn.num_groups, -1, T)
    mg = m[:, None]
    n = mg.sum((2, 3), keepdim=True).clamp(min=1) * xg.shape[2]
    mean = (xg * mg).sum((2, 3), keepdim=True) / n
    var = ((xg - mean) ** 2 * mg).sum((2, 3), keepdim=True) / n
    y = ((xg - mean) / torch.sqrt(var + gn.eps)).reshape(B, C, T)
    return y * gn.weight[:, None] + gn.bias[:, None]


class _AdaGNBlock(nn.Module):
    """Residual block: GroupNorm, SiLU, conv; GroupNorm modulated by the condition (scale, shift), SiLU,
    dropout, conv; padding frames held at zero and left out of the norms."""

    def __init__(self, c_in: int, c_out: int, d_cond: int, kernel: int, groups: int, dropout: float):
        super().__init__()
        self.n1, self.n2 = nn.GroupNorm(groups, c_in), nn.GroupNorm(groups, c_out)
        self.c1 = nn.Conv1d(c_in, c_out, kernel, padding=kernel // 2)
        self.c2 = nn.Conv1d(c_out, c_out, kernel, padding=kernel // 2)
        self.film = nn.Linear(d_cond, 2 * c_out)
        self.drop = nn.Dropout(dropout)
        self.skip = nn.Conv1d(c_in, c_out, 1) if c_in != c_out else nn.Identity()
        nn.init.zeros_(self.c2.weight)
        nn.init.zeros_(self.c2.bias)

    def forward(self, x, cond, m):
        h = self.c1(nn.functional.silu(masked_group_norm(self.n1, x, m)) * m) * m
        scale, shift = self.film(cond)[..., None].chunk(2, 1)
        h = nn.functional.silu(masked_group_norm(self.n2, h, m) * (1 + scale) + shift) * m
        return (self.skip(x) + self.c2(self.drop(h))) * m


class SMF(nn.Module):
    def __init__(self, cfg: SMFConfig):
        super().__init__()
        self.cfg = cfg
        ch = list(cfg.channels)
        d = ch[0] * 4
        self.d_time = ch[0]
        self.time = nn.Sequential(nn.Linear(ch[0], d), nn.SiLU(), nn.Linear(d, d))
        self.text = nn.Linear(cfg.d_c, d)
        self.inp = nn.Linear(cfg.motion_dim, cfg.d_in)
        self.stem = nn.Conv1d(cfg.d_in, ch[0], cfg.kernel, padding=cfg.kernel // 2)
        blk = lambda a, b: _AdaGNBlock(a, b, d, cfg.kernel, cfg.groups, cfg.dropout)
        self.down = nn.ModuleList([blk(ch[max(i - 1, 0)], c) for i, c in enumerate(ch)])
        self.pool = nn.ModuleList([nn.Conv1d(c, c, 3, stride=2, padding=1) for c in ch[:-1]])
        self.mid = nn.ModuleList([blk(ch[-1], ch[-1]), blk(ch[-1], ch[-1])])
        self.up = nn.ModuleList([blk(2 * c, ch[max(i - 1, 0)]) for i, c in reversed(list(enumerate(ch)))])
        self.head_norm = nn.GroupNorm(cfg.groups, ch[0])
        self.head = nn.Conv1d(ch[0], cfg.d_in, 1)
        self.out = nn.Linear(cfg.d_in, cfg.motion_dim)
        self.register_buffer("ab", cosine_alphas_cumprod(cfg.steps), persistent=False)

    def forward(self, x_t, t, text_emb, cond_mask, pad_mask=None):
        """Predict x0 (``[B, T, D]``). ``cond_mask [B]`` 1 keeps the text, 0 drops it; ``pad_mask [B, T]``
        True at padding."""
        B, T, _ = x_t.shape
        levels = len(self.cfg.channels)
        Tp = -(-T // 2 ** (levels - 1)) * 2 ** (levels - 1)  # a length every level halves exactly
        valid = torch.ones(B, T) if pad_mask is None else (~pad_mask).float()
        m = nn.functional.pad(valid, (0, Tp - T))[:, None]
        h = nn.functional.pad(self.inp(x_t).transpose(1, 2), (0, Tp - T)) * m
        cond = self.time(timestep_embedding(t, self.d_time)) + self.text(text_emb) * cond_mask[:, None]
        h = self.stem(h) * m
        masks, skips = [m], []
        for i, block in enumerate(self.down):
            h = block(h, cond, masks[-1])
            skips.append(h)
            if i < len(self.pool):
                h = self.pool[i](h)
                masks.append(nn.functional.max_pool1d(masks[-1], 2))
                h = h * masks[-1]
        for block in self.mid:
            h = block(h, cond, masks[-1])
        for i, block in enumerate(self.up):
            h = block(torch.cat([h, skips.pop()], 1), cond, masks[-1])
            if i + 1 < len(self.up):
                masks.pop()
                h = nn.functional.interpolate(h, scale_factor=2, mode="nearest") * masks[-1]
        h = self.head(nn.functional.silu(masked_group_norm(self.head_norm, h, masks[-1])) * masks[-1])
        return self.out(h[..., :T].transpose(1, 2))

    def q_sample(self, x0, t, noise):
        a = self.ab[t][:, None, None]
        return a.sqrt() * x0 + (1 - a).sqrt() * noise

    @torch.inference_mode()
    def sample(self, text_emb, T: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """DPM-Solver++ (2M, data prediction, first order on the last step; Lu et al. 2022) from pure noise
        with classifier-free guidance; ``[B, T, D]`` normalised motion."""
        if not self.cfg.min_len <= T <= self.cfg.max_len:
            raise ValueError(f"length {T} outside the trained range [{self.cfg.min_len}, {self.cfg.max_len}]")
        B = text_emb.shape[0]
        x = torch.randn(B, T, self.cfg.motion_dim, generator=generator)
        ts = torch.linspace(self.cfg.steps - 1, 0, self.cfg.solver_steps + 1).round().long()
        alpha, sigma = self.ab.sqrt(), (1 - self.ab).sqrt()
        lam = torch.log(alpha / sigma)
        ones, zeros = torch.ones(B), torch.zeros(B)
        x0_prev, h_prev = None, None
        for i in range(self.cfg.solver_steps):
            s, t = int(ts[i]), int(ts[i + 1])
            tt = torch.full((B,), s)
            x0u = self(x, tt, text_emb, zeros)
            x0 = x0u + self.cfg.guidance * (self(x, tt, text_emb, ones) - x0u)
            h = lam[t] - lam[s]
            if x0_prev is None or i + 1 == self.cfg.solver_steps:
                D = x0
            else:
                r = h_prev / h
                D = (1 + 1 / (2 * r)) * x0 - 1 / (2 * r) * x0_prev
            x = (sigma[t] / sigma[s]) * x - alpha[t] * torch.expm1(-h) * D
            x0_prev, h_prev = x0, h
        return x
