"""Temporal stability of the face capture (``anima eval stability``).

For each talking clip: MediaPipe landmarks are tracked once, then fitted twice, without and with the
temporal Gaussian filter (default sigma). Reported per clip (over frames with a face, 2D image landmarks):

* ``acc_raw``: mean landmark acceleration ``|x[t+1] - 2x[t] + x[t-1]|`` of raw MediaPipe, divided by the
  inter-ocular distance (landmarks 33-263) of that frame;
* ``acc_fit_smoothed``: the same for the smoothed fit's projected landmarks; ``acc_reduction`` = 1 - ratio
  (target >= 40 %);
* ``error_ratio_smoothed_vs_unsmoothed``: mean landmark error (px) of the smoothed fit over that of the
  unsmoothed fit (target <= 1.10: smoothing must not cost accuracy).
"""

from __future__ import annotations

import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.fit import LandmarkBasis
from anima.capture.pipeline import fit_landmark_sequence, track_landmarks
from anima.core.camera import camera_to_image, mediapipe_to_camera
from anima.eval.config import StabilityEval
from anima.eval.metrics import mean_acceleration
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.assets import asset
from anima.io.sequence import TrackedSequence
from anima.io.video import probe_video

DEFAULT_CLIPS = [
    "styletalk-samples/samples/source_video/video/Obama_clip1.mp4",
    "styletalk-samples/samples/source_video/video/andrew_clip_1.mp4",
    "styletalk-samples/samples/source_video/video/feifeili_clip1.mp4",
    "styletalk-samples/samples/source_video/video/KristiNoem.mp4",
    "videoretalking-examples/examples/face/1.mp4",
    "liveportrait-examples/assets/examples/driving/d10.mp4",
]


def fitted_landmarks_2d(seq: TrackedSequence, basis: LandmarkBasis) -> np.ndarray:
    """Projected model landmarks ``[F, K, 2]`` (image px) of a tracked sequence."""
    V = basis.points(seq.identity.astype(np.float64), seq.expression.astype(np.float64))
    R = seq.rotation_matrices()
    X = seq.scale[:, None, None] * (V @ R.transpose(0, 2, 1)) + seq.translation[:, None]
    return camera_to_image(X)


def stability_of_clip(path: str, max_frames: int | None = 300) -> dict:
    info = probe_video(path)
    lm = track_landmarks(info, max_frames, progress=False)
    basis = LandmarkBasis.build(load_face_model(), load_correspondence())
    found = np.isfinite(lm).all(axis=(1, 2))
    raw = camera_to_image(mediapipe_to_camera(lm[:, basis.index], info.width, info.height))
    seq_s = fit_landmark_sequence(lm, info.width, info.height, info.fps, CaptureConfig())
    seq_u = fit_landmark_sequence(lm, info.width, info.height, info.fps, CaptureConfig(smooth_sigma=0.0))
    fit_s = fitted_landmarks_2d(seq_s, basis)
    i33, i263 = basis.outer_eyes
    iod = np.linalg.norm(raw[:, i33] - raw[:, i263], axis=-1)
    # longest run of tracked frames (acceleration needs consecutive frames)
    sel = np.flatnonzero(found)
    acc_raw = mean_acceleration(raw[sel], iod[sel])
    acc_fit = mean_acceleration(fit_s[sel], iod[sel])
    err_s = float(np.nanmean(seq_s.fit_error_px))
    err_u = float(np.nanmean(seq_u.fit_error_px))
    return {
        "clip": path.split("/")[-1],
        "frames": int(len(lm)),
        "tracked": float(found.mean()),
        "acc_raw": acc_raw,
        "acc_fit_smoothed": acc_fit,
        "acc_fit_unsmoothed": mean_acceleration(fitted_landmarks_2d(seq_u, basis)[sel], iod[sel]),
        "acc_reduction": 1 - acc_fit / acc_raw,
        "error_px_smoothed": err_s,
        "error_px_unsmoothed": err_u,
        "error_ratio_smoothed_vs_unsmoothed": err_s / err_u,
    }


def evaluate_stability(clips: list[str] | None = None, max_frames: int | None = 300) -> dict:
    paths = clips or [str(asset(c)) for c in DEFAULT_CLIPS]
    rows = [stability_of_clip(p, max_frames) for p in paths]
    return {
        "filter": f"gaussian sigma={CaptureConfig().smooth_sigma} frames (zero-phase)",
        "clips": rows,
        "mean_acc_reduction": float(np.mean([r["acc_reduction"] for r in rows])),
        "mean_error_ratio": float(np.mean([r["error_ratio_smoothed_vs_unsmoothed"] for r in rows])),
        "targets": {"acc_reduction": ">= 0.40", "error_ratio": "<= 1.10"},
    }


def run(cfg: StabilityEval, progress: bool = False) -> dict:
    """``anima eval stability``."""
    return evaluate_stability(cfg.clips or None, max_frames=cfg.max_frames)


def summary(r: dict) -> list[str]:
    return [f"jitter reduction {100 * r['mean_acc_reduction']:.1f} %, error ratio {r['mean_error_ratio']:.3f}."]


def text(r: dict) -> str:
    lines = [f"{'clip':<28} {'acc raw':>9} {'acc fit':>9} {'reduction':>9} {'err ratio':>9}"]
    for c in r["clips"]:
        lines.append(
            f"{c['clip']:<28} {c['acc_raw']:>9.5f} {c['acc_fit_smoothed']:>9.5f} "
            f"{100 * c['acc_reduction']:>8.1f}% {c['error_ratio_smoothed_vs_unsmoothed']:>9.3f}"
        )
    lines.append(
        f"mean reduction {100 * r['mean_acc_reduction']:.1f}% (target >= 40%), "
        f"mean error ratio {r['mean_error_ratio']:.3f} (target <= 1.10)"
    )
    return "\n".join(lines)
