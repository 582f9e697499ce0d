"""The cGAN refiner of seed 004 §5.3.3: a generator turns a k-NN gesture (with its speech) into a refined
gesture; a critic judges (speech, gesture) pairs; WGAN-GP, the critic updated 5 times per generator step,
plus an L1 term that keeps the refined gesture near the k-NN output (weights: see
:class:`RefinerTrainConfig`). Gestures are in
the parent-relative representation (each joint minus its parent), which the seed found more stable.

* Generator: 1D U-Net on [speech (28) ; k-NN gesture (165)]: 8 [Conv-BN-ReLU] encoder blocks (kernel 3) with
  max-pooling after every second block except the last, 8 decoder blocks mirroring them with skip
  connections and nearest upsampling after every second block, the last a single convolution. It predicts a
  correction added to the k-NN gesture (starts as the identity).
* Critic: 6 [Conv, InstanceNorm, LeakyReLU] blocks with average pooling after every second block, then a
  linear layer to one score (no sigmoid).

Training pairs (:func:`knn_pairs`): for every training window, the k-NN synthesis of its own speech from a
database without its video (the seed's mix of k, for variety), beside the captured gesture (the "real"
pair).
Checkpoint ``anima.gesture_refiner`` version 1 (:func:`save_refiner` / :func:`load_refiner`).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from anima.core.contract import BODY_DIM, SPEECH_DIM
from anima.core.skeleton import PARENTS
from anima.errors import InputError
from anima.gesture.features import N_STEP
from anima.gesture.knn import search
from anima.gesture.post import finish_knn, smooth
from anima.io.checkpoint import load_checkpoint, load_state, rebuild, rebuilding, save_checkpoint

KIND = "gesture_refiner"
VERSION = 2  # 1: its own envelope; 2: anima.io.checkpoint
G_DIM = BODY_DIM


# ---- representation (pure) ------------------------------------------------------------------------


def to_parent_relative(J: np.ndarray | torch.Tensor):
    """``[..., 55, 3]`` pelvis-relative positions -> joint minus parent (the root keeps its position)."""
    par = np.where(PARENTS < 0, 0, PARENTS)
    R = J - J[..., par, :]
    R[..., PARENTS < 0, :] = J[..., PARENTS < 0, :]
    return R


def from_parent_relative(R: np.ndarray | torch.Tensor):
    """Inverse of :func:`to_parent_relative` (parents come before their children)."""
    cols = []
    for j, p in enumerate(PARENTS):
        cols.append(R[..., j, :] if p < 0 else cols[p] + R[..., j, :])
    if isinstance(R, torch.Tensor):
        return torch.stack(cols, -2)
    return np.stack(cols, -2)


# ---- networks ---------------------------------------------------------------------------------------


@dataclass
class RefinerConfig:
    # the seed's figure 5.4 gives the block layout; widths here are halved for a 2-core CPU and 2 minutes
    # of training data
    widths: tuple = (32, 32, 64, 64, 128, 128, 128, 128)
    critic_widths: tuple = (32, 32, 64, 64, 128, 128)

    def to_dict(self) -> dict:
        return {k: list(v) for k, v in asdict(self).items()}


def _block(cin, cout):
    return nn.Sequential(nn.Conv1d(cin, cout, 3, padding=1), nn.BatchNorm1d(cout), nn.ReLU())


# the 1D U-Net of seed 004 fig. 5.4, shared by the §4.4 generator (anima.gesture.generator) and this refiner


def unet_encoder(cin: int, widths) -> nn.ModuleList:
    """8 [Conv-BN-ReLU] blocks (kernel 3); :func:`unet_encode` max-pools after every second one but the last."""
    w = list(widths)
    return nn.ModuleList(_block(cin if i == 0 else w[i - 1], w[i]) for i in range(len(w)))


def unet_decoder(widths) -> nn.ModuleList:
    """Blocks mirroring the encoder, each fed the upsampled features and the skip of the same depth."""
    w = list(widths)
    dec, c = [], w[-1]
    for i in reversed(range(len(w) - 1)):
        dec.append(_block(c + w[i], w[i]))
        c = w[i]
    return nn.ModuleList(dec)


def unet_encode(enc: nn.ModuleList, x):
    """``x [B, C, T]`` (T a multiple of 8) -> (deepest features, skips)."""
    skips = []
    for i, b in enumerate(enc):
        x = b(x)
        skips.append(x)
        if i % 2 == 1 and i < len(enc) - 1:
            x = F.max_pool1d(x, 2)
    return x, skips


def unet_decode(dec: nn.ModuleList, x, skips):
    for i, b in zip(reversed(range(len(skips) - 1)), dec):
        s = skips[i]
        if x.shape[-1] != s.shape[-1]:
            x = F.interpolate(x, size=s.shape[-1], mode="nearest")
        x = b(torch.cat([x, s], 1))
    return x


class RefinerG(nn.Module):
    def __init__(self, cfg: RefinerConfig):
        super().__init__()
        self.enc = unet_encoder(SPEECH_DIM + G_DIM, cfg.widths)
        self.dec = unet_decoder(cfg.widths)
        self.final = nn.Conv1d(cfg.widths[0], G_DIM, 1)
        nn.init.zeros_(self.final.weight)
        nn.init.zeros_(self.final.bias)

    def forward(self, speech, g):
        """``speech [B, T, 28]``, ``g [B, T, 165]`` (normalised parent-relative) -> refined ``[B, T, 165]``.
        T must be a multiple of 8 (three poolings)."""
        x, skips = unet_encode(self.enc, torch.cat([speech, g], -1).transpose(1, 2))
        return g + self.final(unet_decode(self.dec, x, skips)).transpose(1, 2)


class Critic(nn.Module):
    def __init__(self, cfg: RefinerConfig):
        super().__init__()
        w = list(cfg.critic_widths)
        layers = []
        for i in range(len(w)):
            layers += [
                nn.Conv1d(SPEECH_DIM + G_DIM if i == 0 else w[i - 1], w[i], 3, padding=1),
                nn.InstanceNorm1d(w[i], affine=True),
                nn.LeakyReLU(0.2),
            ]
            if i % 2 == 1:
                layers.append(nn.AvgPool1d(2))
        self.body = nn.Sequential(*layers)
        self.fc = nn.Linear(w[-1], 1)

    def forward(self, speech, g):
        h = self.body(torch.cat([speech, g], -1).transpose(1, 2))
        return self.fc(h.mean(-1)).squeeze(-1)


def gradient_penalty(critic, speech, real, fake):
    a = torch.rand(len(real), 1, 1)
    x = (a * real + (1 - a) * fake).requires_grad_(True)
    (g,) = torch.autograd.grad(critic(speech, x).sum(), x, create_graph=True)
    return ((g.flatten(1).norm(dim=1) - 1) ** 2).mean()


# ---- data -------------------------------------------------------------------------------------------


def seed_draws(rng: np.random.Generator, n: int) -> list[int]:
    """The seed's k for ``n`` training pairs (§5.3.4): half from k = 1, half uniform over k = 2..15."""
    return [1 if j % 2 == 0 else int(rng.integers(2, 16)) for j in range(n)]


