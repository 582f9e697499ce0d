"""Ablation of the §4.4 generator's adversarial weight (seed 004 eq. 4.1-4.3): the generator trained with
weights 0 (direct regression), 0.1 (anima's default) and 1 on the 3 video folds of ``anima eval gesture``
(body videos, then face-only videos, assigned round-robin in sorted order); each full-body window is judged by
the model that never saw its video. Reports L1 to the captured motion (cm), wrist motion (cm; captured
speakers move theirs ~2.9) and wrist jerk (m/s^3). Writes benchmarks/results/gesture_adv_ablation.json.

    python benchmarks/ablation_gesture_adv.py --db DATASET [--weights 0 0.1 1]   # ~5 min per weight
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from anima.dataset.windows import read_windows
from anima.errors import AnimaError
from anima.eval.gesture.metrics import jerk as jerk_of
from anima.eval.gesture.metrics import wrist_motion
from anima.gesture.generator import GeneratorConfig, GeneratorTrainConfig, train_generator
from anima.io.atomic import write_json


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--db", required=True, help="a dataset from `anima dataset build`")
    ap.add_argument("--weights", type=float, nargs="+", default=[0.0, 0.1, 1.0])
    ap.add_argument("--folds", type=int, default=3)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "gesture_adv_ablation.json"))
    a = ap.parse_args()
    w = read_windows(a.db)
    body_videos = sorted({s for s, h in zip(w.source, w.has_body) if h})
    other = sorted(set(w.source) - set(body_videos))
    fold_of = {v: n % a.folds for n, v in enumerate(body_videos)}
    fold_of.update({v: n % a.folds for n, v in enumerate(other)})
    fold = np.array([fold_of[s] for s in w.source])
    res = {}
    for weight in a.weights:
        kind = "adversarial" if weight > 0 else "regression"
        l1, motion, jerk = [], [], []
        for f in range(a.folds):
            tr = fold != f
            gen, _ = train_generator(
                w.speech[tr],
                w.body[tr],
                w.face[tr],
                GeneratorConfig(kind=kind, fps=w.fps),
                GeneratorTrainConfig(adv_weight=weight),
            )
            for n in np.flatnonzero((fold == f) & w.has_body):
                J, _ = gen.generate(w.speech[n])
                l1.append(float(np.abs(J - w.body[n].reshape(J.shape)).mean() * 100))
                motion.append(wrist_motion(J))
                jerk.append(jerk_of(J, w.fps))
        res[str(weight)] = {
            "l1_cm": float(np.mean(l1)),
            "wrist_motion_cm": float(np.mean(motion)),
            "jerk": float(np.mean(jerk)),
            "windows": len(l1),
        }
        print(weight, res[str(weight)], flush=True)
    res["wrist_motion_cm_captured"] = float(
        np.mean([wrist_motion(w.body[n].reshape(-1, 55, 3)) for n in np.flatnonzero(w.has_body)])
    )
    write_json(a.out, res)


if __name__ == "__main__":
    try:
        main()
    except AnimaError as e:  # a missing or empty dataset: its message, not a traceback
        raise SystemExit(f"{Path(__file__).name}: {e}") from None
