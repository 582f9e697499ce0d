"""60 s of gestures from a cold command: ``anima gesture SPEECH --db DATASET`` with its video
(``avatar.mp4``) and with ``--no-render``, each a fresh process as a user runs it, interleaved ``repeats``
times so machine noise hits both alike. Per run: the wall time around the process (start-up and exit
included) and the command's own split (``time_s`` of ``--json``: start, load, speech, search, post, write,
render). Writes benchmarks/results/gesture_command.json.

    python benchmarks/bench_gesture_command.py --db DATASET [--repeats 7] [--speech FILE]

The speech defaults to the first 60 s of talking-heads-extra/pose_source2.mp4 (a man talking). One untimed
run first makes the database cache and warms the page cache. Target: under 3 s with the video, the search
part under 1 s.
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
from anima.io.video import FFMPEG, probe_video

SPEECH = "talking-heads-extra/pose_source2.mp4"


def run(cmd: list[str]) -> tuple[float, dict]:
    t = time.perf_counter()
    r = subprocess.run(cmd, check=True, capture_output=True, text=True)
    wall = time.perf_counter() - t
    return wall, json.loads(r.stdout)["time_s"]


def summary(rows: list[dict]) -> dict:
    walls = [r["wall_s"] for r in rows]
    stages = {k for r in rows for k in r["time_s"]}
    return {
        "wall_s_median": round(statistics.median(walls), 3),
        "wall_s_range": [round(min(walls), 3), round(max(walls), 3)],
        "runs_under_3_s": sum(w < 3.0 for w in walls),
        "stage_s_median": {k: round(statistics.median(r["time_s"].get(k, 0.0) for r in rows), 3) for k in stages},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--db", required=True, help="a dataset from `anima dataset build`")
    ap.add_argument("--speech", default=None, help=f"speech file (default: 60 s of {SPEECH})")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "gesture_command.json"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        speech = a.speech
        if speech is None:
            speech = f"{tmp}/speech60.wav"
            src = str(asset(SPEECH))
            subprocess.run([FFMPEG, "-v", "error", "-y", "-i", src, "-t", "60", "-vn", speech], check=True)
        base = [sys.executable, "-m", "anima", "gesture", speech, "--db", a.db, "--json"]
        run(base + ["--out", f"{tmp}/warm"])  # the database cache, numba's caches and the page cache, once
        video, no_video = [], []
        for r in range(a.repeats):
            wall, t = run(base + ["--out", f"{tmp}/v{r}"])
            video.append({"wall_s": round(wall, 3), "time_s": t})
            wall, t = run(base + ["--out", f"{tmp}/n{r}", "--no-render"])
            no_video.append({"wall_s": round(wall, 3), "time_s": t})
        v = probe_video(f"{tmp}/v0/avatar.mp4")
    res = {
        "speech": a.speech or f"{SPEECH}, first 60 s",
        "db": a.db,
        "with_video": summary(video) | {"runs": video},
        "no_render": summary(no_video) | {"runs": no_video},
        "avatar_video": {"width": v.width, "height": v.height, "frames": v.n_frames, "fps": v.fps},
        "target": "with the video under 3 s end to end, the search under 1 s",
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
    }
    write_json(a.out, res)
    print(json.dumps({k: v for k, v in res.items() if k not in ("with_video", "no_render")}, indent=2))
    for k in ("with_video", "no_render"):
        print(k, json.dumps({x: y for x, y in res[k].items() if x != "runs"}))


if __name__ == "__main__":
    main()
