"""Fit the independent judge's thresholds (`anima.eval.judge.JudgeConfig`) on real video, never on generated
output (issue 38, item 5): every human-labelled clip of `anima/eval/labels/attributes` is tracked with MediaPipe
Face Mesh (the judge's tracker), its landmark measures read as events at each threshold of a grid, and each
attribute's threshold is the one with the best event F1 over the clips labelled for it (a detected event that
overlaps a label is a hit, one that overlaps neither a label nor an "ignore" range a false alarm; a label no
event overlaps a miss). Leave-one-clip-out F1 is reported beside it. Writes
benchmarks/results/judge_calibration.json.

    python benchmarks/judge_calibrate.py

Attributes without labelled examples (shake head, turn) keep the judge's geometric defaults: said in the JSON.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.eval.annotations import load_labels  # noqa: E402
from anima.eval.judge import JudgeConfig, events, measures, track_frames  # noqa: E402
from anima.io.assets import asset  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402
from anima.io.video import read_video  # noqa: E402

GRID = {
    "blink": ("blink_ratio", np.round(np.arange(0.35, 0.86, 0.05), 3)),
    "smile": ("smile_width", np.round(np.arange(0.02, 0.40, 0.02), 3)),
    "mouth open": ("open_gap", np.round(np.arange(0.04, 0.31, 0.02), 3)),
    "raise eyebrows": ("brow_up", np.round(np.arange(0.01, 0.101, 0.005), 4)),
    "frown": ("brow_down", np.round(np.arange(0.005, 0.121, 0.005), 4)),
    "nod": ("nod_swing", np.round(np.arange(0.02, 0.16, 0.01), 3)),
}


def score(evs, lab, attr, n, fps) -> tuple[int, int, int]:
    labels = lab["labels"].get(attr, [])
    ignore = lab.get("ignore", {}).get(attr, [])
    det = [(int(s * fps), int(e * fps)) for a, s, e in evs if a == attr]

    def hits(x, rs):
        return any(x[0] <= b and x[1] >= a for a, b in rs)

    tp = sum(hits(r, det) for r in labels)
    fp = sum(not hits(d, labels) and not hits(d, ignore) for d in det)
    return tp, fp, len(labels) - tp


def f1(tp, fp, fn) -> float:
    return 2 * tp / max(2 * tp + fp + fn, 1)


def main() -> None:
    labs = load_labels()
    cache = {}
    keep = Path(tempfile.gettempdir()) / "anima-judge-calibration"  # the tracked measures, reused by a rerun
    keep.mkdir(exist_ok=True)
    for lab in labs:
        f = keep / f"{lab['name']}.npz"
        if f.is_file():
            with np.load(f) as z:
                cache[lab["name"]] = ({k: z[k] for k in z.files if k != "fps"}, float(z["fps"]))
            continue
        frames, info = read_video(asset(lab["clip"]), max_frames=lab.get("frames"))
        cache[lab["name"]] = (measures(track_frames(frames)), info.fps)
        np.savez(f, fps=info.fps, **cache[lab["name"]][0])
        print(lab["name"], len(frames), "frames", file=sys.stderr)
    base = JudgeConfig()
    chosen, report = {}, {}
    for attr, (field, grid) in GRID.items():
        clips = [lab for lab in labs if attr in lab["labels"]]
        if not any(lab["labels"][attr] for lab in clips):
            continue

        def total(v, which):
            cfg = dataclasses.replace(base, **{field: float(v)})
            t = np.zeros(3, int)
            for lab in which:
                m, fps = cache[lab["name"]]
                t += score(events(m, fps, cfg), lab, attr, len(m["eye"]), fps)
            return t

        table = {float(v): total(v, clips) for v in grid}
        best = max(table, key=lambda v: (f1(*table[v]), -abs(v - getattr(base, field))))
        loco = np.zeros(3, int)
        for k, held in enumerate(clips):
            rest = clips[:k] + clips[k + 1 :]
            v = max(grid, key=lambda v: f1(*total(v, rest)))
            loco += total(v, [held])
        chosen[field] = best
        report[attr] = {
            "threshold": field,
            "value": best,
            "clips": len(clips),
            "labelled_events": int(sum(len(lab["labels"][attr]) for lab in clips)),
            "f1": round(f1(*table[best]), 3),
            "hits_false_misses": [int(x) for x in table[best]],
            "leave_one_clip_out_f1": round(f1(*loco), 3),
        }
        print(attr, report[attr], file=sys.stderr)
    write_json(
        Path(__file__).parent / "results" / "judge_calibration.json",
        {
            "what": "the judge's thresholds fitted on human-labelled real clips (MediaPipe Face Mesh measures)",
            "chosen": chosen,
            "attributes": report,
            "not_fitted": {
                "shake head, turn": "no labelled example: geometric defaults of JudgeConfig",
                "smile_lift": "kept at its default (the grid is over smile_width)",
            },
        },
    )


if __name__ == "__main__":
    main()
