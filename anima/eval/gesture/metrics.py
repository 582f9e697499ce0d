"""Metrics of generated gestures and faces (seed 004 ch. 4-5), as plain functions. Each docstring names its
protocol; every function takes the frame rate of the motion it is given.
"""

from __future__ import annotations

import librosa
import numpy as np
from scipy.signal import argrelmin

from anima.core.contract import N_EXPR
from anima.core.skeleton import JOINT_NAMES
from anima.facemodel.ict import FaceModel, load_face_model
from anima.facemodel.landmarks68 import ibug68_vertices

WRISTS = [JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("right_wrist")]


def jerk(J: np.ndarray, fps: float) -> float:
    """Mean magnitude of the third time derivative of both wrists (m/s^3), finite differences at ``fps``,
    over all frames of ``J [T, 55, 3]``. Captured motion at 15 fps reads about 25 on the shared clips."""
    w = J[:, WRISTS]
    return float(np.linalg.norm(np.diff(w, 3, axis=0) * fps**3, axis=-1).mean()) if len(w) > 3 else float("nan")


def wrist_motion(J: np.ndarray) -> float:
    """Expressiveness: the wrists' temporal standard deviation (cm, mean over wrists and axes); a model that
    regresses to the mean pose scores near 0."""
    return float(J[:, WRISTS].std(0).mean() * 100)


def audio_onsets(speech: np.ndarray, fps: float) -> np.ndarray:
    """Audio onsets (s): peaks of the rise of the log energy (speech feature 13) at the motion rate."""
    env = np.maximum(np.diff(speech[:, 13], prepend=speech[0, 13]), 0)
    return librosa.onset.onset_detect(onset_envelope=env, sr=int(round(fps)), hop_length=1, units="time")


def beat_consistency(J: np.ndarray, onsets_s: np.ndarray, fps: float) -> float:
    """Beat consistency (Li et al. 2021): mean over motion beats (local minima of the wrists' summed speed)
    of exp(-d^2 / (2 * 0.1^2)), d the distance in seconds to the nearest audio onset."""
    v = np.linalg.norm(np.diff(J[:, WRISTS], axis=0), axis=-1).sum(-1)
    beats = argrelmin(v, order=2)[0] / fps
    if len(beats) == 0 or len(onsets_s) == 0:
        return float("nan")
    d = np.abs(beats[:, None] - onsets_s[None]).min(1)
    return float(np.exp(-(d**2) / (2 * 0.1**2)).mean())


def l1_cm(pred: np.ndarray, gt: np.ndarray) -> float:
    """L1 to the captured motion: mean absolute joint-coordinate difference (cm), pelvis-relative."""
    return float(np.abs(pred - gt).mean() * 100)


def diversity_cm(outs: list[np.ndarray]) -> float:
    """Mean L1 (cm) between every pair of syntheses of the same speech (e.g. k = 0..4)."""
    return float(np.mean([np.abs(a - b).mean() * 100 for j, a in enumerate(outs) for b in outs[j + 1 :]]))


def lip_keypoints(face56: np.ndarray, model: FaceModel | None = None) -> np.ndarray:
    """``[..., 56]`` -> the 20 lip landmarks (iBUG 48-67) of the ICT mean face in a neutral head pose, mm."""
    model = model or load_face_model()
    lip = ibug68_vertices(model)[48:68]
    sub = model.neutral[lip].astype(np.float64)
    d = model.expr_deltas[:, lip].astype(np.float64)
    return (sub + np.tensordot(face56[..., :N_EXPR].astype(np.float64), d, axes=([-1], [0]))) * 10.0


def lip_error_mm(pred56: np.ndarray, gt56: np.ndarray, model: FaceModel | None = None) -> float:
    """Table 4.3: mean distance (mm) between predicted and captured 3D lip keypoints, neutral head pose."""
    return float(np.linalg.norm(lip_keypoints(pred56, model) - lip_keypoints(gt56, model), axis=-1).mean())


def mouth_opening_mm(face56: np.ndarray, model: FaceModel | None = None) -> np.ndarray:
    """Inner-lip opening (iBUG 62 to 66, mm) per frame."""
    k = lip_keypoints(face56, model)
    return np.linalg.norm(k[..., 14, :] - k[..., 18, :], axis=-1)


def minutes_covered(items, window_s: float) -> float:
    """Minutes covered by ``(source, [window start s])`` items: the union of the (overlapping) windows'
    ranges, each ``window_s`` long."""
    total = 0.0
    for _, starts in items:
        end = -1.0
        for a in sorted(starts):
            b = a + window_s
            total += b - max(a, end) if b > end else 0.0
            end = max(end, b)
    return round(total / 60, 2)


def adherence_table(adherence: dict, window: int) -> dict:
    """Table 5.3: per control, the mean and deviation of the controlled feature over the synthesised frames
    and, against each query's own threshold, the fraction of frames satisfying it. ``adherence[c]`` holds
    ``values`` (control-feature dicts of each synthesis) and ``thresholds`` (one per synthesis)."""
    table = {}
    for c, a in adherence.items():
        name = "left_wrist_height" if c == "none" else c.split(">")[0].split("<")[0]
        vals = np.concatenate([v[name].ravel() for v in a["values"]])
        row = {"mean": float(vals.mean()), "deviation": float(vals.std())}
        if c != "none":  # each query against the threshold of its own (leave-one-out) database
            thr = np.repeat(a["thresholds"], window)
            row["threshold"] = float(np.mean(a["thresholds"]))
            ok = (vals >= thr) if ">" in c else (vals <= thr)
            row["satisfied_fraction"] = float(ok.mean())
            if a.get("videos") is not None:  # the spread over test videos: a bootstrap over them
                vid = np.repeat(np.asarray(a["videos"]), window)
                row["satisfied_fraction_ci95_over_videos"] = bootstrap_over_groups(ok.astype(float), vid)
                row["test_videos"] = int(len(set(a["videos"])))
        table[c] = row
    return table


