"""Lifter inference speed on this machine: batched (all frames of a clip at once, the way capture calls it)
vs one frame at a time, on the same inputs, in one run. Writes benchmarks/results/pose.json.

    python benchmarks/bench_pose.py [--checkpoint CKPT] [--frames N] [--repeats R]

Without a checkpoint, a freshly initialised network of the default (seed) size is timed: speed does not
depend on the weights. Inputs are real Human3.6M S1 2D projections. Target: < 1 ms per frame batched.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from anima.io.atomic import write_json
from anima.pose3d.data import load_h36m
from anima.pose3d.model import Lifter, LifterConfig
from anima.pose3d.train import load_checkpoint, predict


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--frames", type=int, default=2000)
    ap.add_argument("--single", type=int, default=200, help="frames timed one by one")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "pose.json"))
    a = ap.parse_args()
    if a.checkpoint:
        model, ck = load_checkpoint(Path(a.checkpoint))
        cfg = ck["config"]["model"]
    else:
        torch.manual_seed(0)
        model = Lifter(LifterConfig()).eval()
        cfg = LifterConfig().to_dict()
    h = load_h36m(("S1",), every=1)
    uv = h.uv[: a.frames].astype(np.float64)
    conf = np.ones(uv.shape[:2])
    predict(model, uv[:64], conf[:64])  # warm-up
    batched, single = [], []
    for _ in range(a.repeats):
        t0 = time.perf_counter()
        predict(model, uv, conf)
        batched.append((time.perf_counter() - t0) / len(uv) * 1000)
        t0 = time.perf_counter()
        for i in range(a.single):
            predict(model, uv[i : i + 1], conf[i : i + 1])
        single.append((time.perf_counter() - t0) / a.single * 1000)
    b, s = statistics.median(batched), statistics.median(single)
    res = {
        "model": cfg,
        "parameters": sum(p.numel() for p in model.parameters()),
        "frames": len(uv),
        "torch_threads": torch.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "batched_ms_per_frame": b,
        "single_ms_per_frame": s,
        "speedup_batched_over_single": s / b,
        "target": {"batched_ms_per_frame": "< 1"},
        "batched_runs": batched,
        "single_runs": single,
    }
    write_json(a.out, res)
    print(json.dumps({k: v for k, v in res.items() if not k.endswith("_runs")}, indent=2))


if __name__ == "__main__":
    main()
