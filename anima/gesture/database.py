"""The matching database from the dataset builder's (audio, motion) windows (read through
:func:`anima.dataset.windows.read_windows`: 55-joint skeleton + 28 speech features per frame, at the data's
own frame rate)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from anima.errors import InputError
from anima.gesture.features import POSE_OFFSETS, T_MATCH, audio_features, pose_features
from anima.gesture.knn import MatchDB
from anima.io.mapped import cache_key, file_stamp, mapped_arrays
from anima.library import builtin

LOOKAHEAD = max(POSE_OFFSETS)


def _with_future(J: np.ndarray, sources: list, starts: list, fps: float) -> list[np.ndarray]:
    """Each window's joints followed by the next frames of its video where another window holds them (windows
    overlap), so a pose feature near a window's end looks ahead into the real motion, as it does inside:
    the last frame of one window and the same frame in the next window get the same feature, and the search
    continues across window ends exactly."""
    T = J.shape[1]
    out = []
    by_time = {(s, round(t * fps)): i for i, (s, t) in enumerate(zip(sources, starts))}
    for i, (s, t) in enumerate(zip(sources, starts)):
        f0 = round(t * fps)
        ext = J[i]
        for k in range(1, T):  # a window starting k frames later holds frames T .. T + LOOKAHEAD - 1
            j = by_time.get((s, f0 + k))
            if j is not None and T - k + LOOKAHEAD <= T:
                ext = np.concatenate([J[i], J[j][T - k : T - k + LOOKAHEAD]])
                break
        out.append(ext)
    return out


def from_dataset(folder: str | Path, split: str | None = "train") -> MatchDB:
    """The matching database of a dataset's windows of ``split``, through a memory-mapped cache
    (:mod:`anima.io.mapped`) keyed on the dataset's manifest (rewritten by every build), the split and the
    code that makes the features: a command maps the arrays in milliseconds instead of reading the shards
    with Arrow and recomputing the features."""
    manifest = Path(folder) / "manifest.json"
    if not manifest.is_file():
        return _from_windows(folder, split)
    code = "".join(file_stamp(Path(__file__).parent / f) for f in ("database.py", "features.py"))
    a = mapped_arrays("gesture_db", cache_key(file_stamp(manifest), split, code), lambda: _arrays(folder, split))
    src = json.loads(str(a["source"]))
    return MatchDB(a["F"], a["P"], a["G"], [tuple(x) for x in src], a["S"], fps=float(a["fps"]))


def from_builtin() -> MatchDB:
    """The matching database of the built-in motion library's windows (:mod:`anima.library.builtin`)."""
    b = builtin.load()
    g = b.gesture
    if not len(g["G"]):
        raise InputError("the built-in motion library has no (audio, gesture) window: give --db DATASET")
    return MatchDB(g["F"], g["P"], g["G"], b.gesture_source, g["S"], fps=b.gesture_fps)


def _arrays(folder, split) -> dict:
    db = _from_windows(folder, split)
    return {
        "F": db.F,
        "P": db.P,
        "G": db.G,
        "S": db.S,
        "fps": np.float64(db.fps),
        "source": np.str_(json.dumps(db.source)),
    }


def _from_windows(folder: str | Path, split: str | None) -> MatchDB:
    from anima.dataset.windows import read_windows  # lazy: pyarrow, only when the cache is made

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
    ext = _with_future(J, [w.source[i] for i in keep], [w.start_s[i] for i in keep], w.fps)
    P = np.stack([pose_features(j)[:T_MATCH] for j in ext])
    G = w.body[keep]
    src = [(w.source[i], w.start_s[i]) for i in keep]
    return MatchDB(F, P, G, src, S, fps=w.fps)