def bootstrap_over_groups(x: np.ndarray, groups: np.ndarray, reps: int = 2000, seed: int = 0) -> list[float]:
    """95 % interval of the mean of ``x`` when whole groups (videos) are resampled with replacement (each
    group's sum and count, so a long video weighs as its frames do). Seeded."""
    keys, inv = np.unique(groups, return_inverse=True)
    sums = np.bincount(inv, weights=x, minlength=len(keys))
    counts = np.bincount(inv, minlength=len(keys)).astype(float)
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, len(keys), (reps, len(keys)))
    means = sums[pick].sum(1) / np.maximum(counts[pick].sum(1), 1)
    return [float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))]


def speaker_of(source: str) -> str:
    """The speaker of a clip, from the naming of the shared sets: PATS (oliver3_gt.mp4 -> oliver), StyleTalk
    (Obama_clip2.mp4 -> obama), TANGO (speaker7_....mp4 -> speaker7); other clips by their folder."""
    p = source.replace("\\", "/").split("/")
    stem = p[-1].rsplit(".", 1)[0]
    if "pats-crops" in p:
        return stem.split("_")[0].rstrip("0123456789")
    if "styletalk-samples" in p:
        return stem.split("_")[0].lower()
    if "tango-interviews" in p and stem.startswith("speaker"):
        return stem.split("_")[0]
    generic = {"assets", "examples", "video", "videos", "source", "face", "driving", "source_video", "samples"}
    for part in reversed(p[:-1]):
        if part and part not in generic:
            return part
    return p[-1]


def speaker_folds(sources, folds: int, by_speaker: bool = True, fixed: dict | None = None) -> dict[str, int]:
    """Each video's fold: with ``by_speaker``, all of a speaker's videos (:func:`speaker_of`)
    in one fold, so a window is judged by models that never saw its speaker; the speakers, most windows first
    (then by name), each go to the fold with the fewest windows so far (scikit-learn's GroupKFold rule).
    ``sources``: one entry per window (a video may repeat; its count is the weight). ``fixed``: speakers
    already placed ({speaker: fold}, their windows counted). Without ``by_speaker`` (one speaker's
    person-specific protocol): the sorted videos in turn (``n % folds``)."""
    videos = sorted(set(sources))
    if not by_speaker:
        return {v: n % folds for n, v in enumerate(videos)}
    weight: dict[str, int] = {}
    for s in sources:
        weight[speaker_of(s)] = weight.get(speaker_of(s), 0) + 1
    place = dict(fixed or {})
    load = [sum(w for sp, w in weight.items() if place.get(sp) == f) for f in range(folds)]
    for sp in sorted(set(weight) - set(place), key=lambda sp: (-weight[sp], sp)):
        f = min(range(folds), key=lambda f: (load[f], f))
        place[sp] = f
        load[f] += weight[sp]
    return {v: place[speaker_of(v)] for v in videos}


def group_of(source: str, by_speaker: bool = True) -> str:
    """What is held out together: a video's speaker (:func:`speaker_of`), or the video itself where every
    window is one speaker's (``--speaker``: the seed's person-specific protocol)."""
    return speaker_of(source) if by_speaker else source


def inner_validation(videos, by_speaker: bool = True) -> set:
    """The inner validation videos of an outer fold's training ``videos`` (a nested choice of a setting): every
    third of their speakers (sorted by name) with all of that speaker's videos, or every third video for one
    speaker. Every video when there is a single group: no inner split (the caller falls back to its default)."""
    groups = sorted({group_of(v, by_speaker) for v in videos})
    val = set(groups[::3])
    return {v for v in videos if group_of(v, by_speaker) in val}


def fold_count(sources, folds: int, by_speaker: bool = True) -> int:
    """How many folds ``folds`` can be: at least 2, at most the speakers (``by_speaker``) or the videos."""
    groups = {speaker_of(s) for s in sources} if by_speaker else set(sources)
    return max(2, min(folds, len(groups)))


def replayed(
    source: list, rate, picks: list, fps: float, n_step: int, span_s: float, fold_mirror: bool = True
) -> float:
    """Loops: the share of an output's search steps whose source motion (same video, overlapping frames) was
    already output within the previous ``span_s`` seconds. ``source``: the database's ``(video, start_s)`` per
    window, ``rate``: its source frames per frame (None: 1), ``picks``: the search's ``(window, start)`` per step;
    with ``fold_mirror`` a mirrored copy (``video#mirror``) counts as its source."""
    if len(picks) < 2:
        return 0.0
    rate = np.ones(len(source)) if rate is None else np.asarray(rate, np.float64)
    spans = []
    for m, r in picks:
        video, t = source[m]
        if fold_mirror:
            video = video.removesuffix("#mirror")  # anima.gesture.knn.MIRROR
        a = t * fps + r * rate[m]
        spans.append((video, a, a + n_step * rate[m]))
    back = int(round(span_s * fps / n_step))
    hits = 0
    for i, (v, a, b) in enumerate(spans[1:], 1):
        hits += any(w == v and a < d and c < b for w, c, d in spans[max(0, i - back) : i])
    return hits / (len(spans) - 1)
