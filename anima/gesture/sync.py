"""The discriminator of seed 004 §4.4 trained as an audio-gesture sync classifier (§4.6, table 4.4): is this
gesture the one that went with this speech (in sync), or one taken from another moment (off sync)?

Network: 6 [Conv1d (kernel 3), BatchNorm, ReLU] blocks on [speech (28) ; body + hands (165)] with
max-pooling after every second block, a global average, a linear layer and a sigmoid (as logits here).
Pairs are crops of L frames (16, 32 or 64 at 15 fps) of the dataset's windows: in sync = speech and gesture
of the same crop; off sync = the same speech with the gesture of a random crop of another window.
Pure torch and numpy; the evaluation runner is ``anima.eval.gesture``.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from anima.core.contract import BODY_DIM as G_DIM
from anima.core.contract import SPEECH_DIM


class SyncClassifier(nn.Module):
    def __init__(self, widths=(32, 32, 64, 64, 128, 128), in_dim: int = SPEECH_DIM + G_DIM):
        super().__init__()
        layers, cin = [], in_dim
        for i, w in enumerate(widths):
            layers += [nn.Conv1d(cin, w, 3, padding=1), nn.BatchNorm1d(w), nn.ReLU()]
            if i % 2 == 1 and i < len(widths) - 1:
                layers.append(nn.MaxPool1d(2))
            cin = w
        self.body = nn.Sequential(*layers)
        self.fc = nn.Linear(cin, 1)

    def forward(self, speech, g):
        """``speech [B, L, 28]``, ``g [B, L, D]`` (normalised) -> in-sync (or "real") logit ``[B]``. The same
        network is the §4.4 generator's discriminator (``anima.gesture.generator``)."""
        return self.fc(self.body(torch.cat([speech, g], -1).transpose(1, 2)).mean(-1)).squeeze(-1)


def make_pairs(S: np.ndarray, G: np.ndarray, L: int, n: int, rng: np.random.Generator):
    """``n`` in-sync and ``n`` off-sync crops of length ``L`` from windows ``S [M, T, 28]``, ``G [M, T, 165]``.
    Off-sync gestures come from a different window."""
    M, T = S.shape[:2]
    if M < 2:
        raise ValueError("off-sync pairs need at least two windows")
    i = rng.integers(0, M, n)
    a = rng.integers(0, T - L + 1, n)
    j = (i + rng.integers(1, M, n)) % M  # never the same window
    b = rng.integers(0, T - L + 1, n)
    s = np.stack([S[w, o : o + L] for w, o in zip(i, a)])
    pos = np.stack([G[w, o : o + L] for w, o in zip(i, a)])
    neg = np.stack([G[w, o : o + L] for w, o in zip(j, b)])
    return (
        np.concatenate([s, s]),
        np.concatenate([pos, neg]),
        np.concatenate([np.ones(n, np.float32), np.zeros(n, np.float32)]),
    )


def train_sync(S, G, L: int, steps: int = 300, batch: int = 32, seed: int = 0) -> tuple[SyncClassifier, dict]:
    """Train on windows ``S``, ``G`` (already normalised); fresh random crops every step."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = SyncClassifier()
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    for _ in range(steps):
        s, g, y = make_pairs(S, G, L, batch // 2, rng)
        loss = F.binary_cross_entropy_with_logits(net(torch.from_numpy(s), torch.from_numpy(g)), torch.from_numpy(y))
        opt.zero_grad()
        loss.backward()
        opt.step()
    net.eval()
    return net, {"final_loss": float(loss.detach())}


@torch.inference_mode()
def accuracy(net: SyncClassifier, S, G, L: int, n: int = 200, seed: int = 1) -> float:
    s, g, y = make_pairs(S, G, L, n, np.random.default_rng(seed))
    pred = net(torch.from_numpy(s), torch.from_numpy(g)).numpy() > 0
    return float((pred == (y > 0.5)).mean())
