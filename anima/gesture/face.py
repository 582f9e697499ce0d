"""A talking face for gestures made from speech: the mouth from the speech, the eyes blinking.

* **Mouth** (:func:`fit_speech_face`, :func:`speech_face`): the jaw opens with the speech's envelope (its log
  energy, z-scored over the utterance, lightly smoothed), scaled to the spread of the jaw in the dataset's
  captured talking faces; every other expression follows the jaw as it does in those faces (its regression
  on the captured jawOpen). Two numbers and one slope per channel come from the data, so a few minutes of
  captured faces are enough (a full regression from the 28 speech features to the 53 weights, tried on the
  shared clips' 11 windows, correlated 0.09 with the speech's energy: it learned the mean). It follows the
  speech's loudness, not its words: no visemes.
* **Blinks** (:func:`blink_curve`): a renewal process of blinks (about 17 a minute, at least 1.2 s apart),
  each a 0.2-0.3 s close, shut, open of both lids (shut for at least 0.12 s), seeded.

Without a dataset's face windows the built-in defaults (an adult's jaw range) are used, said in the notes.
"""

from __future__ import annotations

import numpy as np

from anima.core.contract import EXPR_NAMES, N_EXPR

ENERGY = 13  # the speech feature that is the frame's log energy (anima.audio.features.FEATURE_NAMES)
BLINK_PER_MIN = 17.0
BLINK_MIN_GAP_S = 1.2
JAW = EXPR_NAMES.index("jawOpen")
_EYES = [EXPR_NAMES.index("eyeBlink_L"), EXPR_NAMES.index("eyeBlink_R")]
DEFAULT = {"jaw_mean": 0.10, "jaw_std": 0.07}  # an adult talking (the shared talking heads' captures)


def _mirror(x: np.ndarray) -> np.ndarray:
    """Per-channel values with each _L/_R pair averaged (a symmetric rest face and coupling)."""
    out = np.array(x, np.float64, copy=True)
    for i, n in enumerate(EXPR_NAMES):
        if n.endswith("_L"):
            j = EXPR_NAMES.index(n[:-2] + "_R")
            out[i] = out[j] = (x[i] + x[j]) / 2
    return out


def fit_speech_face(face: np.ndarray) -> dict[str, np.ndarray] | None:
    """The mouth model from captured talking faces ``face [N, T, 56]`` (windows with NaN are skipped): the
    jaw's mean and spread, the median face (left and right averaged) and each channel's slope on the jaw.
    None with fewer than 64 captured frames."""
    ok = np.isfinite(face).all((1, 2))
    Y = np.concatenate(face[ok])[:, :N_EXPR] if ok.any() else np.zeros((0, N_EXPR))
    if len(Y) < 64:
        return None
    jaw = Y[:, JAW]
    var = max(float(jaw.var()), 1e-6)
    beta = ((Y - Y.mean(0)) * (jaw - jaw.mean())[:, None]).mean(0) / var
    return {
        "jaw_mean": np.float32(jaw.mean()),
        "jaw_std": np.float32(np.sqrt(var)),
        "base": _mirror(np.median(Y, 0)).astype(np.float32),
        "beta": _mirror(beta).astype(np.float32),
        "frames": np.int64(len(Y)),
    }


def speech_face(S: np.ndarray, model: dict | None) -> np.ndarray:
    """Expression weights ``[T, 53]`` for speech features ``S [T, 28]``: the jaw on the utterance's z-scored
    log energy (smoothed over three frames, clipped to [-2, 3]), the other channels on the jaw."""
    from scipy.ndimage import gaussian_filter1d

    e = np.nan_to_num(np.asarray(S, np.float64)[:, ENERGY])
    z = (e - e.mean()) / max(float(e.std()), 1e-6) if len(e) > 1 else np.zeros_like(e)
    z = np.clip(gaussian_filter1d(z, 1.0) if len(z) > 3 else z, -2.0, 3.0)
    m = model or {}
    mean, std = float(m.get("jaw_mean", DEFAULT["jaw_mean"])), float(m.get("jaw_std", DEFAULT["jaw_std"]))
    jaw = mean + std * z
    if model is None:
        E = np.zeros((len(S), N_EXPR))
        E[:, JAW] = jaw
    else:
        E = model["base"][None].astype(np.float64) + (jaw - mean)[:, None] * model["beta"][None]
        E[:, JAW] = jaw
    return np.clip(E, 0.0, 1.0).astype(np.float32)


def blink_shape(fps: float, dur_s: float) -> np.ndarray:
    """One blink's closure per frame: a quick close (30 %), the lids shut (at least two frames, and 0.12 s), a
    slower open; at least 0.2 s in all."""
    n = max(int(round(dur_s * fps)), 4)
    shut = max(2, int(np.ceil(0.12 * fps)), int(round(0.25 * n)))
    close = max(1, int(round(0.3 * n)))
    open_ = max(1, n - close - shut)
    ramp = lambda k: 0.5 - 0.5 * np.cos(np.pi * (np.arange(1, k + 1) / (k + 1)))
    return np.concatenate([ramp(close), np.ones(shut), ramp(open_)[::-1], [0.0]]).astype(np.float32)


def blink_curve(T: int, fps: float, seed: int = 0, per_min: float = BLINK_PER_MIN) -> np.ndarray:
    """Both lids' closure ``[T]`` in [0, 1]: blinks at a renewal process's times (gaps of 1.2 s plus an
    exponential with the rest of the mean gap), each :func:`blink_shape` of 0.2-0.3 s."""
    rng = np.random.default_rng(seed)
    out = np.zeros(T, np.float32)
    mean_gap = 60.0 / per_min
    t = rng.uniform(0.3, mean_gap)
    while t * fps < T:
        dur = rng.uniform(0.2, 0.3)
        shape = blink_shape(fps, dur)
        a = int(round(t * fps))
        seg = out[a : a + len(shape)]
        seg[:] = np.maximum(seg, shape[: len(seg)])
        t += len(shape) / fps + BLINK_MIN_GAP_S + rng.exponential(max(mean_gap - BLINK_MIN_GAP_S, 0.1))
    return out


def talking_face(S: np.ndarray, fps: float, model: dict | None, seed: int = 0) -> np.ndarray:
    """A face frame ``[T, 56]`` for speech ``S [T, 28]``: the regression's expressions with blinks laid over
    the lids, the head rotation left to the body (zeros)."""
    E = speech_face(S, model)
    blink = blink_curve(len(S), fps, seed)
    for k in _EYES:
        E[:, k] = np.maximum(E[:, k] * (1 - blink), blink)
    return np.concatenate([E, np.zeros((len(S), 3), np.float32)], 1)
