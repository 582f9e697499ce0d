"""Temporal stability of the face capture (``anima eval stability``).

For each talking clip: MediaPipe landmarks are tracked once, then fitted twice, without and with the
temporal Gaussian filter (default sigma). Reported per clip (over frames with a face, 2D image landmarks):

* ``acc_raw``: mean landmark acceleration ``|x[t+1] - 2x[t] + x[t-1]|`` of raw MediaPipe, divided by the
  inter-ocular distance (landmarks 33-263) of that frame;
* ``acc_fit_smoothed``: the same for the smoothed fit's projected landmarks; ``acc_reduction`` = 1 - ratio
  (target >= 40 %);
* ``error_ratio_smoothed_vs_unsmoothed``: mean landmark error (px) of the smoothed fit over that of the
  unsmoothed fit (target <= 1.10: smoothing must not cost accuracy).

The filter's sigma is chosen on **validation** clips (:data:`VALIDATION_CLIPS`, validation split of
:mod:`anima.dataset.splits`) by :func:`choose_sigma`: always one whose mean error ratio there is within 1.10,
among those that also reach a 40 % mean reduction the one the dataset's detectors do best with; where no sigma
keeps the error ratio within 1.10 on validation, none is chosen and the result says so. The report is on
**test** clips (:data:`DEFAULT_CLIPS`, test split), with the capture's default and with the chosen sigma, and
says for each, on validation and on test, whether it meets the targets (``targets_met``, ``verdict``): the
reported clips choose nothing.
"""

from __future__ import annotations

import numpy as np

from anima.capture.config import FIT_FOR_DETECTORS, CaptureConfig
from anima.capture.fit import LandmarkBasis
from anima.capture.pipeline import fit_landmark_sequence, track_landmarks
from anima.core.camera import camera_to_image, mediapipe_to_camera
from anima.eval.annotations import detectors_by_smoothing
from anima.eval.config import StabilityEval
from anima.eval.metrics import mean_acceleration
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.assets import asset
from anima.io.sequence import TrackedSequence
from anima.io.video import probe_video

DEFAULT_CLIPS = [  # talking faces of the test split (EDTalk's pose source, one recording with
    # video-retalking's face 3, is train: the two are one interview)
    "videoretalking-examples/examples/face/5.mp4",
    "liveportrait-examples/assets/examples/driving/d10.mp4",
    "liveportrait-examples/assets/examples/driving/d20.mp4",
    "styletalk-samples/samples/style_clips/video/happyenglish_clip1.mp4",
    "styletalk-samples/samples/style_clips/video/nice_clip1.mp4",
]
VALIDATION_CLIPS = [  # talking faces of the validation split (face 3 went with the interview it copies)
    "talking-heads-misc/MimicTalk/data/raw/examples/German_20s.mp4",
    "talking-heads-misc/LatentSync/assets/demo2_video.mp4",
    "styletalk-samples/samples/style_clips/video/trump_clip1.mp4",
    "liveportrait-examples/assets/examples/driving/d11.mp4",
]
SIGMAS = (0.5, 0.75, 1.0, 1.5, 2.0)  # frames
DETECTORS_CALIBRATED_AT = 1.0  # the capture smoothing the dataset's detector thresholds were calibrated on
TARGET_REDUCTION, TARGET_RATIO = 0.40, 1.10


def fitted_landmarks_2d(seq: TrackedSequence, basis: LandmarkBasis) -> np.ndarray:
    """Projected model landmarks ``[F, K, 2]`` (image px) of a tracked sequence."""
    V = basis.points(seq.identity.astype(np.float64), seq.expression.astype(np.float64))
    R = seq.rotation_matrices()
    X = seq.scale[:, None, None] * (V @ R.transpose(0, 2, 1)) + seq.translation[:, None]
    return camera_to_image(X)


