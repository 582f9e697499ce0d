"""The speech-to-gesture generator of seed 004 ch. 4 (§4.4), its discriminator and its baselines.

Per frame at 15 fps the generator maps the 28 speech features to
* face (53): the ICT expression weights (the seed's 64 parameters of another face model),
* body (42): the 13 body joints (39) and the head orientation (axis-angle, 3), as in the seed,
* hands (126): the 2 x 21 hand joints, as in the seed.

* :class:`SpeechToGesture`: one 1D U-Net encoder (8 [Conv-BN-ReLU] blocks, kernel 3, max-pooling after every
  second block but the last) and three decoders (face, body, hands), each 7 [Conv-BN-ReLU] blocks mirroring
  the encoder with skip connections and nearest upsampling, and a final 1D convolution. Fully convolutional:
  any length of speech.
* Discriminator: the 6-block network of :class:`anima.gesture.sync.SyncClassifier` on speech + body + hands
  (the face is excluded from the adversarial term, eq. 4.2).
* :class:`LSTMBaseline`: Shlizerman et al. (2018) as the seed retrained it: three separate LSTMs (face, body,
  hands) on the speech features, with a time delay so that each output frame hears a little ahead.
* ``moglow``: a MoGlow-style normalising flow (:mod:`anima.gesture.moglow`), trained by likelihood on the
  windows with a body.
* ``velocity_adversarial``: the speech-to-gesture baseline of Ginosar et al. (2019), which the seed compares
  against: the same U-Net trained with the regression terms plus an adversarial term whose discriminator
  sees only the motion's frame-to-frame differences (no speech), weight 1 as in their paper. Their network
  read a log-mel spectrogram and predicted 2D keypoints; here it reads the same speech features and
  predicts the same 3D parts as the others, so the rows differ only in the training objective.

Losses (eq. 4.1): L_face = sum_t |face - face^|_2, L_body = sum_t |body - body^|_1, L_hand likewise, in the
data's own units (expression weights, metres, radians). The seed chose w1..w3 "to ensure that each term is
equally weighted"; its values belong to its units and face model, so here each w_i is 1 / (the term's value
for the training mean pose), measured on the training windows: every term starts at 1. The adversarial term
(eq. 4.3, non-saturating form) is added with weight ``adv_weight``. Face-only windows (talking-head clips
without a visible body) train the face decoder only.

Pure torch and numpy; checkpoints through :func:`save_generator` / :func:`load_generator`.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from anima.core.contract import GESTURE_FPS, HEAD_ROT_DIM, N_BODY_JOINTS, N_EXPR, N_HAND_JOINTS, N_JOINTS, SPEECH_DIM
from anima.core.skeleton import BODY
from anima.errors import InputError
from anima.gesture.moglow import MoGlow, fit_pca
from anima.gesture.post import one_skeleton, skeleton_lengths, smooth
from anima.gesture.refine import unet_decode, unet_decoder, unet_encode, unet_encoder
from anima.gesture.sync import SyncClassifier
from anima.io.checkpoint import load_checkpoint, load_state, rebuild, rebuilding, save_checkpoint

KIND = "gesture_generator"
VERSION = 2  # 1: its own envelope; 2: anima.io.checkpoint
PARTS = {"face": N_EXPR, "body": 3 * N_BODY_JOINTS + HEAD_ROT_DIM, "hands": 3 * 2 * N_HAND_JOINTS}
KINDS = ("adversarial", "regression", "lstm", "velocity_adversarial", "moglow")
SMOOTH_SIGMA = 1.5  # frames: the Gaussian filter seed 004 applies to its generated body, hands and head (§4.5)


# ---- representation (pure) ------------------------------------------------------------------------


def split_parts(body165: np.ndarray, face56: np.ndarray) -> dict[str, np.ndarray]:
    """Dataset window arrays ``[..., T, 165]`` (55 joints) and ``[..., T, 56]`` (53 expressions + head
    rotation) -> the generator's three parts."""
    J = body165.reshape(*body165.shape[:-1], N_JOINTS, 3)
    body = np.concatenate([J[..., BODY, :].reshape(*J.shape[:-2], 3 * N_BODY_JOINTS), face56[..., N_EXPR:]], -1)
    return {
        "face": face56[..., :N_EXPR],
        "body": body,
        "hands": J[..., N_BODY_JOINTS:, :].reshape(*J.shape[:-2], PARTS["hands"]),
    }


