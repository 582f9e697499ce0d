"""Body and hand capture report (``anima eval body``): per clip, body tracked %, each hand tracked %, the
same after interpolation of short drop-outs, and the bone-length coefficient of variation before and after
cleaning (it must drop); plus the hand detector on the still images of ``hand-images/``."""

from __future__ import annotations

import glob

import numpy as np

from anima.capture.body import assemble, bone_length_cv, clean
from anima.capture.config import CaptureConfig
from anima.capture.pipeline import track_holistic
from anima.core.skeleton import LEFT_HAND, RIGHT_HAND
from anima.eval.config import BodyEval
from anima.io.assets import asset
from anima.io.video import probe_video
from anima.track import get

DEFAULT_SETS = [
    "gesture-video/pats-crops/*.mp4",
    "gesture-video/tango-interviews/*.mp4",
    "talking-heads-misc/LatentSync/assets/*.mp4",
]


def body_report_clip(path: str, cfg: CaptureConfig | None = None, max_frames: int | None = None) -> dict:
    cfg = cfg or CaptureConfig()
    info = probe_video(path)
    _, frames = track_holistic(info, max_frames, progress=False, tracker=cfg.tracker)
    raw = assemble(frames, info.width, info.height, info.fps)
    c = clean(raw, cfg.body_min_conf, cfg.max_gap, cfg.body_sigma, False)
    ok_raw = np.isfinite(raw.joints).all(-1)
    ok = np.isfinite(c.joints).all(-1)
    return {
        "clip": path.split("/")[-1],
        "frames": len(frames),
        "size": [info.width, info.height],
        "fps": info.fps,
        "body_tracked": float(ok_raw[:, :13].all(1).mean()),
        "left_hand_tracked": float(ok_raw[:, LEFT_HAND].all(1).mean()),
        "right_hand_tracked": float(ok_raw[:, RIGHT_HAND].all(1).mean()),
        "left_hand_after_interpolation": float(ok[:, LEFT_HAND].all(1).mean()),
        "right_hand_after_interpolation": float(ok[:, RIGHT_HAND].all(1).mean()),
        "bone_cv_raw": bone_length_cv(raw.joints),
        "bone_cv_cleaned": bone_length_cv(c.joints),
    }


def hand_images_report() -> list[dict]:
    import cv2

    rows = []
    with get().hands(static=True, max_hands=4) as hands:
        for p in sorted(glob.glob(str(asset("hand-images")) + "/**/*.jpg", recursive=True)):
            img = cv2.imread(p)
            found = hands(np.ascontiguousarray(img[:, :, ::-1]))
            scores = [round(h.score, 3) for h in found]
            rows.append({"image": p.split("/")[-1], "hands_found": len(found), "scores": scores})
    return rows


def evaluate_body(patterns: list[str] | None = None, max_frames: int | None = None, progress: bool = True) -> dict:
    from tqdm import tqdm

    paths = []
    for pat in patterns or DEFAULT_SETS:
        paths += sorted(glob.glob(str(asset(pat.split("*")[0].rstrip("/"))) + "/" + pat.split("/")[-1]))
    rows = [body_report_clip(p, max_frames=max_frames) for p in tqdm(paths, desc="clips", disable=not progress)]
    keys = [
        "body_tracked",
        "left_hand_tracked",
        "right_hand_tracked",
        "left_hand_after_interpolation",
        "right_hand_after_interpolation",
        "bone_cv_raw",
        "bone_cv_cleaned",
    ]
    return {
        "clips": rows,
        "mean": {k: float(np.mean([r[k] for r in rows])) for k in keys} if rows else {},
        "bone_cv_dropped_on": f"{sum(r['bone_cv_cleaned'] < r['bone_cv_raw'] for r in rows)}/{len(rows)} clips",
        "hand_images": hand_images_report(),
    }


def run(cfg: BodyEval, progress: bool = False) -> dict:
    """``anima eval body``."""
    return evaluate_body(cfg.clips or None, cfg.max_frames, progress=progress)


def summary(r: dict) -> list[str]:
    """Markdown of ``eval all`` and of the docs' generated block: per clip, tracked fractions and the
    bone-length coefficient of variation before and after cleaning."""
    out = [
        "| clip | body tracked | left hand | right hand | left hand after interpolation | right hand after "
        "interpolation | bone-length CV raw / cleaned |",
        "|---|---|---|---|---|---|---|",
    ]
    for c in r["clips"]:
        out.append(
            f"| {c['clip']} | {100 * c['body_tracked']:.1f} % | {100 * c['left_hand_tracked']:.1f} % | "
            f"{100 * c['right_hand_tracked']:.1f} % | {100 * c['left_hand_after_interpolation']:.1f} % | "
            f"{100 * c['right_hand_after_interpolation']:.1f} % | {c['bone_cv_raw']:.3f} / {c['bone_cv_cleaned']:.3f} |"
        )
    out += ["", f"Bone-length CV dropped on {r['bone_cv_dropped_on']}."]
    out += [f"Hand image {h['image']}: {h['hands_found']} hand(s) found." for h in r["hand_images"]]
    return out


def text(r: dict) -> str:
    lines = [
        f"{'clip':<44} {'body':>6} {'L hand':>7} {'R hand':>7} {'L int':>6} {'R int':>6} {'CV raw':>7} {'CV cln':>7}"
    ]
    for c in r["clips"]:
        lines.append(
            f"{c['clip'][:44]:<44} {100 * c['body_tracked']:>5.1f}% {100 * c['left_hand_tracked']:>6.1f}% "
            f"{100 * c['right_hand_tracked']:>6.1f}% {100 * c['left_hand_after_interpolation']:>5.1f}% "
            f"{100 * c['right_hand_after_interpolation']:>5.1f}% {c['bone_cv_raw']:>7.3f} "
            f"{c['bone_cv_cleaned']:>7.3f}"
        )
    lines.append(f"bone-length CV dropped on {r['bone_cv_dropped_on']}")
    lines += [f"hand image {h['image']}: {h['hands_found']} hand(s) {h['scores']}" for h in r["hand_images"]]
    return "\n".join(lines)