def stability_of_clip(path: str, max_frames: int | None = 300, sigmas=None) -> dict:
    """One clip, tracked once and fitted unsmoothed and with each sigma (default: the capture's)."""
    info = probe_video(path)
    lm = track_landmarks(info, max_frames, progress=False)
    basis = LandmarkBasis.build(load_face_model(), load_correspondence())
    found = np.isfinite(lm).all(axis=(1, 2))
    raw = camera_to_image(mediapipe_to_camera(lm[:, basis.index], info.width, info.height))
    seq_u = fit_landmark_sequence(
        lm, info.width, info.height, info.fps, CaptureConfig(smooth_sigma=0.0, fit=FIT_FOR_DETECTORS)
    )
    i33, i263 = basis.outer_eyes
    iod = np.linalg.norm(raw[:, i33] - raw[:, i263], axis=-1)
    sel = np.flatnonzero(found)
    acc_raw = mean_acceleration(raw[sel], iod[sel])
    err_u = float(np.nanmean(seq_u.fit_error_px))
    default = CaptureConfig().smooth_sigma
    per = {}
    for sg in sorted(set(sigmas or ()) | {default}):
        seq_s = fit_landmark_sequence(
            lm, info.width, info.height, info.fps, CaptureConfig(smooth_sigma=sg, fit=FIT_FOR_DETECTORS)
        )
        acc_fit = mean_acceleration(fitted_landmarks_2d(seq_s, basis)[sel], iod[sel])
        err_s = float(np.nanmean(seq_s.fit_error_px))
        per[str(sg)] = {"acc_reduction": 1 - acc_fit / acc_raw, "error_ratio": err_s / err_u, "acc_fit": acc_fit}
    d = per[str(default)]
    return {
        "clip": path.split("/")[-1],
        "frames": int(len(lm)),
        "tracked": float(found.mean()),
        "acc_raw": acc_raw,
        "acc_fit_smoothed": d["acc_fit"],
        "acc_fit_unsmoothed": mean_acceleration(fitted_landmarks_2d(seq_u, basis)[sel], iod[sel]),
        "acc_reduction": d["acc_reduction"],
        "error_px_smoothed": d["error_ratio"] * err_u,
        "error_px_unsmoothed": err_u,
        "error_ratio_smoothed_vs_unsmoothed": d["error_ratio"],
        "per_sigma": per,
    }


def meets_targets(reduction: float, ratio: float) -> bool:
    """Whether a mean jitter reduction and a mean error ratio meet :data:`TARGET_REDUCTION` and
    :data:`TARGET_RATIO`."""
    return reduction >= TARGET_REDUCTION and ratio <= TARGET_RATIO


def choose_sigma(rows: list[dict], detectors: dict | None = None) -> dict:
    """The sigma the validation ``rows`` choose, always one whose mean error ratio over them is within
    :data:`TARGET_RATIO` (smoothing must not cost accuracy): ``chosen_by_jitter``, the smallest sigma whose mean
    reduction also reaches :data:`TARGET_REDUCTION` (none does: the best reduction among those within the error
    bound, and ``meets_targets`` False); none within the error bound: None (the result says so in
    ``no_choice``).

    With ``detectors`` (:func:`anima.eval.annotations.detectors_by_smoothing`: the shipped detectors' mean
    event F1 per sigma on the labelled clips outside the test split), the capture's smoothing is chosen
    together with the detectors, among the sigmas that meet both targets: the smallest whose detector F1 is at
    least that at :data:`DETECTORS_CALIBRATED_AT` (the smoothing the shipped thresholds were calibrated on),
    else the one with the best F1; none meets both targets: ``chosen_by_jitter``. This is ``chosen``."""
    sig = sorted(float(k) for k in rows[0]["per_sigma"])
    mean = {
        s: (
            float(np.mean([r["per_sigma"][str(s)]["acc_reduction"] for r in rows])),
            float(np.mean([r["per_sigma"][str(s)]["error_ratio"] for r in rows])),
        )
        for s in sig
    }
    ok = [s for s in sig if meets_targets(*mean[s])]
    within = [s for s in sig if mean[s][1] <= TARGET_RATIO]
    by_jitter = ok[0] if ok else (max(within, key=lambda s: mean[s][0]) if within else None)
    out = {
        "rule": f"a sigma with mean error ratio <= {TARGET_RATIO} on validation: the smallest with mean reduction "
        f">= {TARGET_REDUCTION} too (none: the best reduction within the error bound)",
        "per_sigma": {str(s): {"acc_reduction": a, "error_ratio": e} for s, (a, e) in mean.items()},
        "chosen_by_jitter": by_jitter,
        "chosen": by_jitter,
    }
    if detectors:
        f1 = {float(k): v["mean_f1"] for k, v in detectors["per_sigma"].items()}
        floor = f1[DETECTORS_CALIBRATED_AT]
        joint = [s for s in ok if f1.get(s, -1.0) >= floor]
        out["rule"] += (
            f"; with the detectors, among the sigmas meeting both targets, the smallest at which the shipped "
            f"detectors' mean event F1 on the labelled clips outside the test split is at least that at sigma "
            f"{DETECTORS_CALIBRATED_AT} (their calibration), else the one with the best F1"
        )
        out["detectors"] = detectors
        if ok:
            out["chosen"] = joint[0] if joint else max(ok, key=lambda s: (f1.get(s, -1.0), -s))
    chosen = out["chosen"]
    out["meets_targets"] = chosen is not None and meets_targets(*mean[chosen])
    if chosen is None:
        out["no_choice"] = f"no sigma keeps the mean error ratio within {TARGET_RATIO} on the validation clips"
    return out


