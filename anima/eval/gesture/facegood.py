"""Lip sync of speech-driven faces on FaceGood's real (Mandarin speech, blendshape) recordings, never seen in
training."""

from __future__ import annotations

import glob
import warnings

import numpy as np

from anima.audio.features import read_audio, speech_features
from anima.eval.gesture.metrics import mouth_opening_mm
from anima.io.assets import asset

FACEGOOD_FPS = 30.0  # contract: not ours (the rate of FaceGood's bs_value arrays)


def load_py2_npy(path) -> np.ndarray:
    """A ``.npy`` written by Python 2 (FaceGood's arrays): numpy reads its header with a warning; no pickles."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Reading `.npy` or `.npz` file required additional header")
        return np.load(path, allow_pickle=False, encoding="latin1")


def facegood_sync(generators: dict, fps: float, max_lag: int = 8, seconds: float | None = None) -> dict | None:
    """Pearson correlation between the predicted mouth opening and FaceGood's ``mouth_stretch_c`` curve (its
    jaw-open channel, the largest mouth motion of its rig) at ``fps``, at lag 0 and at the best lag within
    +-``max_lag`` frames; the "other speech" row correlates each recording with the prediction for another
    one, at lag 0 and at its own best lag (the same search as the methods). ``generators``: ``{row name:
    [objects with generate(speech [T, 28]) -> (joints, face [T, 56])]}`` (one per fold, averaged)."""
    root = asset("facegood-audio2face/code/train", must_exist=False)
    if not root.is_dir():
        return None
    names_p = root / "shirley_1015_bs_name.npy"  # the name list whose symmetric pairs line up with the values
    wavs = sorted(glob.glob(str(root / "wav" / "*.wav")))
    if not wavs or not names_p.is_file():
        return None
    names = [str(n) for n in load_py2_npy(names_p)]
    ch = names.index("mouth_stretch_c")
    recs = []
    for w in wavs:
        stem = w.rsplit("/", 1)[-1][:-4]
        bs = load_py2_npy(root / "bs_value" / f"bs_value_{stem}.npy")[:, ch]
        x = read_audio(w)
        T = min(int(len(bs) / FACEGOOD_FPS * fps), int(len(x) / 16000 * fps))
        T = T if seconds is None else min(T, int(seconds * fps))  # (tests: the first seconds of each)
        ref = np.interp(np.arange(T) / fps, np.arange(len(bs)) / FACEGOOD_FPS, bs)
        recs.append((stem, speech_features(x, fps, T).features, ref))

    def corr(a, b, lag):
        if lag > 0:
            a, b = a[lag:], b[:-lag]
        elif lag < 0:
            a, b = a[:lag], b[-lag:]
        n = min(len(a), len(b))
        return float(np.corrcoef(a[:n], b[:n])[0, 1])

    rows = {}
    lags_all = range(-max_lag, max_lag + 1)
    for kind, gens in generators.items():
        preds = [np.mean([mouth_opening_mm(g.generate(S)[1]) for g in gens], 0) for _, S, _ in recs]
        r0, best, lags, other0, other_best = [], [], [], [], []
        for n, (_, _, ref) in enumerate(recs):
            cs = [corr(preds[n], ref, lag) for lag in lags_all]
            r0.append(cs[max_lag])
            best.append(max(cs))
            lags.append(int(np.argmax(cs)) - max_lag)
            co = [corr(preds[(n + 1) % len(recs)], ref, lag) for lag in lags_all]
            other0.append(co[max_lag])
            other_best.append(max(co))
        rows[kind] = {
            "r_lag0": float(np.mean(r0)),
            "r_best": float(np.mean(best)),
            "best_lag_frames": lags,
            "r_other_speech": float(np.mean(other0)),
            "r_other_speech_best": float(np.mean(other_best)),
        }
    return {
        "recordings": len(recs),
        "minutes": round(sum(len(r[2]) for r in recs) / fps / 60, 2),
        "channel": "mouth_stretch_c",
        "lag_search": f"+-{max_lag} frames for methods and other speech alike",
        "rows": rows,
    }
