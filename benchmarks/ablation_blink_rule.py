"""The blink rule: the absolute eyeBlink level (before) against eyeBlink above its own running
median (now), on the clips labelled by watching frames. The window and level grid is scored on every labelled
clip but the held-out one (the development clips: where the shipped 1.0 s / 0.2 was chosen), and the shipped
rule and the old one are then scored on the held-out clip alone. Event-level precision and recall, the
protocol of ``anima eval annotations``. Writes benchmarks/results/blink_rule_ablation.json.

    python benchmarks/ablation_blink_rule.py      # about 40 s
"""

from __future__ import annotations

import argparse
from pathlib import Path

from anima.dataset.config import DetectorConfig
from anima.eval.annotations import capture_labelled, load_labels, score
from anima.io.atomic import write_json

BEFORE = DetectorConfig(blink_on=0.5, blink_baseline_s=None)


def _blink(pairs, cfg: DetectorConfig) -> dict:
    r = score(pairs, cfg)["blink"]
    return {k: r[k] for k in ("clips", "labelled_events", "detections", "precision", "recall")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--held-out", default="uncrop_obama")
    ap.add_argument("--windows", type=float, nargs="+", default=[0.8, 1.0, 1.5])
    ap.add_argument("--levels", type=float, nargs="+", default=[0.15, 0.2, 0.25, 0.3, 0.35])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "blink_rule_ablation.json"))
    a = ap.parse_args()
    labs = [lab for lab in load_labels() if "blink" in lab["labels"]]
    pairs = {lab["name"]: (capture_labelled(lab), lab) for lab in labs}
    dev = [p for n, p in pairs.items() if n != a.held_out]
    held = [pairs[a.held_out]]
    grid = [
        {"window_s": w, "level": v, **_blink(dev, DetectorConfig(blink_baseline_s=w, blink_on=v))}
        for w in a.windows
        for v in a.levels
    ]
    shipped = DetectorConfig()
    res = {
        "development_clips": [n for n in pairs if n != a.held_out],
        "held_out_clip": a.held_out,
        "development": {"before": _blink(dev, BEFORE), "grid": grid},
        "held_out": {"before": _blink(held, BEFORE), "shipped": _blink(held, shipped)},
        "shipped": {"window_s": shipped.blink_baseline_s, "level": shipped.blink_on},
        "note": "in-sample scores of fixed rules (no per-fold threshold choice); anima eval annotations reports "
        "the leave-one-clip-out figures",
    }
    write_json(a.out, res)
    print(f"development ({len(dev)} clips): before {res['development']['before']}")
    for g in grid:
        print(f"  window {g['window_s']} s, level {g['level']}: P {g['precision']:.2f} R {g['recall']:.2f}")
    print(f"held out ({a.held_out}): before {res['held_out']['before']}, shipped {res['held_out']['shipped']}")


if __name__ == "__main__":
    main()
