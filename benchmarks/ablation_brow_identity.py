"""Is the missed brow the fit's identity/expression split? On CREMA-D actor 1001's six
clips, the capture's brow and mouth weights (clip means) with the per-clip identity at several identity
regularisations (``lam_id``; the default is 2), and with the neutral clip's identity imposed on every clip
(the same face for all six, so no constant expression can hide in a clip's identity). Also each clip's
inner-brow height in MediaPipe's own landmarks (before any fit). Writes
benchmarks/results/brow_identity_ablation.json.

    python benchmarks/ablation_brow_identity.py      # about 30 s
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np

from anima.capture.config import CaptureConfig, FitConfig
from anima.capture.fit import LandmarkBasis, choose_keyframes, fit_frames, fit_identity
from anima.capture.pipeline import capture_video
from anima.core.camera import mediapipe_to_camera
from anima.eval.annotations import CREMA_D_CLIPS, EMOTION_WEIGHTS, inner_brow_height
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.assets import asset
from anima.io.atomic import write_json

WEIGHTS = ("browInnerUp", "browDown", "noseSneer", "eyeWide", "mouthSmile", "mouthFrown")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lam-id", type=float, nargs="+", default=[0.25, 0.5, 1.0, 2.0, 4.0])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "brow_identity_ablation.json"))
    a = ap.parse_args()
    model = load_face_model()
    names = list(model.expr_names)
    base = FitConfig()
    basis = LandmarkBasis.build(model, load_correspondence(), base.use_iris)
    codes = [*EMOTION_WEIGHTS, "NEU"]
    seqs = {
        c: capture_video(str(asset(CREMA_D_CLIPS.format(c))), CaptureConfig(face_only=True), progress=False)
        for c in codes
    }
    P = {
        c: mediapipe_to_camera(s.landmarks[s.tracked][:, basis.index].astype(np.float64), s.width, s.height)
        for c, s in seqs.items()
    }

    def weights(expr: np.ndarray) -> dict:
        return {
            w: round(float(expr[:, [i for i, n in enumerate(names) if n == w or n.startswith(w + "_")]].mean()), 3)
            for w in WEIGHTS
        }

    def checks(W: dict) -> list[str]:
        return [
            f"{EMOTION_WEIGHTS[c][0]}:{w}"
            for c in EMOTION_WEIGHTS
            for w in EMOTION_WEIGHTS[c][1]
            if W[c][w] <= W["NEU"][w]
        ]

    rows = []
    for lam in a.lam_id:
        cfg = dataclasses.replace(base, lam_id=lam)
        W = {
            c: weights(
                fit_frames(p, basis, fit_identity(p[choose_keyframes(p, basis, cfg.n_keyframes)], basis, cfg), cfg).expr
            )
            for c, p in P.items()
        }
        rows.append({"identity": f"per clip, lam_id {lam}", "weights": W, "failed_checks": checks(W)})
    pn = P["NEU"]
    ident = fit_identity(pn[choose_keyframes(pn, basis, base.n_keyframes)], basis, base)
    W = {c: weights(fit_frames(p, basis, ident, base).expr) for c, p in P.items()}
    rows.append({"identity": "the neutral clip's, on every clip", "weights": W, "failed_checks": checks(W)})
    res = {
        "clips": "CREMA-D actor 1001, sentence DFA",
        "rows": rows,
        "landmark_inner_brow_height_iod": {
            EMOTION_WEIGHTS.get(c, ("neutral",))[0]: round(inner_brow_height(s), 4) for c, s in seqs.items()
        },
    }
    write_json(a.out, res)
    print(json.dumps({r["identity"]: r["failed_checks"] for r in rows}, indent=1))
    print(json.dumps(res["landmark_inner_brow_height_iod"]))


if __name__ == "__main__":
    main()
