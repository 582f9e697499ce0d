"""The matching database from the dataset builder's (audio, motion) windows (read through
:func:`anima.dataset.windows.read_windows`: 55-joint skeleton + 28 speech features per frame, at the data's
own frame rate), or from a motion library's (:mod:`anima.library.builtin`: the built-in one or one from
``anima library build``).

A library is small (the built-in one holds 40 s of gesture), so its database also holds **variants** of its
motion (:func:`with_variants`, not in the seed): each video's stretch of windows mirrored left to right, and
both the stretch and its mirror image played at 1/1.15 and 1.15 times their speed (the speech features resampled
with them), cut into windows again. For the no-repeat rule every variant counts as its source stretch (its frames
mapped back through :attr:`anima.gesture.knn.MatchDB.rate`): a variant gives the search other ways to continue and
other looks, never a way to replay a stretch sooner."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from anima.core.contract import HOP
from anima.core.skeleton import JOINT_NAMES
from anima.dataset.windows import read_windows
from anima.errors import InputError
from anima.gesture.features import POSE_OFFSETS, T_MATCH, audio_features, pose_features
from anima.gesture.knn import MIRROR, MatchDB
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


def from_builtin(variants: bool = True) -> MatchDB:
    """The matching database of the built-in motion library's windows (:mod:`anima.library.builtin`)."""
    return from_library(None, variants)


def from_library(path: str | Path | None = None, variants: bool = True) -> MatchDB:
    """The matching database of a motion library's windows: ``path`` a library from ``anima library build`` (its
    folder or ``.npz``), None the built-in one; ``variants``: with :func:`with_variants`."""
    b = builtin.load(builtin.resolve(path))
    g = b.gesture
    if not len(g["G"]):
        where = "the built-in motion library" if path is None else f"the motion library {path}"
        raise InputError(f"{where} has no (audio, gesture) window (its videos had no speech or no visible body)")
    db = MatchDB(g["F"], g["P"], g["G"], b.gesture_source, g["S"], fps=b.gesture_fps)
    return with_variants(db) if variants else db


SPEEDS = (1 / 1.15, 1.15)  # source frames per output frame of the speed-varied copies
_FLIP = np.array(
    [JOINT_NAMES.index(n.replace("left", "@").replace("right", "left").replace("@", "right")) for n in JOINT_NAMES]
)


def mirrored(J: np.ndarray) -> np.ndarray:
    """Joints ``[..., 55, 3]`` mirrored left to right (x is the body's left-right axis)."""
    return J[..., _FLIP, :] * np.array([-1.0, 1.0, 1.0], J.dtype)


def _stretches(db: MatchDB) -> list[tuple[str, int, np.ndarray, np.ndarray]]:
    """Each video's windows joined where they overlap or touch: ``(video, first frame, joints [L, 55, 3], speech
    [L, 28])``."""
    T = db.G.shape[1]
    by = {}
    for i, (v, t) in enumerate(db.source):
        by.setdefault(v, []).append((round(t * db.fps), i))
    out = []
    for v, items in by.items():
        items.sort()
        run = []
        for f0, i in items + [(None, None)]:
            if run and (f0 is None or f0 > run[-1][0] + T):
                a, b = run[0][0], run[-1][0] + T
                J = np.empty((b - a, db.G.shape[2]), np.float64)
                S = np.empty((b - a, db.S.shape[2]), np.float64)
                for g0, j in run:
                    J[g0 - a : g0 - a + T] = db.G[j]
                    S[g0 - a : g0 - a + T] = db.S[j]
                out.append((v, a, J.reshape(b - a, -1, 3), S))
                run = []
            if f0 is not None:
                run.append((f0, i))
    return out


def with_variants(db: MatchDB, speeds=SPEEDS, hop: int = HOP) -> MatchDB:
    """``db`` with the mirrored and speed-varied copies of its motion (module docstring). Needs its speech
    features (``S``)."""
    if db.S is None or not db.M:
        return db
    T = db.G.shape[1]
    F, P, G, S, src, rate = [db.F], [db.P], [db.G], [db.S], list(db.source), [np.ones(db.M)]
    for video, a, J, Sp in _stretches(db):
        L = len(J)
        for mirror in (False, True):
            for rho in (1.0, *speeds):
                if rho == 1.0 and not mirror:
                    continue  # the windows themselves
                n = int(np.floor((L - 1) / rho)) + 1
                if n < T:
                    continue
                t = np.arange(n) * rho
                i0 = np.minimum(np.floor(t).astype(int), L - 2)
                w = (t - i0)[:, None]
                Jr = J[i0] * (1 - w[:, :, None]) + J[i0 + 1] * w[:, :, None]
                Sr = Sp[i0] * (1 - w) + Sp[i0 + 1] * w
                if mirror:
                    Jr = mirrored(Jr)
                Pr, Fr = pose_features(Jr), audio_features(Sr)
                starts = list(range(0, n - T + 1, hop))
                if starts[-1] < n - T and n - T - starts[-1] >= hop // 2:
                    starts.append(n - T)  # the stretch's end too
                for s0 in starts:
                    F.append(Fr[None, s0 : s0 + T])
                    P.append(Pr[None, s0 : s0 + T])
                    G.append(Jr[None, s0 : s0 + T].reshape(1, T, -1).astype(db.G.dtype))
                    S.append(Sr[None, s0 : s0 + T].astype(db.S.dtype))
                    src.append((video + (MIRROR if mirror else ""), (a + s0 * rho) / db.fps))
                    rate.append(np.array([rho]))
    return MatchDB(
        np.concatenate(F).astype(db.F.dtype),
        np.concatenate(P).astype(db.P.dtype),
        np.concatenate(G),
        src,
        np.concatenate(S),
        db.fps,
        np.concatenate(rate),
    )


def distinct_seconds(db: MatchDB) -> float:
    """Seconds of distinct source motion in ``db`` (overlapping windows once; a variant, mirrored or speed-varied,
    counts as its source)."""
    vid, f0 = db.video_frames
    rate = np.ones(db.M) if db.rate is None else np.asarray(db.rate, np.float64)
    T = db.G.shape[1]
    total = 0.0
    for v in np.unique(vid):
        spans = sorted((f0[m], f0[m] + T * rate[m]) for m in np.flatnonzero(vid == v))
        end = -np.inf
        for a, b in spans:
            total += max(0.0, b - max(a, end))
            end = max(end, b)
    return total / db.fps


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
    return from_windows(read_windows(folder, split), f"{folder} (split {split})")


def from_windows(w, where: str = "the windows") -> MatchDB:
    """The matching database of (audio, motion) windows (:class:`anima.dataset.windows.Windows`): its full-body
    windows, each pose feature looking ahead into the next window of its video (:func:`_with_future`)."""
    keep = np.flatnonzero(w.has_body) if w.n and w.length == T_MATCH else np.zeros(0, int)
    if not len(keep):
        raise InputError(
            f"no usable (audio, motion) windows in {where}: build the dataset from "
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
