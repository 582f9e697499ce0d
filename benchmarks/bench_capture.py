"""Capture speed on 2 cores: end-to-end (decode + MediaPipe + fit) vs raw MediaPipe on the same frames,
and fitting alone. Writes benchmarks/results/capture.json.

    python benchmarks/bench_capture.py [--clip REL_PATH] [--frames N] [--repeats R]

Both pipelines run in the same process, interleaved, ``repeats`` times; the overhead ratio is the median
over repeats of (end-to-end time / raw MediaPipe time) of back-to-back pairs, so machine noise cancels out.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

os.environ.setdefault("GLOG_minloglevel", "2")

import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_face, fit_landmark_sequence
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.video import iter_frames, probe_video
from anima.track.mediapipe import FaceMeshTracker


def raw_mediapipe(path: str, n: int) -> tuple[float, np.ndarray]:
    """Decode + MediaPipe only (the baseline). Returns (seconds, landmarks)."""
    info = probe_video(path)
    t0 = time.perf_counter()
    out = []
    with FaceMeshTracker() as tr:
        for i, f in enumerate(iter_frames(info)):
            if i >= n:
                break
            lm = tr(f)
            out.append(np.full((478, 3), np.nan, np.float32) if lm is None else lm)
    return time.perf_counter() - t0, np.stack(out)


def end_to_end(path: str, n: int) -> float:
    t0 = time.perf_counter()
    capture_face(path, CaptureConfig(max_frames=n), progress=False)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--clip",
        default="liveportrait-examples/assets/examples/driving/d10.mp4",
        help="512x512 talking clip under the data root",
    )
    ap.add_argument("--frames", type=int, default=0, help="frames to use (0 = the whole clip)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "capture.json"))
    a = ap.parse_args()
    path = str(asset(a.clip))
    info = probe_video(path)
    n = min(a.frames, info.n_frames) if a.frames else info.n_frames
    load_face_model(), load_correspondence()  # loaded once, as in a long-running capture
    end_to_end(path, 10)  # warm-up (numba/JIT caches, file cache)
    raw_t, e2e_t = [], []
    lm = None
    for _ in range(a.repeats):
        t, lm = raw_mediapipe(path, n)
        raw_t.append(t)
        e2e_t.append(end_to_end(path, n))
    # fitting alone, on the tracked landmarks (tiled to >= 1000 frames)
    reps = int(np.ceil(1000 / len(lm)))
    lm_big = np.concatenate([lm] * reps)
    fit_landmark_sequence(lm_big[:50], info.width, info.height, info.fps, CaptureConfig())
    fit_t = []
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        fit_landmark_sequence(lm_big, info.width, info.height, info.fps, CaptureConfig())
        fit_t.append(time.perf_counter() - t0)
    raw_m, e2e_m, fit_m = statistics.median(raw_t), statistics.median(e2e_t), statistics.median(fit_t)
    res = {
        "clip": a.clip,
        "size": [info.width, info.height],
        "frames": n,
        "repeats": a.repeats,
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "raw_mediapipe_fps": n / raw_m,
        "end_to_end_capture_fps": n / e2e_m,
        "overhead_ratio": statistics.median(e / r for e, r in zip(e2e_t, raw_t)),
        "fit_only_fps": len(lm_big) / fit_m,
        "fit_only_frames": len(lm_big),
        "targets": {"end_to_end_capture_fps": ">= 25", "fit_only_fps": ">= 300", "overhead_ratio": "<= 1.25"},
        "raw_s": raw_t,
        "end_to_end_s": e2e_t,
        "fit_s": fit_t,
    }
    write_json(a.out, res)
    print(json.dumps({k: v for k, v in res.items() if not k.endswith("_s")}, indent=2))


if __name__ == "__main__":
    main()
