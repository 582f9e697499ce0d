"""Generate facial motion from text with a trained checkpoint, and write what a user opens.

``Generator(checkpoint)`` loads a text2face or MDM checkpoint with its text encoder; ``generate(prompts,
length, seed)`` returns raw motion ``[B, T, 56]`` (53 ICT expression weights in [0, 1], head axis-angle).
``anima text2face`` itself is :func:`anima.text2face.run.run`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from anima.core.contract import N_EXPR
from anima.errors import InputError
from anima.text2face.encoders import clean_prompt, get_encoder
from anima.text2face.train import load_checkpoint

SHIPPED = Path(__file__).parent / "checkpoints" / "text2face.pt"


def default_checkpoint() -> Path:
    if not SHIPPED.is_file():
        raise InputError(f"no shipped checkpoint at {SHIPPED}; train one with `anima train text2face`")
    return SHIPPED


class Generator:
    def __init__(self, checkpoint: str | Path | None = None):
        self.path = Path(checkpoint) if checkpoint else default_checkpoint()
        ck = load_checkpoint(self.path)
        self.ck, self.model, self.kind = ck, ck["model"], ck["kind"]
        self.fps = ck["fps"]
        self.cfg = self.model.cfg
        self.mean = np.asarray(ck["mean"], np.float32)
        self.std = np.asarray(ck["std"], np.float32)

    @property
    def encoder(self):
        """The frozen text encoder of the checkpoint (loaded on first use: it takes seconds)."""
        return get_encoder(self.cfg.encoder)

    @property
    def length_range(self) -> tuple[int, int]:
        return self.cfg.min_len, self.cfg.max_len

    def check_length(self, n: int) -> int:
        lo, hi = self.length_range
        if not lo <= n <= hi:
            raise InputError(
                f"length {n} frames ({n / self.fps:.1f} s) is outside the trained range {lo}-{hi} "
                f"frames ({lo / self.fps:.1f}-{hi / self.fps:.1f} s at {self.fps:g} fps)"
            )
        return n

    def embed(self, prompts: list[str]) -> np.ndarray:
        return self.encoder.encode([clean_prompt(p, self.encoder) for p in prompts])

    def generate_from_embeddings(self, E: np.ndarray, length: int, seed: int = 0, cached: bool = True) -> np.ndarray:
        self.check_length(length)
        g = torch.Generator().manual_seed(int(seed))
        e = torch.from_numpy(np.asarray(E, np.float32))
        if self.kind == "text2face":
            code = torch.randn(len(e), self.cfg.d_r, generator=g)
            z = self.model.sample(e, code, length, cached=cached)
        else:
            z = self.model.sample(e, length, generator=g)
        return self.denormalise(z.numpy())

    def denormalise(self, z: np.ndarray) -> np.ndarray:
        m = z * self.std + self.mean
        m[..., :N_EXPR] = np.clip(m[..., :N_EXPR], 0.0, 1.0)
        return m.astype(np.float32)

    def generate(self, prompts: list[str], length: int = 90, seed: int = 0) -> np.ndarray:
        return self.generate_from_embeddings(self.embed(prompts), length, seed)