def knn_pairs(db, cfg: RefinerTrainConfig | None = None, windows=None, no_repeat_steps: int = 0):
    """(speech [N, 64, 28], k-NN gesture [N, 64, 55, 3], captured gesture [N, 64, 55, 3], window index [N]):
    each window's speech matched against a database without its own video. ``cfg.k_sampling``: ``"seed"``
    (§5.3.4: ``cfg.pairs_per_window`` syntheses per window, k = 1 for half of them and uniform over 2..15 for
    the rest, each from a random database frame's pose feature) or ``"ks"`` (one synthesis per k in
    ``cfg.ks`` from the database's mean pose feature: the :meth:`RefinerTrainConfig.anima_v1` ablation)."""
    cfg = cfg or RefinerTrainConfig()
    if db.S is None:
        raise InputError("the database has no per-frame speech features (build it with from_dataset)")
    videos = sorted({s for s, _ in db.source})
    idx = range(db.M) if windows is None else windows
    rng = np.random.default_rng(cfg.seed)
    S, K, R, W = [], [], [], []
    for i in idx:
        own = db.source[i][0]
        rest = np.array([j for j in range(db.M) if db.source[j][0] != own])
        if len(rest) == 0:
            continue
        sub = db.subset(rest)
        for k, p0 in pair_draws(sub, cfg, rng):
            G, picks = search(sub, db.F[i], min(k, len(rest) - 1), p0, no_repeat_steps=no_repeat_steps)
            g = finish_knn(G, picks, sub.bone_lengths, N_STEP)
            S.append(db.S[i])
            K.append(g)
            R.append(db.G[i].reshape(len(g), -1, 3))
            W.append(i)
    if not S:
        raise InputError(f"the k-NN refiner needs windows from at least two videos (got {len(videos)})")
    return np.stack(S), np.stack(K), np.stack(R), np.array(W)


