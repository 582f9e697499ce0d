"""Text -> facial motion (seed 000 ch. 6): a conditional VQ-VAE turns a frozen text embedding plus a
per-sample random code into a sequence of guidance tokens; a FaceFormer-style transformer decoder
(periodic positional encoding, biased causal self-attention B^F, alignment bias B^A on cross-attention)
turns them into motion, trained with teacher forcing and sampled autoregressively with cached keys/values.

Motion frames are z-normalised 56-d vectors (53 ICT expression weights + head axis-angle). Pure torch; no
I/O (checkpoints: :mod:`anima.text2face.train`).

One addition to the seed: the cVQVAE decoder also sees the requested length (``length_cond``). The seed
fixed every clip to 90 frames; here clips run 1-10 s, and without the length the guidance for frame t
cannot know whether "then blinks" should fall at 2 s or at 6 s.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
import torch.nn.functional as F
from torch import nn

from anima.core.contract import FACE_DIM


@dataclass
class Text2FaceConfig:
    d_c: int = 384  # text embedding size (MiniLM 384, CLIP 512)
    D_emb: int = 256  # codebook entry size
    N_emb: int = 128  # codebook entries
    d_r: int = 64  # per-sample random code
    d_t: int = 64  # guidance token size
    d_m: int = 512  # transformer width
    mlp_hidden: int = 512
    n_heads: int = 4
    n_layers: int = 1
    ff_mult: int = 2  # FaceFormer: feed-forward = 2 * d_m
    period: int = 15  # PPE / temporal-bias period at 30 fps
    max_len: int = 300  # longest sequence (frames): guidance tokens are produced for this many frames
    min_len: int = 30
    dropout: float = 0.1
    beta: float = 0.25  # VQ loss: (1 - beta) codebook term + beta commitment term
    length_cond: bool = True
    style: bool = False  # ablation: a per-sample random style vector added to every decoder input
    motion_dim: int = FACE_DIM
    encoder: str = "minilm"

    def to_dict(self) -> dict:
        return asdict(self)


PRESETS = {
    # the seed's hyper-parameters (§7.1)
    "seed": dict(),
    # the shipped model: same design, narrower (77 training clips; commit-sized checkpoint)
    "small": dict(d_m=256, d_t=32, mlp_hidden=128),
}


def preset(name: str, **over) -> Text2FaceConfig:
    if name not in PRESETS:
        raise KeyError(f"unknown preset {name!r}; known: {', '.join(PRESETS)}")
    return Text2FaceConfig(**{**PRESETS[name], **over})


# ---- FaceFormer pieces ----------------------------------------------------------------------------


def periodic_positional_encoding(d_model: int, period: int, max_len: int) -> torch.Tensor:
    """``[max_len, d_model]``: sinusoids over one period, repeated (FaceFormer's PPE)."""
    pos = torch.arange(period, dtype=torch.float32)[:, None]
    div = torch.exp(torch.arange(0, d_model, 2, dtype=torch.float32) * (-math.log(10000.0) / d_model))
    pe = torch.zeros(period, d_model)
    pe[:, 0::2] = torch.sin(pos * div)
    pe[:, 1::2] = torch.cos(pos * div[: d_model // 2])
    return pe.repeat(max_len // period + 1, 1)[:max_len]


def alibi_slopes(n_heads: int) -> torch.Tensor:
    def pow2(n):
        start = 2 ** (-(2 ** -(math.log2(n) - 3)))
        return [start * start**i for i in range(n)]

    if math.log2(n_heads).is_integer():
        s = pow2(n_heads)
    else:
        c = 2 ** math.floor(math.log2(n_heads))
        s = pow2(c) + pow2(2 * c)[0::2][: n_heads - c]
    return torch.tensor(s, dtype=torch.float32)


def temporal_bias(n_heads: int, period: int, max_len: int) -> torch.Tensor:
    """B^F ``[H, T, T]``: causal mask (-inf above the diagonal) plus ``-slope_h * floor((i - j) / p)``."""
    i = torch.arange(max_len)[:, None]
    j = torch.arange(max_len)[None, :]
    dist = torch.div(i - j, period, rounding_mode="floor").clamp(min=0).float()
    bias = -alibi_slopes(n_heads)[:, None, None] * dist[None]
    return bias.masked_fill((j > i)[None], float("-inf"))


def alignment_bias(t_len: int, s_len: int) -> torch.Tensor:
    """B^A ``[T, S]``: frame t attends only guidance token t (0 on the diagonal, -inf elsewhere)."""
    m = torch.full((t_len, s_len), float("-inf"))
    k = min(t_len, s_len)
    m[torch.arange(k), torch.arange(k)] = 0.0
    return m


class Attention(nn.Module):
    def __init__(self, d: int, heads: int, dropout: float):
        super().__init__()
        self.h, self.dk = heads, d // heads
        self.q, self.k, self.v, self.o = (nn.Linear(d, d) for _ in range(4))
        self.drop = dropout

    def split(self, x):
        B, T, _ = x.shape
        return x.view(B, T, self.h, self.dk).transpose(1, 2)

    def forward(self, x, mem, bias, cache: dict | None = None):
        q = self.split(self.q(x))
        k, v = self.split(self.k(mem)), self.split(self.v(mem))
        if cache is not None:
            if "k" in cache:
                k = torch.cat([cache["k"], k], 2)
                v = torch.cat([cache["v"], v], 2)
            cache["k"], cache["v"] = k, v
        y = F.scaled_dot_product_attention(q, k, v, attn_mask=bias, dropout_p=self.drop if self.training else 0.0)
        B, H, T, dk = y.shape
        return self.o(y.transpose(1, 2).reshape(B, T, H * dk))


class DecoderLayer(nn.Module):
    """Post-norm transformer decoder layer (as ``nn.TransformerDecoderLayer``) with a key/value cache."""

    def __init__(self, d: int, heads: int, ff: int, dropout: float):
        super().__init__()
        self.sa = Attention(d, heads, dropout)
        self.ca = Attention(d, heads, dropout)
        self.ff = nn.Sequential(nn.Linear(d, ff), nn.ReLU(), nn.Dropout(dropout), nn.Linear(ff, d))
        self.n1, self.n2, self.n3 = nn.LayerNorm(d), nn.LayerNorm(d), nn.LayerNorm(d)
        self.drop = nn.Dropout(dropout)

    def forward(self, x, mem, self_bias, cross_bias, cache: dict | None = None):
        x = self.n1(x + self.drop(self.sa(x, x, self_bias, cache)))
        x = self.n2(x + self.drop(self.ca(x, mem, cross_bias)))
        return self.n3(x + self.drop(self.ff(x)))


# ---- the model --------------------------------------------------------------------------------------


class CVQVAE(nn.Module):
    """Text embedding -> MLP -> nearest codebook entry (straight-through) -> [z_q, c, length] -> MLP ->
    ``max_len`` guidance tokens of ``d_t`` -> linear to ``d_m``."""

    def __init__(self, cfg: Text2FaceConfig):
        super().__init__()
        self.cfg = cfg
        h = cfg.mlp_hidden
        self.enc = nn.Sequential(nn.Linear(cfg.d_c, h), nn.LeakyReLU(0.2), nn.Linear(h, cfg.D_emb))
        self.codebook = nn.Embedding(cfg.N_emb, cfg.D_emb)
        self.codebook.weight.data.uniform_(-1.0 / cfg.N_emb, 1.0 / cfg.N_emb)
        n_len = 8 if cfg.length_cond else 0
        self.dec = nn.Sequential(
            nn.Linear(cfg.D_emb + cfg.d_r + n_len, h), nn.LeakyReLU(0.2), nn.Linear(h, cfg.max_len * cfg.d_t)
        )
        self.proj = nn.Linear(cfg.d_t, cfg.d_m)

    def length_features(self, length: torch.Tensor) -> torch.Tensor:
        x = length.float()[:, None] / self.cfg.max_len
        f = torch.arange(1, 5, dtype=torch.float32, device=x.device)[None] * math.pi
        return torch.cat([torch.sin(x * f), torch.cos(x * f)], 1)

    def quantize(self, z_e: torch.Tensor):
        d = (
            z_e.pow(2).sum(1, keepdim=True)
            - 2 * z_e @ self.codebook.weight.T
            + self.codebook.weight.pow(2).sum(1)[None]
        )
        idx = d.argmin(1)
        e = self.codebook(idx)
        b = self.cfg.beta
        vq = (1 - b) * F.mse_loss(e, z_e.detach()) + b * F.mse_loss(z_e, e.detach())
        z_q = z_e + (e - z_e).detach()  # straight-through
        return z_q, idx, vq

    @torch.no_grad()
    def restart_codes(self, text_emb: torch.Tensor, counts: torch.Tensor, generator=None) -> int:
        """Codebook upkeep (training only): entries no text mapped to since the last call move onto encoder
        outputs of random training texts (dead-code restart, as in Jukebox / SoundStream). Without it the
        codebook collapses onto one or two entries and the text is ignored. Returns how many moved."""
        dead = torch.nonzero(counts == 0).flatten()
        if len(dead) == 0:
            return 0
        z = self.enc(text_emb)
        pick = torch.randint(0, len(z), (len(dead),), generator=generator)
        self.codebook.weight.data[dead] = z[pick] + 0.01 * z.std() * torch.randn(
            len(dead), z.shape[1], generator=generator
        )
        return len(dead)

    def forward(self, text_emb, code, length):
        z_q, idx, vq = self.quantize(self.enc(text_emb))
        parts = [z_q, code] + ([self.length_features(length)] if self.cfg.length_cond else [])
        g = self.dec(torch.cat(parts, 1)).view(-1, self.cfg.max_len, self.cfg.d_t)
        return self.proj(g), idx, vq


class Text2Face(nn.Module):
    def __init__(self, cfg: Text2FaceConfig):
        super().__init__()
        self.cfg = cfg
        self.guide = CVQVAE(cfg)
        self.inp = nn.Linear(cfg.motion_dim, cfg.d_m)
        self.style = nn.Linear(cfg.d_r, cfg.d_m, bias=False) if cfg.style else None
        self.layers = nn.ModuleList(
            DecoderLayer(cfg.d_m, cfg.n_heads, cfg.ff_mult * cfg.d_m, cfg.dropout) for _ in range(cfg.n_layers)
        )
        self.out = nn.Linear(cfg.d_m, cfg.motion_dim)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)
        self.pe_drop = nn.Dropout(cfg.dropout)
        self.register_buffer("ppe", periodic_positional_encoding(cfg.d_m, cfg.period, cfg.max_len), persistent=False)
        self.register_buffer("bias_f", temporal_bias(cfg.n_heads, cfg.period, cfg.max_len), persistent=False)
        self.register_buffer("bias_a", alignment_bias(cfg.max_len, cfg.max_len), persistent=False)

    def _embed(self, frames, t0: int, style):
        x = self.inp(frames)
        if style is not None:
            x = x + style[:, None]
        return self.pe_drop(x + self.ppe[t0 : t0 + x.shape[1]])

    def _style(self, code):
        return self.style(code) if self.style is not None else None

    def forward(self, text_emb, code, motion):
        """Teacher forcing. ``motion [B, T, D]`` (normalised, padded); returns prediction ``[B, T, D]`` and
        the VQ loss."""
        B, T, _ = motion.shape
        mem, _, vq = self.guide(text_emb, code, torch.full((B,), T, device=motion.device))
        shifted = torch.cat([torch.zeros_like(motion[:, :1]), motion[:, :-1]], 1)
        x = self._embed(shifted, 0, self._style(code))
        mem = mem[:, :T]
        for layer in self.layers:
            x = layer(x, mem, self.bias_f[:, :T, :T], self.bias_a[:T, :T])
        return self.out(x), vq

    def forward_autoregressive(self, text_emb, code, lengths_T: int):
        """The FaceFormer training scheme (ablation): feed back its own predictions, with gradients."""
        return self._rollout(text_emb, code, lengths_T, cached=True)[0]

    def _rollout(self, text_emb, code, T: int, cached: bool):
        B = text_emb.shape[0]
        mem, _, vq = self.guide(text_emb, code, torch.full((B,), T, device=text_emb.device))
        style = self._style(code)
        prev = torch.zeros(B, 1, self.cfg.motion_dim, device=text_emb.device)
        outs = []
        if cached:
            caches = [dict() for _ in self.layers]
            for t in range(T):
                x = self._embed(prev, t, style)
                for layer, c in zip(self.layers, caches):
                    x = layer(x, mem[:, t : t + 1], self.bias_f[:, t : t + 1, : t + 1], None, c)
                prev = self.out(x)
                outs.append(prev)
            return torch.cat(outs, 1), vq
        seq = prev
        for t in range(T):  # the uncached sampler: recompute the whole prefix every step (FaceFormer's)
            x = self._embed(seq, 0, style)
            for layer in self.layers:
                x = layer(x, mem[:, : t + 1], self.bias_f[:, : t + 1, : t + 1], self.bias_a[: t + 1, : t + 1])
            y = self.out(x[:, -1:])
            outs.append(y)
            seq = torch.cat([seq, y], 1)
        return torch.cat(outs, 1), vq

    @torch.inference_mode()
    def sample(self, text_emb, code, T: int, cached: bool = True) -> torch.Tensor:
        """Autoregressive sampling, ``[B, T, D]`` normalised motion."""
        if not self.cfg.min_len <= T <= self.cfg.max_len:
            raise ValueError(f"length {T} outside the trained range [{self.cfg.min_len}, {self.cfg.max_len}]")
        return self._rollout(text_emb, code, T, cached)[0]
