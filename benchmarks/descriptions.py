"""How many descriptions a dataset build gives each clip: for every (text, motion) clip of a dataset,
the descriptions `anima dataset build` makes from its events (`anima.dataset.describe.fitting_descriptions`,
the build's own call), counted: distinct ones, tokens (the encoder's window is 256), repeated phrases, and
which templates. Writes benchmarks/results/descriptions.json.

    python benchmarks/descriptions.py DATASET [--n 10]

The clip's events and length come from the dataset (the detectors' events as stored); the descriptions are
made again with the current code, so a build made before the current describe.py is measured as a new build
would describe it.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.dataset.describe import _repeats_phrases, fitting_descriptions, n_tokens, segment_timeline  # noqa: E402
from anima.dataset.windows import read_clips  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402


def template(t: str) -> str:
    if t.startswith("At ") or "; at " in t or "throughout;" in t:
        return "timed"
    if t.startswith(("Over the clip", "In this clip", "Throughout")):
        return "summary"
    if t.startswith(("To begin with", "First,", "At first", "In the beginning")) or "for a " in t or "briefly" in t:
        return "long grammar"
    return "ordered"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "descriptions.json"))
    a = ap.parse_args()
    rows = []
    for c in read_clips(a.dataset):
        seed = int(hashlib.sha1(c.clip_id.encode()).hexdigest()[:8], 16)
        segs = segment_timeline(c.events, duration=len(c.motion) / c.fps)
        texts, dropped = fitting_descriptions(segs, a.n, seed, c.gender)
        toks = [n_tokens(t) for t in texts]
        rows.append(
            {
                "clip": c.clip_id,
                "events": len(c.events),
                "distinct": len(set(texts)),
                "max_tokens": max(toks) if toks else 0,
                "repeated_phrases": sum(_repeats_phrases(t) for t in texts),
                "dropped": dropped,
                "templates": sorted({template(t) for t in texts}),
            }
        )
    d = np.array([r["distinct"] for r in rows])
    out = {
        "dataset": a.dataset,
        "clips": len(rows),
        "clips_with_at_least_n": int((d >= a.n).sum()),
        "n": a.n,
        "distinct_min": int(d.min()),
        "max_tokens": max(r["max_tokens"] for r in rows),
        "with_repeated_phrases": sum(r["repeated_phrases"] > 0 for r in rows),
        "busiest_clip_events": max(r["events"] for r in rows),
        "rows": rows,
    }
    write_json(a.out, out)
    print({k: v for k, v in out.items() if k != "rows"})


if __name__ == "__main__":
    main()
