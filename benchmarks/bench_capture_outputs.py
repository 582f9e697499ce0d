"""What the default outputs cost: ``anima capture CLIP`` (every file and video) against ``anima capture CLIP
--no-render`` (the tracked sequence, CSV, GLB, BVH; no videos) on the same clip, each a fresh command as a
user runs it, interleaved ``repeats`` times so machine noise hits both alike. The figure is the median over
repeats of the ratio of back-to-back pairs. Writes benchmarks/results/capture_outputs.json.

    python benchmarks/bench_capture_outputs.py [--clip REL_PATH] [--repeats R]
    python benchmarks/bench_capture_outputs.py --clip gesture-video/pats-crops/oliver1_gt.mp4 --target 1.5 \
        --out benchmarks/results/capture_outputs_half_body.json

Targets: the default outputs (the face close-up in ``avatar.mp4`` included) at most 1.4x the time of
--no-render on a face clip (d0, the default) and 1.5x on a half-body clip (a PATS host).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.video import probe_video

CLIP = "liveportrait-examples/assets/examples/driving/d0.mp4"  # the demo clip: 3.1 s, 512x512, a face


def timed(cmd: list[str]) -> float:
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clip", default=CLIP)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--target", type=float, default=1.4, help="the ratio the clip's default outputs may cost")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "capture_outputs.json"))
    a = ap.parse_args()
    clip = str(asset(a.clip))
    info = probe_video(clip)
    base = [sys.executable, "-m", "anima", "capture", clip, "--quiet"]
    env_note = {"RAY_AUTH_MODE": os.environ.get("RAY_AUTH_MODE")}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        timed(base + ["--out", f"{tmp}/warm", "--no-render"])  # numba caches and the page cache, once
        for r in range(a.repeats):
            nr = timed(base + ["--out", f"{tmp}/nr{r}", "--no-render"])
            full = timed(base + ["--out", f"{tmp}/full{r}"])
            rows.append({"no_render_s": nr, "default_s": full, "ratio": full / nr})
        videos = sorted(p.name for p in Path(f"{tmp}/full0").glob("*.mp4"))
    res = {
        "clip": a.clip,
        "frames": info.n_frames,
        "size": [info.width, info.height],
        "videos": videos,
        "repeats": rows,
        "no_render_s_median": statistics.median(r["no_render_s"] for r in rows),
        "default_s_median": statistics.median(r["default_s"] for r in rows),
        "ratio_median": statistics.median(r["ratio"] for r in rows),
        "target": f"ratio <= {a.target}",
        "met": statistics.median(r["ratio"] for r in rows) <= a.target,
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "env": env_note,
    }
    write_json(a.out, res)
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