def _means(rows: list[dict], sigma) -> tuple[float, float]:
    return (
        float(np.mean([r["per_sigma"][str(sigma)]["acc_reduction"] for r in rows])),
        float(np.mean([r["per_sigma"][str(sigma)]["error_ratio"] for r in rows])),
    )


def _pair(d: dict) -> tuple[float, float]:
    return d["acc_reduction"], d["error_ratio"]


def verdict(r: dict) -> list[str]:
    """Whether the chosen sigma and the capture's default meet the targets on the validation clips and on the
    test clips, in words, from a result's numbers (what ``summary`` prints and the result records)."""
    s = r.get("sigma_selection")
    if not s:
        return []
    chosen, default, val = s.get("chosen"), s["default"], s["per_sigma"]
    n_val, n_test = len(s["clips"]), len(r["clips"])

    def said(red, ratio):
        miss = [w for w, bad in (("reduction", red < TARGET_REDUCTION), ("error ratio", ratio > TARGET_RATIO)) if bad]
        how = f"{100 * red:.1f} % / {ratio:.3f}"
        return f"{how}, meets the targets" if not miss else f"{how}, misses the {' and the '.join(miss)} target"

    out = []
    if chosen is None:
        out.append(f"No sigma chosen: {s.get('no_choice', 'none meets the rule')}.")
    else:
        out.append(f"Chosen sigma {chosen} on the {n_val} validation clips: {said(*_pair(val[str(chosen)]))}.")
    if chosen != default:
        out.append(
            f"The capture's default, sigma {default}, is not the choice; on the {n_val} validation clips: "
            f"{said(*_pair(val[str(default)]))}."
        )
    test = f"On the {n_test} test clips at the default ({default}): "
    test += said(r["mean_acc_reduction"], r["mean_error_ratio"])
    if chosen is not None and chosen != default and r.get("at_chosen_sigma"):
        c = r["at_chosen_sigma"]
        test += f"; at the chosen sigma ({chosen}): {said(c['mean_acc_reduction'], c['mean_error_ratio'])}"
    return out + [test + "."]


