"""A long video in a dataset build: one Ray task for the whole video against one task per chunk, side by side
in one run, through the ``anima dataset build`` command itself (each build into a fresh folder).

The video is the longest the shared data holds (talking-heads-extra/pose_source2.mp4: 60 s, 1,499 frames).
With one task per video a long video keeps one worker busy while the others idle; with ``--chunk-len`` each
chunk is its own task. Three builds a repeat: 2 workers one task, 2 workers chunked (the default 15 s chunks,
1 s warm-up), and one worker pinned to one core (the per-core reference, as in bench_dataset.py). Writes
benchmarks/results/dataset_chunks.json: wall and task span (start-up excluded) of each, their ratios, and how
far the chunked build's motion is from the one-task build's (the tracker's state at each chunk start).

    python benchmarks/bench_dataset_chunks.py [--repeats R]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_dataset import build

from anima.io.assets import asset
from anima.io.atomic import write_json

VIDEO = "talking-heads-extra/pose_source2.mp4"


def motion(out: Path) -> tuple[np.ndarray, list]:
    import pyarrow.parquet as pq

    (shard,) = (out / "shards" / "text_motion").glob("*.parquet")
    t = pq.read_table(shard)
    x = np.concatenate([np.reshape(v, (-1, 56)) for v in t["motion"].to_pylist()])
    return x, t["start_s"].to_pylist()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--chunk-len", type=float, default=15.0)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "dataset_chunks.json"))
    a = ap.parse_args()
    video = [str(asset(VIDEO))]
    kinds = {
        "one_task_2_workers": dict(workers=2, extra=("--chunk-len", "0")),
        "chunked_2_workers": dict(workers=2, extra=("--chunk-len", str(a.chunk_len))),
        "one_task_1_worker_1_core": dict(workers=1, one_core=True, extra=("--chunk-len", "0")),
    }
    walls = {k: [] for k in kinds}
    spans = {k: [] for k in kinds}
    diffs = []
    for _ in range(a.repeats):
        got = {}
        for k, kw in kinds.items():
            wall, span, man, folder = build(video, keep=True, **kw)
            walls[k].append(wall)
            spans[k].append(span)
            got[k] = (man, motion(folder))
        (x, sx), (y, sy) = got["one_task_2_workers"][1], got["chunked_2_workers"][1]
        assert sx == sy, "the chunked build cut other clips"
        d = np.abs(x - y)
        diffs.append(
            {"mean_abs": float(d.mean()), "max_abs": float(d.max()), "mean_abs_value": float(np.abs(x).mean())}
        )
    w = {k: statistics.median(v) for k, v in walls.items()}
    s = {k: statistics.median(v) for k, v in spans.items()}
    man = got["chunked_2_workers"][0]
    res = {
        "video": VIDEO,
        "frames": man["frames"],
        "seconds_of_video": man["seconds_of_video"],
        "chunk_len_s": a.chunk_len,
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "python": platform.python_version(),
        "wall_s": walls,
        "task_span_s": spans,
        "speedup_chunked_over_one_task_2_workers": w["one_task_2_workers"] / w["chunked_2_workers"],
        "speedup_chunked_over_one_task_2_workers_startup_excluded": s["one_task_2_workers"] / s["chunked_2_workers"],
        "speedup_chunked_2_workers_over_1_core": w["one_task_1_worker_1_core"] / w["chunked_2_workers"],
        "speedup_chunked_2_workers_over_1_core_startup_excluded": s["one_task_1_worker_1_core"]
        / s["chunked_2_workers"],
        "motion_difference_chunked_vs_one_task": diffs,
        "note": "wall: the whole command; task span: the video's first task start to its last task end (start-up "
        "excluded). Medians over repeats. The clips (start times) of the chunked build equal the one-task build's "
        "(checked); motion difference: all 56 values of every clip frame.",
    }
    write_json(a.out, res)
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
