"""Training pairs from a tracked sequence.

* (text, face motion) clips at 30 fps: per frame the 53 ICT expression weights and the head rotation
  (axis-angle, 3) = 56 values (``FACE_DIM``).
* (audio, motion) windows of 64 frames at 15 fps (seed 004): body + hands (165), face (56) and the 28 speech
  features computed from the audio at exactly those frame times. Windows overlap by half (hop 32); a window
  is kept only if every joint is tracked (a missing hip takes its clip-median position: hips are often out of
  view and do not gesture) and every frame lies inside the audio. As in seed 004 (fig. 4.4), short occlusions
  are tolerated: a joint missing for at most ``MAX_GAP_S`` between two tracked frames is interpolated
  linearly (hands leave the frame or pass behind each other for a few frames while gesturing). Windows
  without a usable body but with a tracked face are kept as face-only windows (body NaN).
"""

from __future__ import annotations

import numpy as np

from anima.core.contract import BODY_DIM, GESTURE_FPS, HOP, TEXT_FPS, WINDOW
from anima.core.rotations import matrix_to_rotvec, rotvec_to_matrix
from anima.io.sequence import FLAG_NO_FACE

MAX_GAP_S = 0.5


def resample_times(n: int, fps: float, new_fps: float, start_s: float = 0.0, end_s: float | None = None):
    end_s = n / fps if end_s is None else end_s
    k = int(np.floor((end_s - start_s) * new_fps + 1e-6))
    return start_s + np.arange(k) / new_fps


def resample_linear(x: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``x [F, ...]`` (frame i at i / fps) at ``times``; NaN propagates."""
    pos = np.clip(times * fps, 0, len(x) - 1)
    i0 = np.floor(pos).astype(int)
    i1 = np.minimum(i0 + 1, len(x) - 1)
    w = (pos - i0).reshape(-1, *([1] * (x.ndim - 1)))
    return (1 - w) * x[i0] + w * x[i1]


def resample_rotvec(rv: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    R = resample_linear(rotvec_to_matrix(rv), fps, times)
    U, _, Vt = np.linalg.svd(R)
    d = np.sign(np.linalg.det(U @ Vt))
    U[:, :, 2] *= d[:, None]
    return matrix_to_rotvec(U @ Vt)


def face_motion(seq, times: np.ndarray) -> np.ndarray:
    """``[T, 56]``: expression weights (53) + head rotation axis-angle (3) at ``times``."""
    e = np.clip(resample_linear(seq.expression.astype(np.float64), seq.fps, times), 0, 1)
    r = resample_rotvec(seq.rotation.astype(np.float64), seq.fps, times)
    return np.concatenate([e, r], 1).astype(np.float32)


def text_motion_clip(seq, a: int, b: int) -> np.ndarray:
    """Face motion of frames ``[a, b)`` resampled to 30 fps."""
    t = resample_times(seq.n_frames, seq.fps, TEXT_FPS, a / seq.fps, b / seq.fps)
    return face_motion(seq, t)


def fill_short_gaps(x: np.ndarray, max_frames: int) -> np.ndarray:
    """``x [F, ...]`` with NaN rows per trailing element: every run of at most ``max_frames`` missing frames
    with a tracked frame on both sides is filled by linear interpolation; longer runs and runs at either end
    stay NaN."""
    out = np.array(x, np.float64, copy=True)
    flat = out.reshape(len(out), -1)
    for c in range(flat.shape[1]):
        v = flat[:, c]
        bad = ~np.isfinite(v)
        if not bad.any() or bad.all():
            continue
        i = 0
        while i < len(v):
            if not bad[i]:
                i += 1
                continue
            j = i
            while j < len(v) and bad[j]:
                j += 1
            if i > 0 and j < len(v) and j - i <= max_frames:
                w = np.arange(1, j - i + 1) / (j - i + 1)
                v[i:j] = (1 - w) * v[i - 1] + w * v[j]
            i = j
    return out


def audio_motion_windows(
    seq, speech15: np.ndarray, speech_valid15: np.ndarray, window: int = WINDOW, hop: int = HOP
) -> list[dict]:
    """Windows of ``window`` frames at 15 fps over the whole sequence (see module doc). A window whose face
    is tracked and whose speech is valid but whose body or hands are not (a head-and-shoulders clip, a long
    hand occlusion) is kept as a face-only window: its ``body`` is all NaN (``has_body`` False); the face
    head of the speech-to-gesture generator trains on it."""
    t = np.arange(len(speech15)) / GESTURE_FPS
    speech_ok = speech_valid15 & np.isfinite(speech15).all(1)
    idx = np.clip(np.round(t * seq.fps).astype(int), 0, seq.n_frames - 1)
    face_ok = (seq.flags[idx] & FLAG_NO_FACE) == 0
    face = face_motion(seq, t)
    face_ok &= np.isfinite(face).all(1)
    if seq.body_joints is not None:
        J = seq.body_joints.astype(np.float64).copy()
        # hips are usually out of view (desk, crop) and dropped for low visibility; they do not gesture, so
        # a missing hip takes its median position over the clip (MediaPipe's low-confidence estimate)
        raw = seq.body_joints_raw if seq.body_joints_raw is not None else J
        for j in (1, 2):
            med = (
                np.nanmedian(raw[:, j], axis=0)
                if np.isfinite(raw[:, j]).any()
                else np.array([0.1 if j == 1 else -0.1, 0, 0])
            )
            miss = ~np.isfinite(J[:, j]).all(-1)
            J[miss, j] = med
        J = fill_short_gaps(J, int(round(MAX_GAP_S * seq.fps)))
        body = resample_linear(J, seq.fps, t).reshape(len(t), -1)
        body_ok = np.isfinite(body).all(1)
    else:
        body = np.full((len(t), BODY_DIM), np.nan)
        body_ok = np.zeros(len(t), bool)
    out = []
    for s in range(0, len(t) - window + 1, hop):
        w = slice(s, s + window)
        if not speech_ok[w].all():
            continue
        full = bool(body_ok[w].all())
        if not full and not face_ok[w].all():
            continue
        b = body[w] if full else np.full((window, BODY_DIM), np.nan)
        out.append(
            {
                "start_frame": s,
                "start_s": s / GESTURE_FPS,
                "body": b.astype(np.float32),
                "has_body": full,
                "face": face[w],
                "speech": speech15[w].astype(np.float32),
            }
        )
    return out