def pair_draws(sub, cfg: RefinerTrainConfig, rng: np.random.Generator) -> list[tuple[int, np.ndarray]]:
    """(k, initial pose feature) of each training synthesis of one window (see :func:`knn_pairs`)."""
    P = sub.P.reshape(-1, sub.P.shape[-1])
    if cfg.k_sampling == "ks":
        return [(k, P.mean(0)) for k in cfg.ks]
    return [(k, P[rng.integers(len(P))]) for k in seed_draws(rng, cfg.pairs_per_window)]


# ---- training and checkpoints --------------------------------------------------------------------------


@dataclass
class RefinerTrainConfig:
    """Defaults are the seed's (§5.3.4: loss weights w1 = 0.1 (L1 to the k-NN), w2 = 1 (adversarial), w3 = 100
    (gradient penalty); k = 1 for half of the pairs, uniform 2..15 for the rest, random initial pose); only
    the number of steps is smaller (the seed: 300,000 on hours of data). :meth:`anima_v1` is another
    setting, kept as a measured ablation."""

    steps: int = 600  # generator steps
    critic_steps: int = 5
    batch: int = 16
    lr: float = 1e-4
    gp: float = 100.0  # w3
    l1: float = 0.1  # w1: weight of |G_syn - G_kNN|_1 (normalised units)
    adv: float = 1.0  # w2: weight of the critic term
    k_sampling: str = "seed"  # "seed" or "ks" (see knn_pairs)
    pairs_per_window: int = 4
    ks: tuple = (0, 1, 2, 3, 4)  # k_sampling "ks" only
    seed: int = 0
    model: dict = field(default_factory=dict)

    @classmethod
    def anima_v1(cls, **kw) -> RefinerTrainConfig:
        """The ablation's refiner: L1 10, adversarial 1, gradient penalty 10, k = 0..4 from the mean
        pose (it kept the refined output within 0.15 cm of the k-NN's)."""
        return cls(**{"gp": 10.0, "l1": 10.0, "adv": 1.0, "k_sampling": "ks", **kw})


CORRECTION_SIGMA = 1.5  # frames: the seed's temporal filter of learned outputs (§4.5), here on the correction


class Refiner:
    """Normalisation + generator: ``refine(speech [T, 28], J [T, 55, 3]) -> [T, 55, 3]`` for any T. The
    generator's correction to the k-NN gesture is smoothed in time (Gaussian, ``correction_sigma`` frames, the
    seed's filter of learned outputs) before it is added, so the captured motion's own detail is kept and the
    network's frame-to-frame noise is not (0 turns it off)."""

    def __init__(self, G: RefinerG, stats: dict, correction_sigma: float = CORRECTION_SIGMA):
        self.G = G.eval()
        self.stats = {k: np.asarray(v, np.float32) for k, v in stats.items()}
        self.correction_sigma = correction_sigma

    def _norm(self, speech, J):
        s = (speech - self.stats["s_mean"]) / self.stats["s_std"]
        g = (to_parent_relative(J).reshape(len(J), -1) - self.stats["g_mean"]) / self.stats["g_std"]
        return s.astype(np.float32), g.astype(np.float32)

    @torch.inference_mode()
    def refine(self, speech: np.ndarray, J: np.ndarray) -> np.ndarray:
        T = len(J)
        pad = (-T) % 8
        s, g = self._norm(
            np.pad(speech, ((0, pad), (0, 0)), mode="edge"), np.pad(J, ((0, pad), (0, 0), (0, 0)), mode="edge")
        )
        out = self.G(torch.from_numpy(s)[None], torch.from_numpy(g)[None])[0].numpy()[:T]
        R = (out * self.stats["g_std"] + self.stats["g_mean"]).reshape(T, -1, 3)
        refined = from_parent_relative(R)
        if self.correction_sigma > 0 and T > 1:
            refined = J + smooth(refined - J, self.correction_sigma)
        return np.asarray(refined, np.float32)


