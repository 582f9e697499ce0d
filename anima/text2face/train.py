"""Training of the text -> face models (seed 000 §6.3, §7.1) and their checkpoints.

``train(dataset, out, TrainConfig(...))`` trains the seed's model (``kind="text2face"``, teacher forcing by
default, ``scheme="autoregressive"`` for the FaceFormer ablation), the MDM-style diffusion baseline
(``kind="mdm"``) or the StableMoFusion-style one (``kind="smf"``) on the same crops, with the same loss: the
z-normalised vertex-offset MSE of the face region (through the 53x53 Gram matrix of
:class:`anima.text2face.data.FaceGeometry`) plus the MSE of the z-normalised head rotation, masked over
padding (eq. 6.2), plus the VQ loss (eq. 6.3) for the cVQVAE.

Checkpoints are :mod:`anima.io.checkpoint` files of kind ``text2face``, ``mdm`` or ``smf``, version 2: config (model
and training config, normalisation mean and std, the loss Gram matrix, step), weights, optimizer state
(absent in a compact export, whose weights are float16) and info (data fingerprint, command, losses, wall
time). Training resumes from ``out/checkpoint.pt``.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from anima.core.contract import N_EXPR, TEXT_FPS
from anima.dataset import splits
from anima.errors import InputError, SchemaError
from anima.io.checkpoint import load_checkpoint as load_checkpoint_file
from anima.io.checkpoint import load_state, rebuild, rebuilding
from anima.io.checkpoint import save_checkpoint as save_checkpoint_file
from anima.io.outdir import claim_folder
from anima.io.validate import read_json
from anima.text2face.config import TrainConfig
from anima.text2face.data import FaceGeometry, crop_pool, load_clips, motion_stats, split_clips
from anima.text2face.diffusion import MDM, SMF, MDMConfig, SMFConfig
from anima.text2face.encoders import encode_cached, get_encoder
from anima.text2face.model import Text2Face, Text2FaceConfig, preset

KINDS = ("text2face", "mdm", "smf")
VERSION = 2  # 1: text2face's own envelope; 2: anima.io.checkpoint


def fingerprint(clips) -> str:
    h = hashlib.sha256()
    for c in sorted(clips, key=lambda c: c.clip_id):
        h.update(c.clip_id.encode())
        h.update(np.ascontiguousarray(c.motion).tobytes())
    return h.hexdigest()[:16]


def build_model(kind: str, model_cfg: dict):
    if kind == "text2face":
        return Text2Face(Text2FaceConfig(**model_cfg))
    if kind == "mdm":
        return MDM(MDMConfig(**model_cfg))
    if kind == "smf":
        return SMF(SMFConfig(**model_cfg))
    raise SchemaError(f"unknown model kind {kind!r}")


def model_config(cfg: TrainConfig, d_c: int) -> dict:
    base = dict(d_c=d_c, max_len=cfg.max_len, min_len=cfg.min_len, encoder=cfg.encoder)
    if cfg.kind == "text2face":
        return preset(cfg.preset, **base, **cfg.model).to_dict()
    return (MDMConfig if cfg.kind == "mdm" else SMFConfig)(**{**base, **cfg.model}).to_dict()


def rec_loss(pred, target, mask, std, G, w_rot: float):
    """Masked mean over frames of the z-normalised vertex-offset MSE + ``w_rot`` x head-rotation MSE."""
    d = pred - target
    de = d[..., :N_EXPR] * std[:N_EXPR]
    vert = torch.einsum("bti,ij,btj->bt", de, G, de)
    rot = d[..., N_EXPR:].pow(2).mean(-1)
    per = vert + w_rot * rot
    return (per * mask).sum() / mask.sum().clamp(min=1)


# ---- checkpoints -----------------------------------------------------------------------------------


def save_checkpoint(
    path: Path,
    *,
    kind,
    model,
    train_cfg: TrainConfig,
    stats,
    gram,
    step,
    opt=None,
    info=None,
    compact=False,
    fps: float = TEXT_FPS,
) -> Path:
    state = {k: (v.half() if compact and v.is_floating_point() else v) for k, v in model.state_dict().items()}
    tensors = {"state": state}
    if opt is not None and not compact:
        tensors["optimizer"] = opt.state_dict()
    config = {
        "model": model.cfg.to_dict(),
        "train": asdict(train_cfg),
        "mean": stats[0].tolist(),
        "std": stats[1].tolist(),
        "gram": np.asarray(gram).tolist(),
        "step": step,
        "fps": fps,
    }
    return save_checkpoint_file(path, kind, VERSION, config, tensors, info or {})


def load_checkpoint(path: str | Path) -> dict:
    """The checkpoint as a dict (kind, model_config, train_config, mean, std, gram, step, state, optim, info)
    with the rebuilt model under ``model``."""
    ck = load_checkpoint_file(path, KINDS, (1, VERSION), train_hint="train one with `anima train text2face`")
    c = ck.config
    model = rebuild(ck, lambda: build_model(ck.kind, c["model"]))
    with rebuilding(ck):
        for k in ("train", "mean", "std", "gram", "step"):
            c[k]
    load_state(model, ck)
    model.eval()
    return {
        "kind": ck.kind,
        "version": ck.version,
        "model_config": c["model"],
        "train_config": c["train"],
        "mean": c["mean"],
        "std": c["std"],
        "gram": c["gram"],
        "step": c["step"],
        "state": ck.state,
        "optim": ck.tensors.get("optimizer"),
        "info": ck.info,
        "model": model,
        "path": ck.path,
        "fps": float(c.get("fps", TEXT_FPS)),
    }


# ---- training --------------------------------------------------------------------------------------


def prepare(dataset: str | Path, cfg: TrainConfig):
    clips = load_clips(dataset)
    train_clips, held = split_clips(clips)
    pool = crop_pool(train_clips, cfg.per_clip, cfg.min_len, cfg.max_len, cfg.seed)
    enc = get_encoder(cfg.encoder)
    texts = sorted({it.text for it in pool})
    emb = dict(zip(texts, encode_cached(enc, texts)))
    E = np.stack([emb[it.text] for it in pool])
    stats = motion_stats(pool)
    gram = FaceGeometry().gram(np.concatenate([it.motion[:, :N_EXPR] for it in pool]))
    return clips, pool, E, stats, gram, enc


def training_videos(dataset: str | Path, clips) -> list[str]:
    """The training clips' videos by key path (the dataset manifest's split table, :mod:`anima.dataset.splits`),
    so what a model saw can be checked on any copy of the data; a dataset built before the table: video ids."""
    man = Path(dataset) / "manifest.json"
    table = read_json(man, "dataset manifest").get("split_table", {}) if man.is_file() else {}
    return sorted({table.get(c.video_id, {}).get("key_path", c.video_id) for c in clips if c.split == "train"})


def _resume(ck_path: Path, cfg: TrainConfig, model, opt) -> tuple[int, list, float]:
    """``(step, losses, seconds)`` of the checkpoint at ``ck_path``, its model and optimiser state loaded, when it
    was trained with ``cfg`` (to at most ``cfg.steps``: resumed or extended); InputError otherwise."""
    ck = load_checkpoint(ck_path)
    mine = json.loads(json.dumps(asdict(cfg)))
    same = {**ck["train_config"], "steps": cfg.steps, "ckpt_every": cfg.ckpt_every} == mine
    if ck["kind"] == cfg.kind and same and ck.get("optim") and ck["step"] <= cfg.steps:  # resume or extend
        model.load_state_dict(ck["state"])
        opt.load_state_dict(ck["optim"])
        return ck["step"], ck["info"].get("losses", []), ck["info"].get("wall_s", 0.0)
    raise InputError(
        f"{ck_path} exists but was trained with another configuration (or further than --steps); use another --out"
    )


def _padded_batch(motions: list, idx) -> tuple[torch.Tensor, torch.Tensor]:
    """The motions ``idx`` zero-padded to the longest ``[B, T, C]`` and their mask ``[B, T]`` (1 where real)."""
    T = max(len(motions[i]) for i in idx)
    x = torch.zeros(len(idx), T, motions[0].shape[1])
    mask = torch.zeros(len(idx), T)
    for b, i in enumerate(idx):
        x[b, : len(motions[i])] = motions[i]
        mask[b, : len(motions[i])] = 1
    return x, mask


def _text2face_loss(model, cfg: TrainConfig, step: int, E_t, idx, code, x, mask, std_t, G) -> torch.Tensor:
    """One step's loss of the text2face model: its dead codes restarted every ``cfg.restart_every`` steps
    (stateless: a resumed run restarts them alike), then teacher-forced (``x`` noised and dropped as ``cfg``
    says) or rolled out, the reconstruction loss plus the quantiser's."""
    if cfg.restart_every and step % cfg.restart_every == 0:  # stateless: resumes exactly
        with torch.no_grad():
            used = model.guide.quantize(model.guide.enc(E_t))[1]
        model.guide.restart_codes(
            E_t,
            torch.bincount(used, minlength=model.cfg.N_emb),
            torch.Generator().manual_seed(cfg.seed * 7919 + step),
        )
    if cfg.fresh_codes:
        code = torch.randn(len(idx), code.shape[1])
    if cfg.scheme == "teacher":
        xin = x + cfg.tf_noise * torch.randn_like(x) if cfg.tf_noise else x
        if cfg.tf_drop:
            xin = xin * (torch.rand(x.shape[:2]) >= cfg.tf_drop)[..., None]
        pred, vq = model(E_t[idx], code, xin)
    else:
        pred, vq = model._rollout(E_t[idx], code, x.shape[1], cached=True)
    return rec_loss(pred, x, mask, std_t, G, cfg.w_rot) + vq


