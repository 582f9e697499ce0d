"""``anima train gesture``: train a gesture model on a dataset's (audio, motion) windows and write its
checkpoint (:mod:`anima.io.checkpoint`).

* ``refiner``: the cGAN refiner of the k-NN output (§5.3.3): every training window's speech is synthesised by
  the k-NN search over the other videos (the seed's k: 1 for half, 2..15 for the rest, from random initial
  poses; joins blended and the no-repeat rule on, as the command's search), then the WGAN-GP refiner trains
  on (speech, k-NN, captured) triples with the seed's loss weights;
* ``generator`` (the §4.4 adversarial U-Net), ``regression`` (without the adversarial term), ``lstm`` (the
  LSTM baseline), ``velocity_adversarial`` (Ginosar et al.): trained on every window, face-only windows
  training the face decoder; ``moglow`` (the MoGlow-style flow): trained on the windows with a body.
"""

from __future__ import annotations

import sys
from pathlib import Path

from tqdm import tqdm

from anima.dataset.windows import read_windows
from anima.errors import InputError
from anima.gesture.config import MODELS, GestureConfig, GestureTrainConfig
from anima.gesture.database import from_dataset
from anima.gesture.features import N_STEP
from anima.gesture.generator import GeneratorConfig, GeneratorTrainConfig, save_generator, train_generator
from anima.gesture.refine import RefinerTrainConfig, knn_pairs, save_refiner, train_refiner
from anima.io.checkpoint import looks_like_checkpoint
from anima.io.outdir import check_out_file


def train_from_dataset(
    db: str | Path,
    out: str | Path,
    cfg: GestureTrainConfig | None = None,
    progress: bool = True,
    command: str | None = None,
) -> dict:
    """Train ``cfg.model`` on the training split of ``db`` (every split with ``cfg.all_splits``); returns a
    summary."""
    cfg = cfg or GestureTrainConfig()
    model, steps, seed, all_splits = cfg.model, cfg.steps, cfg.seed, cfg.all_splits
    if not Path(db).exists():
        raise InputError(f"no dataset at {db}")
    if model not in MODELS:
        raise InputError(f"unknown --model {model!r}: one of {', '.join(MODELS)}")
    if steps is not None and steps < 1:
        raise InputError("--steps must be >= 1")
    check_out_file(out, inputs=[db], suffixes=(".pt",), ours=looks_like_checkpoint, what="a checkpoint")
    split = None if all_splits else "train"
    if model == "refiner":
        match_db = from_dataset(db, split)
        cfg = RefinerTrainConfig(steps=steps or RefinerTrainConfig().steps, seed=seed)
        if progress:
            print(f"k-NN syntheses of {match_db.M} windows (each against the other videos)...", file=sys.stderr)
        pairs = knn_pairs(match_db, cfg, no_repeat_steps=round(GestureConfig().no_repeat_s * match_db.fps / N_STEP))
        with tqdm(total=cfg.steps, desc="train cGAN refiner", unit="step", disable=not progress) as bar:
            ref, info = train_refiner(match_db, cfg, progress=lambda s: bar.update(1), pairs=pairs)
        info.update(dataset=str(db), command=command)
        save_refiner(out, ref, info)
        return {
            "checkpoint": str(out),
            "model": model,
            "pairs": info["pairs"],
            "windows": info["windows"],
            "wall_s": info["wall_s"],
        }
    w = read_windows(db, split)
    if not w.n:
        raise InputError(f"no training windows in {db}")
    kind = {"generator": "adversarial"}.get(model, model)
    cfg = GeneratorTrainConfig(steps=steps or GeneratorTrainConfig().steps, seed=seed)
    with tqdm(total=cfg.steps, desc=f"train {model}", unit="step", disable=not progress) as bar:
        gen, info = train_generator(
            w.speech, w.body, w.face, GeneratorConfig(kind=kind, fps=w.fps), cfg, progress=lambda s: bar.update(1)
        )
    info.update(dataset=str(db), command=command)
    save_generator(out, gen, info)
    return {
        "checkpoint": str(out),
        "model": model,
        "kind": kind,
        "windows": info["windows"],
        "body_windows": info["body_windows"],
        "loss_weights": info["loss_weights"],
        "wall_s": info["wall_s"],
    }
