"""Talk's jaw motion: the talk track tiled from every talk segment as captured (before) against
the livelier half scaled up to ``TALK_JAW_STD`` (now), side by side in one run, on the built-in library and on a
dataset (``--db``). Per library: jawOpen's standard deviation of 3-s talk tracks over ``--seeds`` seeds (mean
and lowest). Writes benchmarks/results/talk_energy.json.

    python benchmarks/ablation_talk_energy.py [--db ds]      # a few seconds
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from anima.core.contract import EXPR_NAMES, TEXT_FPS
from anima.io.atomic import write_json
from anima.text2face.compose import TALK_JAW_STD, _talk_track
from anima.text2face.run import _library

JAW = EXPR_NAMES.index("jawOpen")


def jaw_std(lib, lively: bool, seeds: int, n: int) -> dict:
    v = [float(np.std(_talk_track(lib, n, np.random.default_rng(s), lively)[:, JAW])) for s in range(seeds)]
    return {"mean": round(float(np.mean(v)), 4), "lowest": round(float(np.min(v)), 4)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--db", help="a dataset folder from `anima dataset build` (its clips as the library)")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "talk_energy.json"))
    a = ap.parse_args()
    n = int(3 * TEXT_FPS)
    rows = {}
    for name, db in (("built-in", None), ("dataset", a.db)):
        if name == "dataset" and not db:
            continue
        lib = _library(db, False)
        rows[name] = {
            "talk_segments": len(lib.segments.get("talk") or []),
            "before": jaw_std(lib, False, a.seeds, n),
            "now": jaw_std(lib, True, a.seeds, n),
        }
        print(name, rows[name])
    write_json(
        a.out,
        {
            "what": " ".join(__doc__.split("\n\n")[0].split()),
            "talk_jaw_std": TALK_JAW_STD,
            "seeds": a.seeds,
            "rows": rows,
        },
    )


if __name__ == "__main__":
    main()
