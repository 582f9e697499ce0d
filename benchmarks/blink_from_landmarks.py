"""Does reading blinks from the landmarks' lid opening help the dataset's detectors? The shipped
detectors on the labelled clips of the train and validation splits (never test), each captured as the dataset
captures it, with the fit's eyeBlink raised to the landmarks' lid opening (``anima.capture.pipeline.
with_seen_blinks``, shipped) and without it; event-level F1 per attribute pooled over the clips.

    python benchmarks/blink_from_landmarks.py    # writes benchmarks/results/blink_from_landmarks.json (~2 min)
"""

from __future__ import annotations

import argparse
from pathlib import Path

import anima.capture.pipeline as pipeline
from anima.eval.annotations import detectors_by_smoothing
from anima.io.atomic import write_json


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "blink_from_landmarks.json"))
    a = ap.parse_args()
    shipped = detectors_by_smoothing([1.0])
    keep = pipeline.with_seen_blinks
    pipeline.with_seen_blinks = lambda expr, *args, **kw: expr  # the fit's eyeBlink alone, as before
    try:
        fit_only = detectors_by_smoothing([1.0])
    finally:
        pipeline.with_seen_blinks = keep
    rows = [{"capture": name, **r["per_sigma"]["1.0"]["f1"], "mean_f1": round(r["per_sigma"]["1.0"]["mean_f1"], 4)}
            for name, r in (("landmark blinks (shipped)", shipped), ("fit only", fit_only))]  # fmt: skip
    write_json(a.out, {"clips": shipped["clips"], "sides": shipped["sides"], "rows": rows})
    for r in rows:
        print(r)


if __name__ == "__main__":
    main()