def train_refiner(db, cfg: RefinerTrainConfig, progress=None, pairs=None) -> tuple[Refiner, dict]:
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    S, K, R, W = pairs if pairs is not None else knn_pairs(db, cfg)
    rel_k = to_parent_relative(K).reshape(len(K), K.shape[1], -1)
    rel_r = to_parent_relative(R).reshape(len(R), R.shape[1], -1)
    allg = np.concatenate([rel_k, rel_r]).reshape(-1, G_DIM)
    stats = {
        "s_mean": S.reshape(-1, SPEECH_DIM).mean(0),
        "s_std": S.reshape(-1, SPEECH_DIM).std(0) + 1e-4,
        "g_mean": allg.mean(0),
        "g_std": allg.std(0) + 1e-4,
    }
    s_t = torch.from_numpy(((S - stats["s_mean"]) / stats["s_std"]).astype(np.float32))
    k_t = torch.from_numpy(((rel_k - stats["g_mean"]) / stats["g_std"]).astype(np.float32))
    r_t = torch.from_numpy(((rel_r - stats["g_mean"]) / stats["g_std"]).astype(np.float32))
    mcfg = RefinerConfig(**{k: tuple(v) for k, v in cfg.model.items()})
    G, D = RefinerG(mcfg), Critic(mcfg)
    opt_g = torch.optim.Adam(G.parameters(), lr=cfg.lr, betas=(0.5, 0.9))
    opt_d = torch.optim.Adam(D.parameters(), lr=cfg.lr, betas=(0.5, 0.9))
    n = len(s_t)
    log = {"critic": [], "generator_adv": [], "l1": []}
    t0 = time.time()
    for step in range(cfg.steps):
        for _ in range(cfg.critic_steps):
            i = torch.from_numpy(rng.integers(0, n, cfg.batch))
            with torch.no_grad():
                fake = G(s_t[i], k_t[i])
            loss_d = (
                D(s_t[i], fake).mean() - D(s_t[i], r_t[i]).mean() + cfg.gp * gradient_penalty(D, s_t[i], r_t[i], fake)
            )
            opt_d.zero_grad()
            loss_d.backward()
            opt_d.step()
        i = torch.from_numpy(rng.integers(0, n, cfg.batch))
        fake = G(s_t[i], k_t[i])
        adv = -D(s_t[i], fake).mean()
        l1 = (fake - k_t[i]).abs().mean()
        loss_g = cfg.adv * adv + cfg.l1 * l1
        opt_g.zero_grad()
        loss_g.backward()
        opt_g.step()
        log["critic"].append(round(float(loss_d.detach()), 4))
        log["generator_adv"].append(round(float(adv.detach()), 4))
        log["l1"].append(round(float(l1.detach()), 4))
        if progress is not None:
            progress(step)
    info = {
        "pairs": n,
        "windows": int(len(np.unique(W))),
        "wall_s": round(time.time() - t0, 1),
        "train_config": {**asdict(cfg), "ks": list(cfg.ks)},
        "model_config": mcfg.to_dict(),
        "log": log,
    }
    return Refiner(G, stats), info


def save_refiner(path: str | Path, ref: Refiner, info: dict) -> Path:
    config = {"model": info["model_config"], "stats": {k: v.tolist() for k, v in ref.stats.items()}}
    return save_checkpoint(
        path,
        KIND,
        VERSION,
        config,
        {"state": ref.G.state_dict()},
        {k: v for k, v in info.items() if k != "model_config"},
    )


def load_refiner(path: str | Path) -> Refiner:
    ck = load_checkpoint(path, KIND, (1, VERSION), train_hint="train one with `anima train gesture`")
    G = rebuild(ck, lambda: RefinerG(RefinerConfig(**{k: tuple(v) for k, v in ck.config["model"].items()})))
    with rebuilding(ck):
        stats = {k: np.asarray(v, np.float32) for k, v in ck.config["stats"].items()}
    load_state(G, ck)
    return Refiner(G, stats)
