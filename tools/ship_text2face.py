"""Ship the text2face checkpoint at the step count the validation windows choose.

    python tools/ship_text2face.py DATASET [--work W]

Runs what ``anima eval text2face`` runs for its "ours" row (:func:`anima.eval.text2face.choose_steps`: the
small preset trained once to the grid's largest step count with a snapshot at each, every snapshot scored on
the validation windows, the lowest MAE kept), with one torch thread as a row of ``anima eval all --jobs 2``
trains, and ships that snapshot to ``anima/text2face/checkpoints/text2face.pt`` with its manifest (the choice
recorded as ``steps_chosen``). The test windows choose nothing: the manifest reports them.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dataset", help="a dataset from `anima dataset build ../shared/data`")
    ap.add_argument("--work", default="ship_work", help="where the snapshots are trained (reused when there)")
    a = ap.parse_args()
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[var] = "1"  # as a row of `anima eval all --jobs 2` on 2 cores, before torch loads
    from anima.eval.text2face.run import (
        SELECTED,
        STEP_GRID,
        FaceGeometry,
        TrainConfig,
        choose_steps,
        encode_cached,
        eval_items,
        prepare,
        quick_metrics,
        split_clips,
    )
    from anima.io.outdir import claim_folder
    from anima.text2face.generate import SHIPPED
    from anima.text2face.ship import ship

    work = claim_folder(Path(a.work), "text2face_work", "--work", inputs=[a.dataset])
    prepared = prepare(a.dataset, TrainConfig(preset="small", steps=max(STEP_GRID)))
    _, held = split_clips(prepared[0])
    items = eval_items(held)
    item_E = encode_cached(prepared[5], [t for it in items for t in it.texts]).reshape(
        len(items), len(items[0].texts), -1
    )
    command = f"python tools/ship_text2face.py {a.dataset}"  # (the work folder is a cache: not part of it)
    path, chosen = choose_steps(
        a.dataset, work, "ours", SELECTED["ours"], STEP_GRID, items, item_E, FaceGeometry(), 5, prepared, True, command
    )
    print(f"chosen: {chosen['value']} steps (validation MAE {chosen['validation_mae_mm']})", file=sys.stderr)
    shipped = ship(path, SHIPPED, lambda p: quick_metrics(a.dataset, p), chosen=chosen)
    print("\n".join(str(p) for p in shipped))
    return 0


if __name__ == "__main__":
    sys.exit(main())
