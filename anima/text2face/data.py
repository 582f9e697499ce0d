"""Training and evaluation items for text -> face motion, from an anima dataset's ``text_motion`` clips.

* **Crops with their own descriptions.** A clip's events (attribute, start, end) are cut to a random window
  and re-described with the dataset's timeline grammar (:mod:`anima.dataset.describe`), so a 3 s crop of
  "talks, then smiles, then blinks" is described by what happens in those 3 s. The pool is drawn once from
  a seed; each item keeps its per-sample random code (seed 000 §6.1: fixed across epochs).
* **Evaluation items:** 90-frame windows (hop 45) of the held-out clips (validation + test videos: the
  builder splits by video), with descriptions of the window.
* **Vertex-offset loss (§6.1).** The seed trains on z-normalised vertex offsets. Here motion stays in the
  56-d ICT space; since offsets are linear in the expression weights, the mean squared z-normalised offset
  error over the face region equals ``de G de^T / (3V)`` with ``G = W W^T``, ``W = B / sigma`` (B the
  expression deltas of the face region, sigma the per-coordinate std of the training offsets). The exact
  loss at 53x53 cost, whatever the vertex count.
* **Metric vertices:** mouth and eye regions of the ICT face (``anima.facemodel.ict.region_vertices``);
  offsets in millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anima.core.contract import N_EXPR, TEXT_FPS
from anima.dataset.describe import describe, segment_timeline
from anima.dataset.windows import read_clips
from anima.errors import InputError
from anima.facemodel.ict import load_face_model, region_vertices

FPS = TEXT_FPS
EVAL_LEN = 90
EVAL_HOP = 45


@dataclass
class Clip:
    clip_id: str
    video_id: str
    split: str
    motion: np.ndarray  # [T, 56] raw (expression weights, axis-angle)
    texts: list[str]
    events: list[tuple[str, float, float]]
    gender: str | None
    fps: float = TEXT_FPS


@dataclass
class Item:
    motion: np.ndarray  # [T, 56] raw
    text: str
    events: list[tuple[str, float, float]]
    source: str
    texts: list[str] = field(default_factory=list)
    video: str = ""  # the held-out video and its split (validation or test), for intervals over videos
    split: str = ""


def load_clips(folder: str | Path) -> list[Clip]:
    rows = read_clips(folder)
    if not rows:
        raise InputError(f"{folder}: the dataset has no (text, motion) clips; build it with `anima dataset build`")
    return [Clip(r.clip_id, r.video_id, r.split, r.motion, r.texts, r.events, r.gender, r.fps) for r in rows]


def crop_events(events, a: int, b: int, fps: float = FPS):
    s0, s1 = a / fps, b / fps
    out = []
    for name, s, e in events:
        s, e = max(s, s0), min(e, s1)
        if e - s > 0.5 / fps:
            out.append((name, s - s0, e - s0))
    return out


def describe_window(events, n_frames: int, rng, gender=None, fps: float = FPS) -> str:
    return describe(segment_timeline(events, duration=n_frames / fps), rng, gender)


def crop_pool(clips: list[Clip], per_clip: int, min_len: int, max_len: int, seed: int) -> list[Item]:
    """Each clip whole (with a dataset description) plus ``per_clip`` random crops, re-described."""
    rng = np.random.default_rng(seed)
    items = []
    for c in clips:
        n = len(c.motion)
        whole = c.motion[:max_len]
        ev = crop_events(c.events, 0, len(whole), c.fps)
        text = (
            c.texts[rng.integers(len(c.texts))]
            if len(whole) == n
            else describe_window(ev, len(whole), rng, c.gender, c.fps)
        )
        items.append(Item(whole, text, ev, c.clip_id))
        for _ in range(per_clip):
            L = int(rng.integers(min_len, min(n, max_len) + 1))
            a = int(rng.integers(0, n - L + 1))
            ev = crop_events(c.events, a, a + L, c.fps)
            items.append(
                Item(c.motion[a : a + L], describe_window(ev, L, rng, c.gender, c.fps), ev, f"{c.clip_id}@{a}+{L}")
            )
    return items


def eval_items(
    clips: list[Clip], length: int = EVAL_LEN, hop: int = EVAL_HOP, seed: int = 0, n_texts: int = 3
) -> list[Item]:
    """Fixed-length windows of the given clips with descriptions of each window."""
    rng = np.random.default_rng(seed)
    out = []
    for c in clips:
        for a in range(0, len(c.motion) - length + 1, hop):
            ev = crop_events(c.events, a, a + length, c.fps)
            texts = [describe_window(ev, length, rng, c.gender, c.fps) for _ in range(n_texts)]
            out.append(Item(c.motion[a : a + length], texts[0], ev, f"{c.clip_id}@{a}", texts, c.video_id, c.split))
    return out


def split_clips(clips: list[Clip]):
    train = [c for c in clips if c.split == "train"]
    held = [c for c in clips if c.split in ("val", "test")]
    if not train:
        raise InputError("the dataset has no training clips")
    return train, held


# ---- normalisation and the vertex-offset geometry ---------------------------------------------------


def motion_stats(items: list[Item]) -> tuple[np.ndarray, np.ndarray]:
    X = np.concatenate([it.motion for it in items], 0).astype(np.float64)
    return X.mean(0).astype(np.float32), np.maximum(X.std(0), 1e-3).astype(np.float32)


class FaceGeometry:
    """Expression deltas of the loss region (ICT ``face``) and the metric regions (mouth, eyes), in mm."""

    def __init__(self):
        fm = load_face_model()
        face = region_vertices(fm, "face")
        self.B = fm.expr_deltas[:, face].reshape(N_EXPR, -1).astype(np.float64) * 10.0  # mm
        me = np.concatenate([region_vertices(fm, "mouth"), region_vertices(fm, "eyes")])
        self.B_metric = fm.expr_deltas[:, np.unique(me)].astype(np.float32) * 10.0  # [53, Vm, 3] mm
        self.n_metric = self.B_metric.shape[1]

    def gram(self, expr: np.ndarray) -> np.ndarray:
        """``G = W W^T / (3V)`` for z-normalised offsets of the training expressions ``expr [N, 53]``."""
        e = expr.astype(np.float64)
        # std of offsets o = e B per coordinate: sqrt(diag(B^T C B)) with C the expression covariance
        C = np.cov(e, rowvar=False)
        var = np.einsum("ik,ij,jk->k", self.B, C, self.B)
        sd = np.sqrt(np.maximum(var, 0))
        sd = np.maximum(sd, 0.05 * np.median(sd[sd > 0]))  # floor: static vertices must not dominate
        W = self.B / sd[None]
        return (W @ W.T / W.shape[1]).astype(np.float32)

    def metric_offsets(self, expr: np.ndarray) -> np.ndarray:
        """Mouth + eye vertex offsets ``[..., Vm, 3]`` mm for expression weights ``[..., 53]``."""
        return np.tensordot(np.asarray(expr, np.float32), self.B_metric, axes=([-1], [0]))
