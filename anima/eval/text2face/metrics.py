"""Table 7.1's metrics (seed 000 section 7.2): MAE and RMSE of the mouth and eye vertices (mm) between generated
and captured motion, Diversity (mean vertex distance between a sample and another sample of the set), attribute
recall with the dataset's detectors, and intervals over sampling repetitions and over held-out videos. Pure
functions of arrays (the face geometry passed in)."""

from __future__ import annotations

import numpy as np

from anima.core.contract import N_EXPR, TEXT_FPS
from anima.dataset.attributes import detect
from anima.export.framing import generated_sequence
from anima.text2face.data import FaceGeometry


def ci(values) -> dict:
    v = np.asarray(values, np.float64)
    half = 1.96 * v.std(ddof=1) / np.sqrt(len(v)) if len(v) > 1 else 0.0
    return {"mean": round(float(v.mean()), 4), "ci95": round(float(half), 4)}


def errors(gen: np.ndarray, real: np.ndarray, geom: FaceGeometry) -> tuple[float, float]:
    d = np.linalg.norm(geom.metric_offsets(gen[..., :N_EXPR]) - geom.metric_offsets(real[..., :N_EXPR]), axis=-1)
    return float(d.mean()), float(np.sqrt((d**2).mean()))


def item_errors(gen: np.ndarray, real: np.ndarray, geom: FaceGeometry) -> np.ndarray:
    """Per item: mean vertex distance (mm) over its frames and vertices ``[N]``."""
    d = np.linalg.norm(geom.metric_offsets(gen[..., :N_EXPR]) - geom.metric_offsets(real[..., :N_EXPR]), axis=-1)
    return d.reshape(len(d), -1).mean(1)


def over_videos(per_item: np.ndarray, items, reps: int = 2000, seed: int = 0) -> dict:
    """Per split (``val``, ``test``, ``all``): the mean of a per-item value and its 95 % interval when whole
    held-out videos are resampled (windows within a video stay together), each video's own mean
    (``per_video``) with the lowest and highest of them, and the counts behind it."""
    out = {}
    for name in ("val", "test", "all"):
        sel = [i for i, it in enumerate(items) if name == "all" or it.split == name]
        if not sel:
            continue
        vids = np.array([items[i].video for i in sel])
        keys, inv = np.unique(vids, return_inverse=True)
        x = np.asarray(per_item, np.float64)[sel]
        sums, counts = np.bincount(inv, weights=x), np.bincount(inv).astype(float)
        pick = np.random.default_rng(seed).integers(0, len(keys), (reps, len(keys)))
        means = sums[pick].sum(1) / counts[pick].sum(1)
        out[name] = {
            "mean": round(float(x.mean()), 4),
            "ci95_over_videos": [
                round(float(np.percentile(means, 2.5)), 4),
                round(float(np.percentile(means, 97.5)), 4),
            ],
            "per_video": {str(k): round(float(v), 4) for k, v in zip(keys, sums / counts)},
            "min_video": round(float((sums / counts).min()), 4),
            "max_video": round(float((sums / counts).max()), 4),
            "videos": int(len(keys)),
            "windows": int(len(sel)),
        }
    return out


def diversity(motions: np.ndarray, geom: FaceGeometry, rng: np.random.Generator) -> float:
    n = len(motions)
    perm = rng.permutation(n)
    j = np.where(perm == np.arange(n), (perm + 1) % n, perm)
    off = geom.metric_offsets(motions[..., :N_EXPR])
    return float(np.linalg.norm(off - off[j], axis=-1).mean())


def attribute_sets(motions: np.ndarray) -> list[set[str]]:
    return [{e[0] for e in detect(generated_sequence(TEXT_FPS, face=m))} for m in motions]


def recall_table(label_sets: list[set[str]], detected: list[list[set[str]]], attributes: list[str]) -> dict:
    """``detected[r][i]``: attributes detected in repetition r, item i."""
    out = {}
    for a in attributes:
        pos = [i for i, s in enumerate(label_sets) if a in s]
        neg = [i for i, s in enumerate(label_sets) if a not in s]
        rec = [np.mean([a in rep[i] for i in pos]) for rep in detected] if pos else [np.nan]
        fa = [np.mean([a in rep[i] for i in neg]) for rep in detected] if neg else [np.nan]
        out[a] = {
            "recall": round(float(np.mean(rec)), 3),
            "false_alarm": round(float(np.mean(fa)), 3),
            "items": len(pos),
        }
    return out
