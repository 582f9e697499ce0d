"""Training of the lifter (seed 004 eqs. 3.3-3.8) on Human3.6M projections (3D labels) and MediaPipe
detections on in-the-wild videos (2D labels only). Resumable; checkpoints carry their config.

Per step, a 3D batch and (when ``wild`` is on) a 2D-only batch:
* 3D batch: ground-truth camera-frame poses of the training subjects projected through their real cameras,
  corrupted like a detector (per-sample noise level, per-joint Gaussian noise, dropped joints with b_k = 0,
  occasionally the legs cut off as in upper-body framing), mirrored half of the time. Losses: L_3Dpose (10),
  L_bone with bone vectors (10), L_2Dheatmap on h_2D against the clean 2D (0.1), L_2Dpose on the projection
  against the clean 2D (10).
* 2D-only batch: MediaPipe keypoints; L_2Dheatmap against the detection itself (0.1, masked by b_k),
  L_2Dpose against the detection (10, masked), L_bone on squared bone lengths against a random training
  subject's lengths (100, eq. 3.6).
Units: 3D in metres (``pose_scale``), 2D in torso heights; the seed's weights are kept as the defaults
(they act on different units than the seed's pixels and millimetres; see the ablation for what each term
does here).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from anima.errors import CheckpointError
from anima.io.checkpoint import load_checkpoint as load_checkpoint_file
from anima.io.checkpoint import load_state, looks_like_checkpoint, rebuild
from anima.io.checkpoint import save_checkpoint as save_checkpoint_file
from anima.io.outdir import check_out_file
from anima.pose3d.config import LifterConfig, TrainConfig
from anima.pose3d.data import (
    TEST_SUBJECTS,
    TRAIN_SUBJECTS,
    load_h36m,
    normalise_2d,
    subject_bone_lengths,
    wild_evidence,
)
from anima.pose3d.joints import BONES, FLIP, K
from anima.pose3d.model import Lifter

KIND = "pose_lifter"
VERSION = 2  # 1: the pose lifter's own envelope (loaded with pickles); 2: anima.io.checkpoint
LEGS = np.array([2, 3, 5, 6])


def _corrupt(uv: np.ndarray, rng: np.random.Generator, cfg: TrainConfig, torso: np.ndarray):
    B = len(uv)
    sig = rng.uniform(0, cfg.noise_max, (B, 1, 1)) * torso[:, None, None]
    noisy = uv + rng.normal(size=uv.shape) * sig
    conf = np.ones((B, K), np.float32)
    conf[rng.random((B, K)) < cfg.drop_joint] = 0
    legs = rng.random(B) < cfg.drop_legs
    conf[np.ix_(legs, LEGS)] = 0
    conf[:, 0] = 1.0  # the root is always given (hips are always estimated by MediaPipe)
    conf *= rng.uniform(0.6, 1.0, (B, K)).astype(np.float32) ** (conf > 0)
    return noisy, conf


def _flip2d(uv):
    out = uv[:, FLIP].copy()
    out[..., 0] *= -1
    return out


class _Batches:
    def __init__(self, cfg: TrainConfig, cache: Path, progress: bool):
        self.cfg = cfg
        assert not set(TEST_SUBJECTS) & set(TRAIN_SUBJECTS)
        h = load_h36m(TRAIN_SUBJECTS, cfg.every)
        if set(h.subject.tolist()) & set(TEST_SUBJECTS):
            raise RuntimeError("test subject in the training set")
        self.J = h.joints_cam - h.joints_cam[:, :1]
        self.uv = h.uv.astype(np.float64)
        self.bones = np.stack(list(subject_bone_lengths().values())) / 1000.0  # (S, 16) metres
        self.wild = wild_evidence(cache, progress=progress) if cfg.wild else None
        self.rng = np.random.default_rng(cfg.seed)

    def h36m(self):
        c, r = self.cfg, self.rng
        i = r.integers(0, len(self.J), c.batch)
        uv, J = self.uv[i], self.J[i].astype(np.float64) / 1000.0
        _, torso = normalise_2d(uv)
        noisy, conf = _corrupt(uv, r, c, torso)
        flip = r.random(c.batch) < 0.5
        uv_n, t = normalise_2d(noisy)
        clean = (uv - noisy[:, :1]) / t[:, None, None]
        uv_n[flip], clean[flip] = _flip2d(uv_n[flip]), _flip2d(clean[flip])
        J[flip] = J[flip][:, FLIP] * [-1, 1, 1]
        conf[flip] = conf[flip][:, FLIP]
        f = lambda a: torch.as_tensor(a, dtype=torch.float32)
        return f(uv_n), f(conf), f(clean), f(J)

    def wild_batch(self):
        c, r, w = self.cfg, self.rng, self.wild
        i = r.integers(0, len(w["uv"]), c.batch_wild)
        uv, conf = w["uv"][i].astype(np.float64), w["conf"][i].astype(np.float32)
        uv_n, _ = normalise_2d(uv)
        flip = r.random(c.batch_wild) < 0.5
        uv_n[flip] = _flip2d(uv_n[flip])
        conf[flip] = conf[flip][:, FLIP]
        conf = np.where(conf >= 0.5, conf, 0.0).astype(np.float32)  # b_k: unreliable joints are masked
        L = self.bones[r.integers(0, len(self.bones), c.batch_wild)]
        f = lambda a: torch.as_tensor(a, dtype=torch.float32)
        return f(uv_n), f(conf), f(L)


def _bone_vec(P):
    return P[:, BONES[:, 0]] - P[:, BONES[:, 1]]


def losses(model: Lifter, cfg: TrainConfig, b3d, bwild=None) -> dict[str, torch.Tensor]:
    """The terms of eq. 3.8 (each already weighted) for one step. The 3D and the 2D-only samples go through
    the network as one batch, so BatchNorm sees one mixed distribution in training as at test time."""
    uv, conf, clean, J = b3d
    B = len(uv)
    use_wild = bwild is not None and (cfg.latent_2d or cfg.projection)
    if use_wild:
        uvw, cw, lengths = bwild
        out_all = model(torch.cat([uv, uvw]), torch.cat([conf, cw]))
        out = {k: v[:B] for k, v in out_all.items()}
        ow = {k: v[B:] for k, v in out_all.items()}
    else:
        out = model(uv, conf)
    L = {"3d": cfg.w_3d * ((out["p3d"] - J) ** 2).sum(-1).mean()}
    if cfg.bone:
        L["bone"] = cfg.w_bone * ((_bone_vec(out["p3d"]) - _bone_vec(J)) ** 2).sum(-1).mean()
    if cfg.latent_2d:
        L["heat"] = cfg.w_heat * ((out["h2d"] - clean) ** 2).sum(-1).mean()
    if cfg.projection:
        L["2d"] = cfg.w_2d * ((out["proj"] - clean) ** 2).sum(-1).mean()
    if use_wild:
        m = (cw > 0).float()  # b_k
        n = m.sum().clamp(min=1)
        if cfg.latent_2d:
            L["heat_wild"] = cfg.w_heat * (m * ((ow["h2d"] - uvw) ** 2).sum(-1)).sum() / n
        if cfg.projection:
            L["2d_wild"] = cfg.w_2d * (m * ((ow["proj"] - uvw) ** 2).sum(-1)).sum() / n
            if cfg.bone:
                bl = (_bone_vec(ow["p3d"]) ** 2).sum(-1)
                L["bone_wild"] = cfg.w_bone_2d * ((bl - lengths**2) ** 2).mean()
    return L


def save_checkpoint(path: Path, model: Lifter, cfg: TrainConfig, step: int, opt=None, extra: dict | None = None):
    tensors = {"state": model.state_dict()}
    if opt is not None:
        tensors["optimizer"] = opt.state_dict()
    save_checkpoint_file(path, KIND, VERSION, asdict(cfg), tensors, {"step": step, "extra": extra or {}})


def load_checkpoint(path: Path) -> tuple[Lifter, dict]:
    """(model, checkpoint dict with ``config``, ``step``, ``state_dict``, ``optimizer``, ``extra``)."""
    ck = load_checkpoint_file(path, KIND, (1, VERSION), train_hint=f"train one with `anima train pose --out {path}`")
    model = rebuild(ck, lambda: Lifter(LifterConfig(**ck.config["model"])))
    load_state(model, ck)
    model.eval()
    return model, {
        "format": KIND,
        "version": ck.version,
        "config": ck.config,
        "step": ck.info.get("step", 0),
        "state_dict": ck.state,
        "optimizer": ck.tensors.get("optimizer"),
        "extra": ck.info.get("extra", {}),
    }


def train(
    cfg: TrainConfig,
    out: Path,
    cache: Path,
    progress: bool = True,
    resume: bool = True,
    log_every: int = 100,
    eval_fn=None,
) -> tuple[Lifter, dict]:
    """Train (or resume) to ``cfg.steps``; writes ``out`` (checkpoint) every 500 steps and at the end."""
    from tqdm import tqdm

    torch.manual_seed(cfg.seed)
    model = Lifter(LifterConfig(**cfg.model))
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    gamma = cfg.lr_decay ** (1.0 / max(cfg.steps, 1))
    start = 0
    out = check_out_file(out, suffixes=(".pt",), ours=looks_like_checkpoint, what="a checkpoint")
    if resume and out.exists():
        _, ck = load_checkpoint(out)
        mine = json.loads(json.dumps(asdict(cfg)))
        same = {k: v for k, v in ck["config"].items() if k != "steps"} == {
            k: v for k, v in mine.items() if k != "steps"
        }
        if not same:
            raise CheckpointError(f"{out} was trained with another configuration; use a new --out or --no-resume")
        model.load_state_dict(ck["state_dict"])
        if ck.get("optimizer"):
            opt.load_state_dict(ck["optimizer"])
        start = ck["step"]
    data = _Batches(cfg, cache, progress)
    data.rng = np.random.default_rng([cfg.seed, start])
    for g in opt.param_groups:
        g["lr"] = cfg.lr * gamma**start
    model.train()
    hist = []
    t0 = time.perf_counter()
    bar = tqdm(
        range(start, cfg.steps),
        desc="train pose lifter",
        disable=not progress,
        unit="step",
        initial=start,
        total=cfg.steps,
    )
    for step in bar:
        L = losses(model, cfg, data.h36m(), data.wild_batch() if cfg.wild else None)
        total = sum(L.values())
        opt.zero_grad()
        total.backward()
        opt.step()
        for g in opt.param_groups:
            g["lr"] *= gamma
        if (step + 1) % log_every == 0 or step + 1 == cfg.steps:
            rec = {"step": step + 1, **{k: float(v.detach()) for k, v in L.items()}}
            hist.append(rec)
            bar.set_postfix(loss=f"{float(total.detach()):.4f}")
        if (step + 1) % 500 == 0 and step + 1 < cfg.steps:
            save_checkpoint(out, model, cfg, step + 1, opt)
    model.eval()
    info = {
        "seconds": time.perf_counter() - t0,
        "history": hist,
        "data": {
            "h36m_train_samples": int(len(data.J)),
            "wild_frames": int(len(data.wild["uv"])) if data.wild is not None else 0,
        },
    }
    save_checkpoint(out, model, cfg, cfg.steps, opt, info)
    return model, info


def predict(model: Lifter, uv_px: np.ndarray, conf: np.ndarray, batch: int = 4096) -> np.ndarray:
    """Pixels ``(N, 17, 2)`` + confidences -> root-relative camera-frame 3D ``(N, 17, 3)`` mm."""
    uv_n, _ = normalise_2d(np.asarray(uv_px, np.float64))
    conf = np.where(np.asarray(conf) >= 0.5, conf, 0.0)
    out = []
    model.eval()
    with torch.no_grad():
        for s in range(0, len(uv_n), batch):
            out.append(
                model.predict_mm(
                    torch.as_tensor(uv_n[s : s + batch], dtype=torch.float32),
                    torch.as_tensor(conf[s : s + batch], dtype=torch.float32),
                ).numpy()
            )
    return np.concatenate(out) if out else np.zeros((0, K, 3), np.float32)


def summary_json(info: dict) -> str:
    return json.dumps({k: v for k, v in info.items() if k != "history"}, indent=2)
