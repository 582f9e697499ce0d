"""The matching database from the dataset builder's (audio, motion) windows (64 frames at 15 fps, 55-joint
skeleton + 28 speech features per frame)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from anima.errors import InputError
from anima.gesture.features import T_MATCH, audio_features, pose_features
from anima.gesture.knn import MatchDB


def from_dataset(folder: str | Path, split: str | None = "train") -> MatchDB:
    from anima.dataset.storage import read_table
    t = read_table(folder, "audio_motion", split)
    F, P, G, src, SS = [], [], [], [], []
    for body, speech, source, start in zip(t["body"].to_pylist(), t["speech"].to_pylist(),
                                           t["source"].to_pylist(), t["start_s"].to_pylist()):
        J = np.asarray(body, np.float32).reshape(-1, 55, 3)
        S = np.asarray(speech, np.float32).reshape(-1, 28)
        if len(J) != T_MATCH or not np.isfinite(J).all():
            continue
        F.append(audio_features(S))
        P.append(pose_features(J))
        G.append(J.reshape(T_MATCH, -1))
        src.append((source, start))
        SS.append(S)
    if not F:
        raise InputError(f"no usable (audio, motion) windows in {folder} (split {split}): build the dataset from "
                         "videos where the upper body and hands are visible and there is speech")
    return MatchDB(np.stack(F), np.stack(P), np.stack(G), src, np.stack(SS))