def join_parts(parts: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`split_parts`: -> joints ``[..., T, 55, 3]``, face ``[..., T, 56]``."""
    b, h = parts["body"], parts["hands"]
    nb = 3 * N_BODY_JOINTS
    J = np.concatenate(
        [b[..., :nb].reshape(*b.shape[:-1], N_BODY_JOINTS, 3), h.reshape(*h.shape[:-1], 2 * N_HAND_JOINTS, 3)], -2
    )
    return J, np.concatenate([parts["face"], b[..., nb:]], -1)


def part_losses(pred: dict, target: dict) -> dict:
    """Eq. 4.1's three terms per window (mean over frames): face L2 norm, body and hands L1 norms."""
    return {
        "face": (pred["face"] - target["face"]).norm(dim=-1).mean(-1),
        "body": (pred["body"] - target["body"]).abs().sum(-1).mean(-1),
        "hands": (pred["hands"] - target["hands"]).abs().sum(-1).mean(-1),
    }


# ---- networks ---------------------------------------------------------------------------------------


@dataclass
class GeneratorConfig:
    kind: str = "adversarial"
    # the seed does not list widths; these follow its reference U-Net halved for a 2-core CPU (as the refiner)
    widths: tuple = (32, 32, 64, 64, 128, 128, 128, 128)
    disc_widths: tuple = (32, 32, 64, 64, 128, 128)
    lstm_hidden: int = 128
    lstm_delay: int = 4  # frames of look-ahead for the LSTM baseline (0.27 s at 15 fps)
    fps: float = GESTURE_FPS  # the frame rate of its training windows (the speech features are taken at it)
    # the MoGlow-style baseline (anima.gesture.moglow), sized for minutes of data; not tuned here
    flow_dim: int = 32  # principal components of the 221-value pose
    flow_steps: int = 8
    flow_hidden: int = 128
    history: int = 5  # previous poses in the condition (MoGlow's tau)
    speech_past: int = 5  # speech frames before and after each frame in the condition (0.33 s, 1 s at 15 fps)
    speech_future: int = 15
    history_dropout: float = 0.75
    temperature: float = 1.0

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: dict) -> GeneratorConfig:
        return cls(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()})


class SpeechToGesture(nn.Module):
    def __init__(self, cfg: GeneratorConfig):
        super().__init__()
        self.enc = unet_encoder(SPEECH_DIM, cfg.widths)
        self.dec = nn.ModuleDict({p: unet_decoder(cfg.widths) for p in PARTS})
        self.final = nn.ModuleDict({p: nn.Conv1d(cfg.widths[0], d, 1) for p, d in PARTS.items()})

    def forward(self, speech):
        """``speech [B, T, 28]`` (normalised, T a multiple of 8) -> {part: [B, T, dim]} (normalised)."""
        x, skips = unet_encode(self.enc, speech.transpose(1, 2))
        return {p: self.final[p](unet_decode(self.dec[p], x, skips)).transpose(1, 2) for p in PARTS}


