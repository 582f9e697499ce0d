"""torch ``Dataset`` views of an anima dataset (see ``anima.dataset.storage`` for the schema)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from anima.core.contract import FACE_DIM
from anima.dataset.storage import load_stats, read_table


class TextMotionDataset(Dataset):
    """(text, face motion) clips for training. Items: ``{"motion": [T, 56] float tensor (z-normalised with
    the training statistics), "text": str, "length": T}``; the text is one of the clip's descriptions, drawn
    with a seeded generator per (epoch, index)."""

    def __init__(self, folder: str | Path, split: str = "train", normalise: bool = True, seed: int = 0):
        self.table = read_table(folder, "text_motion", split).to_pydict()
        stats = load_stats(folder).get("text_motion", {})
        self.mean = (
            np.asarray(stats.get("mean", np.zeros(FACE_DIM)), np.float32)
            if normalise
            else np.zeros(FACE_DIM, np.float32)
        )
        self.std = (
            np.asarray(stats.get("std", np.ones(FACE_DIM)), np.float32) if normalise else np.ones(FACE_DIM, np.float32)
        )
        self.seed, self.epoch = seed, 0

    def __len__(self) -> int:
        return len(self.table["clip_id"])

    def __getitem__(self, i: int) -> dict:
        m = np.asarray(self.table["motion"][i], np.float32).reshape(-1, FACE_DIM)
        rng = np.random.default_rng((self.seed, self.epoch, i))
        texts = self.table["texts"][i]
        return {
            "motion": torch.from_numpy((m - self.mean) / self.std),
            "text": texts[rng.integers(len(texts))],
            "length": len(m),
        }


class AudioMotionDataset(Dataset):
    """(audio, motion) windows: ``{"speech": [64, 28], "body": [64, 165], "face": [64, 56]}`` float tensors."""

    def __init__(self, folder: str | Path, split: str = "train"):
        self.table = read_table(folder, "audio_motion", split).to_pydict()

    def __len__(self) -> int:
        return len(self.table["window_id"])

    def __getitem__(self, i: int) -> dict:
        t = self.table
        n = t["n_frames"][i]
        return {k: torch.from_numpy(np.asarray(t[k][i], np.float32).reshape(n, -1)) for k in ("speech", "body", "face")}
