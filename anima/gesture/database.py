"""The matching database from the dataset builder's (audio, motion) windows (read through
:func:`anima.dataset.windows.read_windows`: 55-joint skeleton + 28 speech features per frame, at the data's
own frame rate)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from anima.dataset.windows import read_windows
from anima.errors import InputError
from anima.gesture.features import T_MATCH, audio_features, pose_features
from anima.gesture.knn import MatchDB


def from_dataset(folder: str | Path, split: str | None = "train") -> MatchDB:
    w = read_windows(folder, split)
    keep = np.flatnonzero(w.has_body) if w.n and w.length == T_MATCH else np.zeros(0, int)
    if not len(keep):
        raise InputError(
            f"no usable (audio, motion) windows in {folder} (split {split}): build the dataset from "
            "videos where the upper body and hands are visible and there is speech"
        )
    J = w.body[keep].reshape(len(keep), T_MATCH, -1, 3)
    S = w.speech[keep]
    F = np.stack([audio_features(s) for s in S])
    P = np.stack([pose_features(j) for j in J])
    G = w.body[keep]
    src = [(w.source[i], w.start_s[i]) for i in keep]
    return MatchDB(F, P, G, src, S, fps=w.fps)