class LSTMBaseline(nn.Module):
    def __init__(self, cfg: GeneratorConfig):
        super().__init__()
        self.delay = cfg.lstm_delay
        self.lstm = nn.ModuleDict({p: nn.LSTM(SPEECH_DIM, cfg.lstm_hidden, batch_first=True) for p in PARTS})
        self.out = nn.ModuleDict({p: nn.Linear(cfg.lstm_hidden, d) for p, d in PARTS.items()})

    def forward(self, speech):
        # time delay: the output at t has heard the speech up to t + delay
        x = torch.cat([speech[:, self.delay :], speech[:, -1:].expand(-1, self.delay, -1)], 1) if self.delay else speech
        return {p: self.out[p](self.lstm[p](x)[0]) for p in PARTS}


def build_model(cfg: GeneratorConfig) -> nn.Module:
    if cfg.kind not in KINDS:
        raise InputError(f"unknown generator kind {cfg.kind!r}: one of {', '.join(KINDS)}")
    if cfg.kind == "moglow":
        return MoGlow(cfg, PARTS, SPEECH_DIM)
    return LSTMBaseline(cfg) if cfg.kind == "lstm" else SpeechToGesture(cfg)


# ---- inference wrapper ---------------------------------------------------------------------------------


class GestureGenerator:
    """Normalisation + network: ``generate(speech [T, 28]) -> (joints [T, 55, 3], face [T, 56])``."""

    def __init__(self, net: nn.Module, cfg: GeneratorConfig, stats: dict):
        self.net = net.eval()
        self.cfg = cfg
        self.stats = {k: np.asarray(v, np.float32) for k, v in stats.items()}
        self.postprocess = True

    @property
    def fps(self) -> float:
        return float(self.cfg.fps)

    @torch.inference_mode()
    def generate(self, speech: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``seed``: the sampling seed of the stochastic MoGlow-style baseline (the others are deterministic)."""
        T = len(speech)
        if T == 0:
            raise InputError("no speech frames to generate from")
        pad = (-T) % 8
        s = np.pad(speech, ((0, pad), (0, 0)), mode="edge")
        s = ((s - self.stats["speech_mean"]) / self.stats["speech_std"]).astype(np.float32)
        x = torch.from_numpy(s)[None]
        out = self.net(x, seed=seed) if self.cfg.kind == "moglow" else self.net(x)
        parts = {p: out[p][0].numpy()[:T] * self.stats[f"{p}_std"] + self.stats[f"{p}_mean"] for p in PARTS}
        parts["face"] = np.clip(parts["face"], 0, 1)
        J, face = join_parts(parts)
        if self.postprocess:  # the seed's temporal filter (§4.5) and one skeleton: the training data's
            J = smooth(J, SMOOTH_SIGMA)
            face[:, N_EXPR:] = smooth(face[:, N_EXPR:], SMOOTH_SIGMA)
            lengths = self.stats.get("bone_lengths")
            J = one_skeleton(J, lengths if lengths is not None else skeleton_lengths(J))
        return J.astype(np.float32), face.astype(np.float32)


# ---- training ---------------------------------------------------------------------------------------


@dataclass
class GeneratorTrainConfig:
    steps: int = 1000  # the seed: 300,000 per subject on hours of data
    batch: int = 25
    lr: float = 5e-4
    adv_weight: float = 0.1
    velocity_adv_weight: float = 1.0  # the velocity-adversarial baseline's (Ginosar et al. 2019: lambda = 1)
    seed: int = 0


def part_stats(S: np.ndarray, parts: dict, has_body: np.ndarray, body: np.ndarray | None = None) -> dict:
    st = {"speech_mean": S.reshape(-1, SPEECH_DIM).mean(0), "speech_std": S.reshape(-1, SPEECH_DIM).std(0) + 1e-4}
    for p, d in PARTS.items():
        x = parts[p] if p == "face" else parts[p][has_body]
        x = x.reshape(-1, d)
        st[f"{p}_mean"], st[f"{p}_std"] = x.mean(0), x.std(0) + 1e-4
    if body is not None and has_body.any():  # the skeleton every output is re-posed on
        st["bone_lengths"] = skeleton_lengths(body[has_body].reshape(-1, body.shape[1], N_JOINTS, 3))
    return st


def train_generator(
    S: np.ndarray, body: np.ndarray, face: np.ndarray, model: GeneratorConfig, cfg: GeneratorTrainConfig, progress=None
) -> tuple[GestureGenerator, dict]:
    """``S [N, T, 28]``, ``body [N, T, 165]`` (all NaN for a face-only window), ``face [N, T, 56]``; T a
    multiple of 8."""
    if len(S) == 0:
        raise InputError("no training windows")
    if S.shape[1] % 8:
        raise InputError(f"training windows must be a multiple of 8 frames long (got {S.shape[1]})")
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    has_body = np.isfinite(body).all((1, 2))
    if not has_body.any():
        raise InputError("no training window has a tracked body and hands")
    parts = split_parts(np.where(has_body[:, None, None], body, 0.0), face)
    stats = part_stats(S, parts, has_body, body)
    # w_i: 1 / (each term for the training mean pose), in the data's units (see the module doc)
    mean_pred = {p: torch.from_numpy(np.broadcast_to(stats[f"{p}_mean"], parts[p].shape).copy()) for p in PARTS}
    tgt_raw = {p: torch.from_numpy(parts[p].astype(np.float32)) for p in PARTS}
    l0 = part_losses(mean_pred, tgt_raw)
    hb = torch.from_numpy(has_body)
    weights = {p: float(1.0 / max(float(l0[p].mean() if p == "face" else l0[p][hb].mean()), 1e-8)) for p in PARTS}
    s_t = torch.from_numpy(((S - stats["speech_mean"]) / stats["speech_std"]).astype(np.float32))
    std = {p: torch.from_numpy(stats[f"{p}_std"]) for p in PARTS}
    mean = {p: torch.from_numpy(stats[f"{p}_mean"]) for p in PARTS}
    y_t = {p: (tgt_raw[p] - mean[p]) / std[p] for p in PARTS}
    if model.kind == "moglow":
        return _train_moglow(s_t, y_t, has_body, model, cfg, stats, progress)
    net = build_model(model)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    adversarial = model.kind in ("adversarial", "velocity_adversarial")
    velocity = model.kind == "velocity_adversarial"  # Ginosar et al.: D sees motion differences, no speech
    if adversarial:
        D = SyncClassifier(model.disc_widths, (0 if velocity else SPEECH_DIM) + PARTS["body"] + PARTS["hands"])
        opt_d = torch.optim.Adam(D.parameters(), lr=cfg.lr)
    adv_weight = cfg.velocity_adv_weight if velocity else cfg.adv_weight
    body_idx = np.flatnonzero(has_body)
    log = {"face": [], "body": [], "hands": [], "adv": [], "disc": []}
    t0 = time.time()
    net.train()
    for step in range(cfg.steps):
        i = torch.from_numpy(rng.integers(0, len(S), cfg.batch))
        out = net(s_t[i])
        raw = {p: out[p] * std[p] + mean[p] for p in PARTS}
        terms = part_losses(raw, {p: tgt_raw[p][i] for p in PARTS})
        m = hb[i].float()
        lf = terms["face"].mean()
        lb = (terms["body"] * m).sum() / m.sum().clamp(min=1)
        lh = (terms["hands"] * m).sum() / m.sum().clamp(min=1)
        loss = weights["face"] * lf + weights["body"] * lb + weights["hands"] * lh
        if adversarial:
            j = torch.from_numpy(rng.choice(body_idx, cfg.batch))
            fake_out = net(s_t[j])
            fake = torch.cat([fake_out["body"], fake_out["hands"]], -1)
            real = torch.cat([y_t["body"][j], y_t["hands"][j]], -1)
            cond = s_t[j]
            if velocity:
                fake, real = fake[:, 1:] - fake[:, :-1], real[:, 1:] - real[:, :-1]
                cond = cond[:, 1:, :0]  # no speech
            d_real, d_fake = D(cond, real), D(cond, fake.detach())
            loss_d = F.binary_cross_entropy_with_logits(
                d_real, torch.ones_like(d_real)
            ) + F.binary_cross_entropy_with_logits(d_fake, torch.zeros_like(d_fake))
            opt_d.zero_grad()
            loss_d.backward()
            opt_d.step()
            g_fake = D(cond, fake)
            adv = F.binary_cross_entropy_with_logits(g_fake, torch.ones_like(g_fake))
            loss = loss + adv_weight * adv
            log["adv"].append(round(float(adv.detach()), 4))
            log["disc"].append(round(float(loss_d.detach()), 4))
        opt.zero_grad()
        loss.backward()
        opt.step()
        log["face"].append(round(float(lf.detach()), 5))
        log["body"].append(round(float(lb.detach()), 5))
        log["hands"].append(round(float(lh.detach()), 5))
        if progress is not None:
            progress(step)
    net.eval()
    info = {
        "windows": int(len(S)),
        "body_windows": int(has_body.sum()),
        "wall_s": round(time.time() - t0, 1),
        "loss_weights": {"w1_face": weights["face"], "w2_body": weights["body"], "w3_hands": weights["hands"]},
        "train_config": asdict(cfg),
        "log": log,
    }
    return GestureGenerator(net, model, stats), info


def _train_moglow(s_t, y_t, has_body, model: GeneratorConfig, cfg: GeneratorTrainConfig, stats, progress):
    """The MoGlow-style baseline by exact likelihood on the windows with a body (the flow models face, body
    and hands together, so face-only windows cannot train it)."""
    hb = np.flatnonzero(has_body)
    Y = torch.cat([y_t[p] for p in PARTS], -1)[hb]
    S = s_t[hb]
    pca_mean, basis = fit_pca(Y.reshape(-1, Y.shape[-1]).numpy().astype(np.float64), model.flow_dim)
    net = MoGlow(model, PARTS, SPEECH_DIM, pca_mean, basis)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    rng = np.random.default_rng(cfg.seed)
    g = torch.Generator().manual_seed(cfg.seed)
    log = {"nll": []}
    t0 = time.time()
    net.train()
    for step in range(cfg.steps):
        i = torch.from_numpy(rng.integers(0, len(Y), cfg.batch))
        loss = net.nll(Y[i], S[i], g)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 5.0)
        opt.step()
        log["nll"].append(round(float(loss.detach()), 4))
        if progress is not None:
            progress(step)
    net.eval()
    var = Y.reshape(-1, Y.shape[-1]).var(0).sum()
    kept = ((torch.as_tensor(basis).T @ (Y.reshape(-1, Y.shape[-1]) - torch.as_tensor(pca_mean)).T) ** 2).sum()
    info = {
        "windows": int(len(s_t)),
        "body_windows": int(len(hb)),
        "wall_s": round(time.time() - t0, 1),
        "loss_weights": {},
        "pca_variance_kept": round(float(kept / (var * (len(Y) * Y.shape[1] - 1))), 4),
        "train_config": asdict(cfg),
        "log": log,
    }
    return GestureGenerator(net, model, stats), info


def save_generator(path, gen: GestureGenerator, info: dict):
    config = {"model": gen.cfg.to_dict(), "stats": {k: v.tolist() for k, v in gen.stats.items()}}
    return save_checkpoint(path, KIND, VERSION, config, {"state": gen.net.state_dict()}, info)


def load_generator(path) -> GestureGenerator:
    ck = load_checkpoint(path, KIND, (1, VERSION), train_hint="train one with `anima train gesture --model generator`")
    with rebuilding(ck):
        cfg = GeneratorConfig.from_dict(ck.config["model"])
    net = rebuild(ck, lambda: build_model(cfg))
    with rebuilding(ck):
        stats = dict(ck.config["stats"])
    load_state(net, ck)
    return GestureGenerator(net, cfg, stats)