def evaluate_stability(clips: list[str] | None = None, max_frames: int | None = 300) -> dict:
    default = CaptureConfig().smooth_sigma
    selection = None
    if not clips:  # the shared clips: sigma chosen on the validation clips, reported on the test clips
        val = [stability_of_clip(str(asset(c)), max_frames, SIGMAS) for c in VALIDATION_CLIPS]
        selection = choose_sigma(val, detectors_by_smoothing(SIGMAS)) | {
            "clips": [r["clip"] for r in val],
            "split": "validation",
        }
    paths = clips or [str(asset(c)) for c in DEFAULT_CLIPS]
    chosen = selection["chosen"] if selection else default
    rows = [stability_of_clip(p, max_frames, {chosen} if chosen is not None else None) for p in paths]
    out = {
        "filter": f"gaussian sigma={default} frames (zero-phase)",
        "clips": rows,
        "split": "test" if not clips else "given clips",
        "mean_acc_reduction": float(np.mean([r["acc_reduction"] for r in rows])),
        "mean_error_ratio": float(np.mean([r["error_ratio_smoothed_vs_unsmoothed"] for r in rows])),
        "targets": {"acc_reduction": f">= {TARGET_REDUCTION}", "error_ratio": f"<= {TARGET_RATIO}"},
    }
    met = {"default": meets_targets(out["mean_acc_reduction"], out["mean_error_ratio"])}
    if selection:
        sel = selection["per_sigma"]
        out["sigma_selection"] = selection | {"default": default, "default_is_the_choice": chosen == default}
        targets = {"validation": {"default": meets_targets(*_pair(sel[str(default)]))}}
        if chosen is not None:
            out["at_chosen_sigma"] = dict(zip(("mean_acc_reduction", "mean_error_ratio"), _means(rows, chosen)))
            targets["validation"]["chosen"] = selection["meets_targets"]
            met["chosen"] = meets_targets(*_means(rows, chosen))
        out["targets_met"] = targets | {out["split"]: met}
        out["verdict"] = " ".join(verdict(out))
    else:
        out["targets_met"] = {out["split"]: met}
    return out


def run(cfg: StabilityEval, progress: bool = False) -> dict:
    """``anima eval stability``."""
    return evaluate_stability(cfg.clips or None, max_frames=cfg.max_frames)


def summary(r: dict) -> list[str]:
    out = ["| clip | jitter reduction | error ratio (smoothed / unsmoothed) |", "|---|---|---|"]
    for c in r["clips"]:
        ratio = c["error_ratio_smoothed_vs_unsmoothed"]
        out.append(f"| {c['clip']} | {100 * c['acc_reduction']:.1f} % | {ratio:.3f} |")
    out.append(
        f"| **mean ({r.get('split', 'given clips')}, sigma {r['filter'].split('=')[1].split()[0]})** | "
        f"**{100 * r['mean_acc_reduction']:.1f} %** | **{r['mean_error_ratio']:.3f}** |"
    )
    chosen, c = (r.get("sigma_selection") or {}).get("chosen"), r.get("at_chosen_sigma")
    if c and chosen is not None and not r["sigma_selection"].get("default_is_the_choice"):
        out.append(
            f"| **mean ({r.get('split', 'given clips')}, sigma {chosen}: the validation's choice)** | "
            f"**{100 * c['mean_acc_reduction']:.1f} %** | **{c['mean_error_ratio']:.3f}** |"
        )
    if r.get("sigma_selection"):
        s = r["sigma_selection"]
        per = ", ".join(
            f"{k}: {100 * v['acc_reduction']:.0f} % / {v['error_ratio']:.3f}" for k, v in s["per_sigma"].items()
        )
        out += [
            "",
            f"Sigma chosen on {len(s['clips'])} validation clips ({', '.join(s['clips'])}; {s['rule']}): "
            f"**{s['chosen'] if s['chosen'] is not None else 'none'}** (the default: {s['default']}; "
            f"by jitter alone: {s.get('chosen_by_jitter', s['chosen'])}). "
            f"Validation means per sigma (reduction / ratio): {per}.",
        ]
        out += ["", *[f"**{line}**" if i == 0 else line for i, line in enumerate(verdict(r))]]
        if s.get("detectors"):
            d = s["detectors"]
            f1 = ", ".join(f"{k}: {v['mean_f1']:.3f}" for k, v in d["per_sigma"].items())
            out.append("")
            out.append(
                f"Shipped detectors' mean event F1 per sigma on the {len(d['clips'])} labelled clips outside the "
                f"test split ({', '.join(d['clips'])}): {f1}."
            )
    return out


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
    return "\n".join(lines + verdict(r))