def train(
    dataset: str | Path, out: str | Path, cfg: TrainConfig, progress: bool = True, command: str = "", prepared=None
) -> dict:
    out = claim_folder(out, "text2face_run", inputs=[dataset])  # a user's folder is refused before any work
    ck_path = out / "checkpoint.pt"
    torch.manual_seed(cfg.seed)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    clips, pool, E, stats, gram, enc = prepared or prepare(dataset, cfg)
    mcfg = model_config(cfg, enc.dim)
    model = build_model(cfg.kind, mcfg)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    step, losses, wall0 = _resume(ck_path, cfg, model, opt) if ck_path.is_file() else (0, [], 0.0)
    std_t, G = torch.tensor(stats[1]), torch.tensor(gram)
    d_r = mcfg.get("d_r", 0)
    codes = torch.from_numpy(
        np.random.default_rng(cfg.seed + 1).standard_normal((len(pool), max(d_r, 1))).astype(np.float32)
    )
    E_t = torch.from_numpy(E)
    motions = [torch.from_numpy((it.motion - stats[0]) / stats[1]) for it in pool]
    fp = fingerprint(clips)
    t0 = time.time()
    model.train()

    def info():
        return {
            "data_fingerprint": fp,
            "dataset": str(dataset),
            "command": command,
            "losses": losses,
            "wall_s": wall0 + time.time() - t0,
            "train_items": len(pool),
            "train_clips": sum(c.split == "train" for c in clips),
            # what the model saw, checkable against any copy of the data (key paths, anima.dataset.splits)
            "train_videos": training_videos(dataset, clips),
            "split_rule": splits.rule(),
            "torch": str(torch.__version__),
        }

    bar = tqdm(total=cfg.steps, initial=step, desc=f"train {cfg.kind}", unit="step", disable=not progress)
    while step < cfg.steps:
        # every step draws from its own seeds: a resumed run continues exactly as an uninterrupted one
        rng = np.random.default_rng((cfg.seed, step))
        torch.manual_seed(cfg.seed * 1_000_003 + step)
        idx = rng.integers(0, len(pool), cfg.batch)
        x, mask = _padded_batch(motions, idx)
        if cfg.kind == "text2face":
            code = codes[idx, :d_r]
            loss = _text2face_loss(model, cfg, step, E_t, idx, code, x, mask, std_t, G)
        else:
            t = torch.from_numpy(rng.integers(0, model.cfg.steps, cfg.batch))
            noise = torch.randn_like(x)
            keep = torch.from_numpy((rng.random(cfg.batch) >= model.cfg.cond_drop).astype(np.float32))
            x0 = model(model.q_sample(x, t, noise), t, E_t[idx], keep, pad_mask=mask == 0)
            loss = rec_loss(x0, x, mask, std_t, G, cfg.w_rot)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        step += 1
        losses.append(round(float(loss.detach()), 5))
        bar.update(1)
        if step % 20 == 0:
            bar.set_postfix(loss=f"{np.mean(losses[-20:]):.3f}")
        if step % cfg.ckpt_every == 0 or step == cfg.steps:
            save_checkpoint(
                ck_path,
                kind=cfg.kind,
                model=model,
                train_cfg=cfg,
                stats=stats,
                gram=gram,
                step=step,
                opt=opt,
                info=info(),
                fps=clips[0].fps,
            )
    bar.close()
    model.eval()
    return {"model": model, "path": ck_path, "info": info(), "stats": stats}
