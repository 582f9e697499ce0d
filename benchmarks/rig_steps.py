"""The largest frame-to-frame turn of any bone direction of the character (`anima.core.rig`), on PATS clips the
finger and hand snap rules were not chosen on (their thresholds were set looking at oliver1, seth3, noah1 and
chem1): the target is no bone turning more than 45 degrees between frames.

    python benchmarks/rig_steps.py [--clips chem2,noah2,oliver2,seth1] [--frames 150]

Writes benchmarks/results/rig_steps.json. For the numbers before the rules, run it with anima/core/rig.py
of commit 13d4612 checked out."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_video
from anima.core import rig
from anima.export.avatar import character_motion
from anima.export.retarget import _plan
from anima.io.assets import asset
from anima.io.atomic import write_json


def max_steps(P: np.ndarray) -> dict[str, float]:
    """Per bone (to the next joint down its chain) the largest turn between consecutive frames, degrees."""
    out = {}
    for b, (aim, _) in _plan(set(rig.NAMES)).items():
        if aim:
            d = P[:, rig.IX[aim]] - P[:, rig.IX[b]]
            c = (d[1:] * d[:-1]).sum(-1) / np.linalg.norm(d[1:], axis=-1) / np.linalg.norm(d[:-1], axis=-1)
            out[b] = float(np.degrees(np.arccos(np.clip(c, -1, 1))).max())
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", default="chem2,noah2,oliver2,seth1")
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "rig_steps.json"))
    a = ap.parse_args()
    rows = {}
    for n in a.clips.split(","):
        seq = capture_video(str(asset(f"gesture-video/pats-crops/{n}_gt.mp4")), CaptureConfig(max_frames=a.frames),
                            progress=False)  # fmt: skip
        steps = max_steps(character_motion(seq)["positions"])
        worst = max(steps, key=steps.get)
        rows[n] = {"frames": seq.n_frames, "max_step_deg": round(steps[worst], 1), "bone": worst,
                   "bones_over_45": sorted(b for b, v in steps.items() if v > 45)}  # fmt: skip
        print(f"{n}: {rows[n]['max_step_deg']} degrees ({worst}); over 45: {rows[n]['bones_over_45']}")
    write_json(a.out, {"clips": rows, "frames_per_clip": a.frames})
    return 0


if __name__ == "__main__":
    sys.exit(main())
