"""Text -> face sampling speed: 90 frames from one prompt with the cached autoregressive sampler vs the
uncached one (FaceFormer's: the whole prefix recomputed every step), same checkpoint, prompt and seed, in one
run. Writes benchmarks/results/text2face.json.

    python benchmarks/bench_text2face.py [--checkpoint CKPT] [--frames 90] [--repeats 7]

Timed: the sampler alone (text embedding given) and the whole call a user makes (prompt -> motion, the MiniLM
encoding included). Target: < 0.5 s for 90 frames on 2 cores. Also times the seed-size model (13.6 M
parameters, freshly initialised: speed does not depend on the weights).
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
from anima.text2face.generate import Generator
from anima.text2face.model import Text2Face, preset

PROMPT = "A woman smiles for a short time, then she blinks and raises the eyebrows briefly"


def timeit(fn, repeats):
    fn()  # warm-up
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return statistics.median(out), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "text2face.json"))
    a = ap.parse_args()
    g = Generator(a.checkpoint)
    E = g.embed([PROMPT])
    cached, cr = timeit(lambda: g.generate_from_embeddings(E, a.frames, 0, cached=True), a.repeats)
    uncached, ur = timeit(lambda: g.generate_from_embeddings(E, a.frames, 0, cached=False), a.repeats)
    same = np.allclose(
        g.generate_from_embeddings(E, a.frames, 0, cached=True),
        g.generate_from_embeddings(E, a.frames, 0, cached=False),
        atol=1e-4,
    )
    full, fr = timeit(lambda: g.generate([PROMPT], a.frames, 0), a.repeats)
    torch.manual_seed(0)
    big = Text2Face(preset("seed")).eval()
    e, c = torch.from_numpy(E), torch.randn(1, 64)
    big_cached, _ = timeit(lambda: big.sample(e, c, a.frames, cached=True), max(3, a.repeats // 2))
    big_uncached, _ = timeit(lambda: big.sample(e, c, a.frames, cached=False), max(3, a.repeats // 2))
    res = {
        "checkpoint": str(g.path),
        "frames": a.frames,
        "prompt": PROMPT,
        "parameters": sum(p.numel() for p in g.model.parameters()),
        "torch_threads": torch.get_num_threads(),
        "cpu_count": os.cpu_count(),
        "machine": platform.machine(),
        "cached_s": cached,
        "uncached_s": uncached,
        "speedup_cached_over_uncached": uncached / cached,
        "cached_equals_uncached": bool(same),
        "prompt_to_motion_s": full,
        "seed_size_model": {
            "parameters": sum(p.numel() for p in big.parameters()),
            "cached_s": big_cached,
            "uncached_s": big_uncached,
            "speedup": big_uncached / big_cached,
        },
        "target": {"prompt_to_motion_s": "< 0.5 for 90 frames"},
        "cached_runs": cr,
        "uncached_runs": ur,
        "prompt_to_motion_runs": fr,
    }
    write_json(a.out, res)
    print(json.dumps({k: v for k, v in res.items() if not k.endswith("_runs")}, indent=2))


if __name__ == "__main__":
    main()
