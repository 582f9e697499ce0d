"""Ship a trained text2face checkpoint: a compact copy (float16 weights, no optimizer state) and a manifest
(command, data fingerprint, training time, held-out metrics, sha256) beside it, ``<name>.json``. The metrics are
computed by the caller's ``evaluate(checkpoint_path) -> dict`` (``anima.eval.text2face.quick_metrics`` from the
command), so the feature package does not reach up into the evaluation layer."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from anima import __version__
from anima.io.atomic import write_json
from anima.io.outdir import check_out_file


def check_ship(dest: str | Path, inputs=()) -> Path:
    """``--ship PATH``, refused before any training: a ``.pt`` file anima may write, whose manifest (the same
    name, ``.json``) is not a user's file."""
    dest = check_out_file(dest, "--ship", inputs=inputs, suffixes=(".pt",), what="a checkpoint")
    check_out_file(
        dest.with_suffix(".json"), "--ship (its manifest)", inputs=inputs,
        ours=lambda q: "heldout_metrics" in json.loads(q.read_text()), what="a manifest",
    )  # fmt: skip
    return dest


def ship(
    checkpoint: str | Path, dest: str | Path, evaluate: Callable[[Path], dict], chosen: dict | None = None
) -> list[Path]:
    """``chosen``: how its step count was chosen (recorded in the manifest as ``steps_chosen``)."""
    from anima.text2face.train import TrainConfig, load_checkpoint, save_checkpoint  # lazy: torch

    dest = check_ship(dest, inputs=[checkpoint])
    ck = load_checkpoint(checkpoint)
    cfg = TrainConfig(**ck["train_config"])
    save_checkpoint(
        dest,
        kind=ck["kind"],
        model=ck["model"],
        train_cfg=cfg,
        stats=(np.asarray(ck["mean"]), np.asarray(ck["std"])),
        gram=ck["gram"],
        step=ck["step"],
        info={k: v for k, v in ck["info"].items() if k != "losses"},
        compact=True,
        fps=ck["fps"],
    )
    metrics = evaluate(dest)
    info = ck["info"]
    manifest = {
        "checkpoint": dest.name,
        "sha256": hashlib.sha256(dest.read_bytes()).hexdigest(),
        "bytes": dest.stat().st_size,
        "kind": ck["kind"],
        "anima_version": __version__,
        "command": info.get("command"),
        "data_fingerprint": info.get("data_fingerprint"),
        "dataset": info.get("dataset"),
        "train_clips": info.get("train_clips"),
        "train_videos": info.get("train_videos"),
        "split_rule": info.get("split_rule"),
        "train_crops": info.get("train_items"),
        "steps": ck["step"],
        "train_wall_s": round(info.get("wall_s", 0.0), 1),
        "final_loss": round(sum(info["losses"][-50:]) / max(1, len(info["losses"][-50:])), 4)
        if info.get("losses")
        else None,
        "params": sum(p.numel() for p in ck["model"].parameters()),
        "model_config": ck["model_config"],
        "heldout_metrics": metrics,
        **({"steps_chosen": chosen} if chosen else {}),
    }
    man = write_json(dest.with_suffix(".json"), manifest)
    return [dest, man]
