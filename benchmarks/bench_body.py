"""Body capture speed on 2 cores: full one-pass capture (decode + Holistic + the camera's motion from the
background + face fit + skeleton assembly and cleaning + speech features + the character in the world: root,
floor, contacts, foot locking, hands on the body, step limits) vs raw Holistic (decode + Holistic) on the same
frames. Writes benchmarks/results/body.json; the default clip is a full-body one (LivePortrait's s13, 720 x 1080),
``--clip`` another.

    python benchmarks/bench_body.py [--clip REL_PATH] [--repeats R]

The overhead ratio is the median over repeats of back-to-back (capture time / raw Holistic time) pairs.
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

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_video
from anima.export.avatar import character_motion
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.video import iter_frames, probe_video
from anima.track.mediapipe import HolisticTracker


def raw_holistic(path: str) -> float:
    info = probe_video(path)
    t0 = time.perf_counter()
    with HolisticTracker() as h:
        for f in iter_frames(info):
            h(f)
    return time.perf_counter() - t0


def full_capture(path: str) -> float:
    t0 = time.perf_counter()
    seq = capture_video(path, CaptureConfig(), progress=False)
    character_motion(seq)  # the character in the world: what every output of the capture is made from
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clip", default="liveportrait-examples/assets/examples/source/s13.mp4")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "body.json"))
    a = ap.parse_args()
    path = str(asset(a.clip))
    info = probe_video(path)
    load_face_model(), load_correspondence()
    capture_video(path, CaptureConfig(max_frames=10), progress=False)  # warm-up
    raw_t, full_t = [], []
    for _ in range(a.repeats):
        raw_t.append(raw_holistic(path))
        full_t.append(full_capture(path))
    res = {
        "clip": a.clip,
        "size": [info.width, info.height],
        "frames": info.n_frames,
        "repeats": a.repeats,
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "raw_holistic_fps": info.n_frames / statistics.median(raw_t),
        "capture_fps": info.n_frames / statistics.median(full_t),
        "overhead_ratio": statistics.median(f / r for f, r in zip(full_t, raw_t)),
        "target": {"overhead_ratio": "<= 1.25"},
        "raw_s": raw_t,
        "capture_s": full_t,
    }
    write_json(a.out, res)
    print(json.dumps({k: v for k, v in res.items() if not k.endswith("_s")}, indent=2))


if __name__ == "__main__":
    main()
