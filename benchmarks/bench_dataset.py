"""Dataset build throughput and Ray scaling: the same videos built with 1 and then 2 local Ray workers, back
to back in one run (each into a fresh folder, through the ``anima dataset build`` command itself).
Writes benchmarks/results/dataset.json: videos/hour, captured frames per second per core, and the
speed-up ratio wall(1 worker) / wall(2 workers) (2.0 would be perfect scaling on 2 cores), with the fixed
start-up and without it (the span of the video tasks).

One worker is measured twice: free to use every core (its MediaPipe threads, the ffmpeg decoder and the
fit-while-tracking thread spill onto the idle second core, so "1 worker" is about 1.35 cores here), and
pinned to one core (the command and every process it starts, Ray's included, inherit the affinity), which is
what a worker gets on a cluster that gives each task one CPU. Both ratios are written.

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
_KEEP: list = []  # temporary folders of kept builds (removed when the interpreter exits)


def build(videos: list[str], workers: int, one_core: bool = False, extra: tuple = (), keep: bool = False):
    """``anima dataset build`` of ``videos`` with ``workers`` Ray workers; ``one_core``: the command and all it
    starts confined to the first CPU this process may use; ``extra``: more options. Returns (wall s, task span
    s, manifest), and with ``keep`` the dataset folder too (a temporary folder removed at exit)."""
    pin = None
    if one_core:
        first = min(os.sched_getaffinity(0))
        pin = lambda: os.sched_setaffinity(0, {first})  # runs in the child, before exec
    tmp = tempfile.TemporaryDirectory()
    _KEEP.append(tmp)
    out = Path(tmp.name) / "ds"
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
            *extra,
        ],
        check=True,
        capture_output=True,
        preexec_fn=pin,
    )
    wall = time.perf_counter() - t0
    tasks = [json.loads(f.read_text()) for f in (out / "videos").glob("*.json")]
    span = max(t["ended_at"] for t in tasks) - min(t["started_at"] for t in tasks)
    man = json.loads((out / "manifest.json").read_text())
    if keep:
        return wall, span, man, out
    tmp.cleanup()
    return wall, span, man


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--videos", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "dataset.json"))
    a = ap.parse_args()
    videos = [str(p) for p in sorted(asset(CLIPS).glob("*.mp4"))[: a.videos]]
    runs = {1: [], 2: [], "1_core": []}
    spans = {1: [], 2: [], "1_core": []}
    man = None
    for _ in range(a.repeats):
        for w in (1, "1_core", 2):
            wall, span, m = build(videos, 1 if w == "1_core" else w, one_core=w == "1_core")
            man = m if w == 2 else man
            runs[w].append(wall)
            spans[w].append(span)
    t1, t2, tc = (statistics.median(runs[k]) for k in (1, 2, "1_core"))
    s1, s2, sc = (statistics.median(spans[k]) for k in (1, 2, "1_core"))
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
        "task_span_s_1_worker": spans[1],
        "task_span_s_2_workers": spans[2],
        "speedup_2_over_1_startup_excluded": s1 / s2,
        "startup_s": {"1_worker": t1 - s1, "2_workers": t2 - s2, "1_worker_1_core": tc - sc},
        "wall_s_1_worker_1_core": runs["1_core"],
        "task_span_s_1_worker_1_core": spans["1_core"],
        "speedup_2_workers_over_1_worker_on_1_core": tc / t2,
        "speedup_2_workers_over_1_worker_on_1_core_startup_excluded": sc / s2,
        "videos_per_hour_2_workers": len(videos) / t2 * 3600,
        "frames_per_s_per_core": frames / compute,
        "note": "wall: the whole command (starting Ray and its workers, the final statistics pass); task span: "
        "from the first video task's start to the last one's end (start-up excluded); startup_s = wall - span. "
        "frames_per_s_per_core is captured frames / summed per-video task seconds (2-worker run); "
        "1_core: one worker with the command and every process it starts pinned to one CPU",
    }
    write_json(a.out, res)
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
