"""Fit the independent judge's thresholds (`anima.eval.text2face.judge.JudgeConfig`) on real video with human labels,
never on generated output, and only on the clips of the training and validation splits (the test
clips choose nothing; their scores with the chosen values are reported apart). Every such
labelled clip of `anima/eval/labels/attributes` is read in two domains:

* **round trip** (the one the judge is used in): the clip is captured (`anima capture --face-only`), its
  expression weights and head rotation are rendered on the face model's neutral head exactly as a generated
  motion is, and the rendering is tracked with MediaPipe Face Mesh;
* **video**: MediaPipe Face Mesh on the clip's own frames (for reference: how far the round trip moves the
  measures).

In each, the landmark measures are read as events at each threshold of a grid; an attribute's threshold is the
one with the best event F1 over the clips labelled for it (a detected event that overlaps a label is a hit, one
that overlaps neither a label nor an "ignore" range a false alarm; a label no event overlaps a miss).
Leave-one-clip-out F1 is reported beside it. Writes benchmarks/results/judge_calibration.json; the judge's
defaults are the round-trip values.

    python benchmarks/judge_calibrate.py

Attributes without labelled examples (shake head, turn) keep the judge's geometric defaults: said in the JSON.
"""

from __future__ import annotations

import dataclasses
import hashlib
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.dataset.splits import split_for  # noqa: E402
from anima.eval.annotations import capture_labelled, load_labels  # noqa: E402
from anima.eval.text2face.judge import JudgeConfig, events, measures, render_motion, track_frames  # noqa: E402
from anima.io.assets import asset  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402
from anima.io.video import read_video  # noqa: E402

GRID = {
    "blink": ("blink_ratio", np.round(np.arange(0.35, 0.86, 0.05), 3)),
    "smile": ("smile_width", np.round(np.arange(0.02, 0.40, 0.02), 3)),
    "mouth open": ("open_gap", np.round(np.arange(0.04, 0.31, 0.02), 3)),
    "raise eyebrows": ("brow_up", np.round(np.arange(0.01, 0.251, 0.01), 4)),
    "frown": ("brow_down", np.round(np.arange(0.01, 0.251, 0.01), 4)),
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


def _judge_code() -> str:
    """A short hash of the code behind a clip's measures (the judge's renderer, tracker and measures, not its
    thresholds): a changed render or measure never reads an older cache."""
    import inspect

    import anima.eval.text2face.judge as judge
    import anima.eval.text2face.judge_render as judge_render

    parts = [inspect.getsource(judge_render)]
    parts += [inspect.getsource(f) for f in (judge.measures, judge.track_frames, judge.render_motion)]
    text = "".join(parts)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def tracked(lab: dict, domain: str) -> tuple[dict, float]:
    """The clip's landmark measures in ``domain`` ("video" or "round trip") and its frame rate (cached)."""
    keep = Path(tempfile.gettempdir()) / "anima-judge-calibration"  # reused by a rerun of the same judge code
    keep.mkdir(exist_ok=True)
    f = keep / f"{lab['name']}-{domain.replace(' ', '_')}-{_judge_code()}.npz"
    if f.is_file():
        with np.load(f) as z:
            return {k: z[k] for k in z.files if k != "fps"}, float(z["fps"])
    if domain == "video":
        frames, info = read_video(asset(lab["clip"]), max_frames=lab.get("frames"))
        m, fps = measures(track_frames(frames)), info.fps
    else:
        seq = capture_labelled(lab)
        motion = np.concatenate([seq.expression, seq.rotation], 1).astype(np.float32)
        m, fps = measures(track_frames(render_motion(motion, seq.fps))), seq.fps
    np.savez(f, fps=fps, **m)
    print(lab["name"], domain, len(m["eye"]), "frames", file=sys.stderr)
    return m, fps


def fit(labs: list[dict], domain: str) -> tuple[dict, dict]:
    cache = {lab["name"]: tracked(lab, domain) for lab in labs}
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
        top = max(f1(*t) for t in table.values())
        tied = [v for v in table if f1(*table[v]) == top]
        best = tied[(len(tied) - 1) // 2]  # ties to their median, never towards the shipped value
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
        print(domain, attr, report[attr], file=sys.stderr)
    return chosen, report


def test_scores(labs: list[dict], domain: str, chosen: dict) -> dict:
    """The test clips' event counts with the values chosen elsewhere (reported, never used to choose)."""
    cfg = dataclasses.replace(JudgeConfig(), **{k: float(v) for k, v in chosen.items()})
    out = {}
    for attr in GRID:
        clips = [lab for lab in labs if attr in lab["labels"]]
        if not clips:
            continue
        t = np.zeros(3, int)
        for lab in clips:
            m, fps = tracked(lab, domain)
            t += score(events(m, fps, cfg), lab, attr, len(m["eye"]), fps)
        f = round(f1(*t), 3) if t[0] + t[1] + t[2] else None  # no event labelled and none read: undefined
        out[attr] = {"clips": len(clips), "hits_false_misses": [int(x) for x in t], "f1": f}
    return out


def main() -> None:
    every = load_labels()
    side = {lab["name"]: split_for(asset(lab["clip"])) for lab in every}
    labs = [lab for lab in every if side[lab["name"]] != "test"]
    test = [lab for lab in every if side[lab["name"]] == "test"]
    out = {
        "calibration_clips": [lab["name"] for lab in labs],
        "test_clips": [lab["name"] for lab in test],
        "what": "the judge's thresholds fitted on human-labelled real clips; the judge uses the round-trip values",
        "not_fitted": {
            "shake head, turn": "no labelled example: geometric defaults of JudgeConfig",
            "smile_lift": "kept at its default (the grid is over smile_width)",
        },
    }
    for domain in ("round trip", "video"):
        chosen, report = fit(labs, domain)
        out[domain] = {"chosen": chosen, "attributes": report, "test": test_scores(test, domain, chosen)}
    write_json(Path(__file__).parent / "results" / "judge_calibration.json", out)


if __name__ == "__main__":
    main()
