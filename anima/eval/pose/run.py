"""``anima eval pose``: the lifter against MediaPipe's own 3D on real Human3.6M S9 images and on HumanEva-I
(seed 004 §3.4.1), and the ablation of table 3.6.

Protocols, metrics: :mod:`anima.eval.pose.metrics` (17 H36M joints, root-relative; HumanEva: its 15 joints).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from anima.errors import InputError
from anima.eval.config import PoseEval
from anima.eval.pose.metrics import PROTOCOLS, pose_metrics
from anima.io.outdir import claim_folder
from anima.pose3d.config import TrainConfig, default_cache, default_checkpoint
from anima.pose3d.data import humaneva_validation, s9_image_evidence
from anima.pose3d.joints import HUMANEVA_EVAL

# seed 004, tables 3.2 and 3.3 (H3.6M test subjects S9 and S11, all actions, average over actions)
SEED_PUBLISHED = {
    "setting": "ResNet-50 on RGB images, trained on H3.6M (H80K or 5 fps) + MPII/LSP 2D; tested on all 15 actions "
    "of S9 and S11 with tight ground-truth crops",
    "h36m_scaled_mpjpe_mm": {"H80K": 71.1, "5fps": 65.7},
    "h36m_procrustes_mpjpe_mm": {"H80K": 53.4, "5fps": 49.2},
    "posing_action": {
        "scaled_mpjpe_mm": {"H80K": 57.1, "5fps": 54.0},
        "procrustes_mpjpe_mm": {"H80K": 43.9, "5fps": 40.6},
    },
}

OUR_SETTING = (
    "MediaPipe Pose (model_complexity 1) 2D keypoints on the full 1000x1000 images (no ground-truth "
    "crop) lifted by a 2D->3D network trained on H3.6M S1,S5,S6,S7,S8 mocap projected through the real "
    "cameras (no images) + MediaPipe 2D on in-the-wild videos; tested on the 320 staged frames of S9 "
    "'Posing 1' (3 cameras), i.e. one action of one test subject"
)

# the ablation of seed table 3.6, on this lifter
ABLATION = {
    "3d_only": dict(bone=False, latent_2d=False, projection=False, wild=False),
    "3d_only+bone (seed baseline)": dict(bone=True, latent_2d=False, projection=False, wild=False),
    "+2d_latent+wild": dict(bone=True, latent_2d=True, projection=False, wild=True),
    "+projection+wild (2D bone lengths)": dict(bone=True, latent_2d=False, projection=True, wild=True),
    "all": dict(bone=True, latent_2d=True, projection=True, wild=True),
}


def evaluate_model(model, cache: Path, progress: bool = False) -> dict:
    from anima.pose3d.train import predict  # lazy: torch

    e = s9_image_evidence(cache, progress)
    f = e["found"]
    s9 = pose_metrics(predict(model, e["uv"][f], e["conf"][f]), e["gt3d"][f])
    he = humaneva_validation()
    hm = pose_metrics(predict(model, he["uv"], he["conf"]), he["gt3d"], joints=HUMANEVA_EVAL)
    return {"h36m_s9_images": s9, "humaneva_validation_gt2d": hm}


def evaluate(checkpoint: Path | None, cache: Path, progress: bool = False) -> dict:
    """The lifter ``checkpoint`` (None: MediaPipe's baseline only) on S9 images and HumanEva."""
    from anima.pose3d.train import load_checkpoint  # lazy: torch

    loaded = load_checkpoint(checkpoint) if checkpoint is not None else None  # fail before the slow part
    e = s9_image_evidence(cache, progress)
    f = e["found"]
    out = {
        "s9_images": {
            "frames": int(len(f)),
            "person_found": int(f.sum()),
            "cameras": sorted(set(e["camera"].tolist())),
            "mediapipe_world_landmarks": pose_metrics(e["world"][f], e["gt3d"][f]),
        },
        "humaneva_validation": {
            "frames": int(len(humaneva_validation()["uv"])),
            "input": "ground-truth 2D of the 3 colour cameras (no HumanEva images are "
            "available, so MediaPipe cannot be run on it); nose masked (b_k = 0)",
        },
        "seed_published": SEED_PUBLISHED,
        "our_setting": OUR_SETTING,
    }
    if loaded is not None:
        model, ck = loaded
        res = evaluate_model(model, cache, progress)
        out["checkpoint"] = {
            "path": str(checkpoint),
            "config": ck["config"],
            "step": ck["step"],
            "train_s": ck["extra"].get("seconds"),
        }
        out["s9_images"]["lifter"] = res["h36m_s9_images"]
        out["humaneva_validation"]["lifter"] = res["humaneva_validation_gt2d"]
    return out


def ablation(
    work: Path, cache: Path, steps: int, width: int = 256, dropout: float = 0.1, progress: bool = True
) -> dict:
    """Train (or reuse, resumable) one lifter per row of :data:`ABLATION` and evaluate each. The rows share
    everything but the flags (seed, data, steps, width)."""
    from anima.pose3d.train import load_checkpoint, train  # lazy: torch

    rows = {}
    for name, flags in ABLATION.items():
        base = TrainConfig(steps=steps)
        cfg = dataclasses.replace(base, model={**base.model, "width": width, "dropout": dropout}, **flags)
        slug = "".join(c if c.isalnum() else "_" for c in name).strip("_")
        ck = Path(work) / f"{slug}.pt"
        done = False
        if ck.exists():
            _, meta = load_checkpoint(ck)
            done = meta["step"] >= steps and meta["config"] == json.loads(json.dumps(dataclasses.asdict(cfg)))
        if done:
            model, meta = load_checkpoint(ck)
            seconds = meta["extra"].get("seconds")
        else:
            model, info = train(cfg, ck, cache, progress=progress, resume=True)
            seconds = info["seconds"]
        r = evaluate_model(model, cache)
        rows[name] = {"flags": flags, "steps": steps, "train_s": seconds, **r}
    return rows


def evaluate_pose(
    model: str | None = None,
    cache: str | None = None,
    ablation_dir: str | None = None,
    ablation_steps: int = 8000,
    ablation_width: int = 256,
    ablation_dropout: float = 0.1,
    progress: bool = True,
) -> dict:
    """``anima eval pose``: the lifter (default checkpoint unless ``model``) and, with ``ablation_dir``, the
    rows of seed table 3.6 trained there."""
    cache_p = Path(cache) if cache else default_cache()
    model_p = Path(model) if model else default_checkpoint()
    if not model_p.exists() and (model or not ablation_dir):
        raise InputError(
            f"no pose lifter checkpoint at {model_p}: train one with `anima train pose`"
            + ("" if ablation_dir else ", or pass --ablation DIR to train the ablation rows")
        )
    if ablation_dir:
        claim_folder(ablation_dir, "pose_ablation", "--ablation")  # a user's folder is refused before any work
    r = evaluate(model_p if model_p.exists() else None, cache_p, progress=progress)
    if ablation_dir:
        r["ablation"] = ablation(
            Path(ablation_dir), cache_p, ablation_steps, ablation_width, ablation_dropout, progress=progress
        )
    return r


def run(cfg: PoseEval, progress: bool = False) -> dict:
    """``anima eval pose``."""
    return evaluate_pose(
        cfg.model, cfg.cache, cfg.ablation, cfg.ablation_steps, cfg.ablation_width, cfg.ablation_dropout, progress
    )


def summary(r: dict) -> list[str]:
    """The table the docs show: S9 cells MPJPE (mm) / PCK@150 (%) / AUC (%) under each protocol, HumanEva's
    Procrustes MPJPE; MediaPipe's own 3D, the lifter checkpoint and the ablation rows where present."""
    s9 = r["s9_images"]

    def cells(m: dict) -> str:
        return " | ".join(f"{m[p]['mpjpe']:.1f} / {m[p]['pck150']:.1f} / {m[p]['auc']:.1f}" for p in PROTOCOLS)

    def he(m: dict | None) -> str:
        return "-" if m is None else f"{m['procrustes']['mpjpe']:.1f}"

    rows = [("MediaPipe `pose_world_landmarks` (peer baseline)", s9["mediapipe_world_landmarks"], None)]
    if "lifter" in s9:
        rows.append(("lifter checkpoint", s9["lifter"], r["humaneva_validation"].get("lifter")))
    for name, a in (r.get("ablation") or {}).items():
        rows.append((f"lifter: {name}", a["h36m_s9_images"], a["humaneva_validation_gt2d"]))
    steps = {a["steps"] for a in (r.get("ablation") or {}).values()}
    out = [
        f"S9 images: {s9['person_found']} of {s9['frames']} frames with a person found by MediaPipe (the others are "
        "reported, not scored). Cells: MPJPE (mm) / 3D PCK@150 (%) / AUC (%)"
        + (f"; ablation rows trained {', '.join(map(str, sorted(steps)))} steps each." if steps else "."),
        "",
        "| model | S9 unscaled | S9 glob. scaled | S9 Procrustes | HumanEva PA-MPJPE |",
        "|---|---|---|---|---|",
    ]
    return out + [f"| {name} | {cells(m)} | {he(h)} |" for name, m, h in rows]
