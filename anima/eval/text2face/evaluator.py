"""A contrastive text-motion evaluator for R-precision (the measure of Guo et al. that MDM reports and that
seed 000 could not compute for lack of a facial one): a text head on the frozen sentence embedding and a 1D
convolutional motion encoder, trained with a symmetric InfoNCE loss on the training crops only. Pure torch.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from anima.core.contract import FACE_DIM
from anima.io.checkpoint import load_checkpoint, load_state, rebuild, save_checkpoint


class MotionTextEvaluator(nn.Module):
    def __init__(self, d_c: int = 384, motion_dim: int = FACE_DIM, width: int = 128, dim: int = 128):
        super().__init__()
        self.text = nn.Sequential(nn.Linear(d_c, 256), nn.GELU(), nn.Linear(256, dim))
        self.conv = nn.Sequential(
            nn.Conv1d(motion_dim, width, 5, padding=2),
            nn.GELU(),
            nn.Conv1d(width, width, 5, padding=4, dilation=2),
            nn.GELU(),
            nn.Conv1d(width, width, 5, padding=8, dilation=4),
            nn.GELU(),
        )
        self.head = nn.Linear(2 * width, dim)
        self.log_temp = nn.Parameter(torch.tensor(np.log(1 / 0.07), dtype=torch.float32))

    def embed_text(self, e):
        return F.normalize(self.text(e), dim=-1)

    def embed_motion(self, x, mask=None):
        """``x [B, T, D]`` normalised motion; mean and max pooled over valid frames."""
        h = self.conv(x.transpose(1, 2)).transpose(1, 2)
        if mask is None:
            mask = torch.ones(h.shape[:2], device=h.device)
        m = mask[..., None]
        mean = (h * m).sum(1) / m.sum(1).clamp(min=1)
        mx = h.masked_fill(m == 0, -1e4).max(1).values
        return F.normalize(self.head(torch.cat([mean, mx], 1)), dim=-1)

    def loss(self, e, x, mask):
        t, m = self.embed_text(e), self.embed_motion(x, mask)
        logits = self.log_temp.exp().clamp(max=100) * m @ t.T
        y = torch.arange(len(e))
        return 0.5 * (F.cross_entropy(logits, y) + F.cross_entropy(logits.T, y))


def train_evaluator(
    motions: list[np.ndarray],
    E: np.ndarray,
    steps: int = 1500,
    batch: int = 64,
    crop: int = 90,
    seed: int = 0,
    progress=None,
) -> MotionTextEvaluator:
    """``motions``: normalised training crops; ``E``: their text embeddings. Crops longer than ``crop`` are
    cut at random (the evaluator scores fixed-length windows) and keep their text only when they were made
    at that length; otherwise the whole crop is used, padded."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    ev = MotionTextEvaluator(E.shape[1], motions[0].shape[1])
    opt = torch.optim.Adam(ev.parameters(), lr=1e-3)
    Et = torch.from_numpy(E)
    for step in range(steps):
        idx = rng.choice(len(motions), min(batch, len(motions)), replace=False)
        T = max(len(motions[i]) for i in idx)
        x = torch.zeros(len(idx), T, motions[0].shape[1])
        mask = torch.zeros(len(idx), T)
        for b, i in enumerate(idx):
            x[b, : len(motions[i])] = torch.from_numpy(motions[i])
            mask[b, : len(motions[i])] = 1
        loss = ev.loss(Et[idx], x, mask)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if progress is not None:
            progress(step, float(loss.detach()))
    ev.eval()
    return ev


@torch.inference_mode()
def r_precision(ev: MotionTextEvaluator, motions: np.ndarray, E: np.ndarray, top: int = 3) -> list[float]:
    """Top-1..``top`` retrieval accuracy of each motion's own text among all the texts given (one per
    motion, same order)."""
    m = ev.embed_motion(torch.from_numpy(np.asarray(motions, np.float32)))
    t = ev.embed_text(torch.from_numpy(np.asarray(E, np.float32)))
    s = (m @ t.T).numpy()
    rank = (s > np.diag(s)[:, None]).sum(1)  # texts scoring strictly higher than the true one
    return [float((rank < k).mean()) for k in range(1, top + 1)]


EVALUATOR_KIND = "text_motion_evaluator"
EVALUATOR_VERSION = 1


def save_evaluator(path, ev: MotionTextEvaluator) -> None:
    save_checkpoint(
        path, EVALUATOR_KIND, EVALUATOR_VERSION, {"d_c": ev.text[0].in_features}, {"state": ev.state_dict()}
    )


def load_evaluator(path) -> MotionTextEvaluator:
    ck = load_checkpoint(path, EVALUATOR_KIND, EVALUATOR_VERSION)
    ev = rebuild(ck, lambda: MotionTextEvaluator(int(ck.config["d_c"])))
    load_state(ev, ck)
    ev.eval()
    return ev
