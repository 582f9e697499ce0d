"""Dataset build throughput and Ray scaling: the same videos built with 1 and then 2 local Ray workers, back
to back in one run (each into a fresh folder, through the ``anima dataset build`` command itself).
Writes benchmarks/results/dataset.json: videos/hour, captured frames per second per core, and the
speed-up ratio wall(1 worker) / wall(2 workers) (2.0 would be perfect scaling on 2 cores).

    python benchmarks/bench_dataset.py [--videos N] [--repeats R]
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

CLIPS = "gesture-video/pats-crops"


def build(videos: list[str], workers: int) -> tuple[float, dict]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "ds"
        t0 = time.perf_counter()
        subprocess.run(
            [
                sys.executable,
                "-m",
                "anima",
                "dataset",
                "build",
                *videos,
                "--out",
                str(out),
                "--workers",
                str(workers),
                "--quiet",
                "--json",
            ],
            check=True,
            capture_output=True,
        )
        wall = time.perf_counter() - t0
        return wall, json.loads((out / "manifest.json").read_text())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--videos", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "dataset.json"))
    a = ap.parse_args()
    videos = [str(p) for p in sorted(asset(CLIPS).glob("*.mp4"))[: a.videos]]
    runs = {1: [], 2: []}
    man = None
    for _ in range(a.repeats):
        for w in (1, 2):
            wall, man = build(videos, w)
            runs[w].append(wall)
    t1, t2 = statistics.median(runs[1]), statistics.median(runs[2])
    frames, compute = man["frames"], man["compute_s"]
    res = {
        "videos": [str(Path(v).relative_to(asset("."))) for v in videos],
        "frames": frames,
        "seconds_of_video": man["seconds_of_video"],
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "wall_s_1_worker": runs[1],
        "wall_s_2_workers": runs[2],
        "speedup_2_over_1": t1 / t2,
        "scaling_efficiency": t1 / t2 / 2,
        "videos_per_hour_2_workers": len(videos) / t2 * 3600,
        "frames_per_s_per_core": frames / compute,
        "note": "wall includes starting Ray (~4 s) and the final statistics pass; frames_per_s_per_core is "
        "captured frames / summed per-video task seconds",
    }
    write_json(a.out, res)
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
