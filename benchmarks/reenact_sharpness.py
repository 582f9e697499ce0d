"""The re-enactment's mouth detail and n, chosen on a validation clip and reported on the test
clip, as a result file for the docs (numbers generated, not typed): self-re-enactment, method 1,
every (n, detail) of the grid on Obama clip 2, then the seed's setting and the chosen one on Obama clip 1.

    python benchmarks/reenact_sharpness.py [--out benchmarks/results/reenact_sharpness.json]   # ~20 min, 2 cores
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.eval.reenact.run import OBAMA, sharpness_ablation  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "reenact_sharpness.json"))
    a = ap.parse_args()
    t0 = time.perf_counter()
    out = sharpness_ablation([OBAMA[1], OBAMA[0], OBAMA[2]], OBAMA, progress=True)
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    write_json(a.out, out)
    print(f"chosen {out['chosen']} in {out['wall_s'] / 60:.1f} min -> {a.out}")


if __name__ == "__main__":
    main()
