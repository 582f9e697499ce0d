"""Why the face fit loses held expressions: is it the solver, or what Face Mesh sees? On the face round trip's
development identities (``benchmarks/roundtrip_face.py``: the ICT head rendered with known weights, tracked
by Face Mesh), each combination's hold is explained by the model four ways and the landmarks' 2D residual
compared:

* the fit as shipped (its identity and weights);
* the fit's identity with the **true** weights;
* the **true** identity with the true weights (the render's own parameters);
* the true identity with weights solved again (the solver given the right identity).

If the truth explains Face Mesh's landmarks worse than a refit that leaves the expression out, the loss is in
what the tracker's landmarks show through the model's correspondence, not in the solver's priors: a
regularisation or an identity prior cannot bring it back.

    python benchmarks/study_face_fit_ceiling.py                  # development identity 0, near view (~2 min)
    python benchmarks/study_face_fit_ceiling.py --identity 1 --view far --out /tmp/ceiling.json

Writes ``benchmarks/results/face_fit_ceiling.json``. Development identities only (the test identities 3-5 are
never looked at here).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import roundtrip_face as rf

from anima.capture.config import CaptureConfig
from anima.capture.fit import LandmarkBasis, fit_frames
from anima.capture.pipeline import fit_landmark_sequence, track_landmarks
from anima.core.camera import mediapipe_to_camera, umeyama
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.atomic import write_json
from anima.io.video import probe_video

SHOWN = ("browDown", "eyeSquint", "noseSneer", "mouthUpperUp", "mouthSmile", "mouthFunnel", "mouthPucker")


def residual_px(basis, identity, E, P) -> float:
    """Mean 2D distance (px) of the landmarks ``P [F, K, 3]`` from the model at ``identity``, ``E [F, 53]``
    under the best similarity per frame."""
    V = basis.points(np.asarray(identity, np.float64), np.asarray(E, np.float64))
    s, R, t = umeyama(V, P, np.ones(P.shape[:2]))
    X = s[:, None, None] * (V @ R.transpose(0, 2, 1)) + t[:, None]
    return float(np.linalg.norm((X - P)[..., :2], axis=-1).mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--identity", type=int, default=0, choices=rf.DEV)
    ap.add_argument("--view", default="near", choices=[v for v in rf.VIEWS if not rf.VIEWS[v].get("still")])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "face_fit_ceiling.json"))
    a = ap.parse_args()
    model = load_face_model()
    names = list(model.expr_names)
    coefs = np.clip(np.random.default_rng(rf.SEED).standard_normal((rf.N_IDENTITIES, model.id_deltas.shape[0])), -2, 2)
    W, segs = rf.timeline(names, tuple(rf.COMBOS), rf.SPEECH_S, np.random.default_rng([rf.SEED, a.identity]))
    ypr = rf.head_path(len(W), np.random.default_rng([rf.SEED, a.identity, list(rf.VIEWS).index(a.view)]))
    with tempfile.TemporaryDirectory(prefix="anima-ceiling-") as tmp:
        video = Path(tmp) / "clip.mp4"
        face = rf.Face(model, coefs[a.identity], rf.SKIN_TONES[a.identity % len(rf.SKIN_TONES)])
        rf.film(face, W, ypr, rf.VIEWS[a.view], video, set())
        info = probe_video(str(video))
        lm = track_landmarks(info, None, False)
    cfg = CaptureConfig(face_only=True)
    seq = fit_landmark_sequence(lm, info.width, info.height, info.fps, cfg, meta={"tracker": {}})
    basis = LandmarkBasis.build(model, load_correspondence(), cfg.fit.use_iris)
    P = mediapipe_to_camera(lm[:, basis.index], info.width, info.height)
    truth_id = coefs[a.identity]
    rows = {}
    for s in segs:
        f = np.asarray(s["hold"])
        refit = fit_frames(P[f], basis, truth_id.astype(np.float64), cfg.fit).expr

        def means(E):
            return {b: round(float(np.mean([E[:, names.index(n)].mean() for n in names if n.split("_")[0] == b])), 3)
                    for b in SHOWN}  # fmt: skip

        rows[s["name"]] = {
            "frames": len(f),
            "residual_px": {
                "fit": round(residual_px(basis, seq.identity, seq.expression[f], P[f]), 2),
                "fit_identity_true_weights": round(residual_px(basis, seq.identity, W[f], P[f]), 2),
                "true_identity_true_weights": round(residual_px(basis, truth_id, W[f], P[f]), 2),
                "true_identity_refit": round(residual_px(basis, truth_id, refit, P[f]), 2),
            },
            "truth": means(W[f]), "fit": means(seq.expression[f]), "refit_true_identity": means(refit),
        }  # fmt: skip
        print(s["name"], json.dumps(rows[s["name"]]["residual_px"]), flush=True)
    write_json(a.out, {"protocol": "benchmarks/study_face_fit_ceiling.py docstring", "identity": a.identity,
                       "view": a.view, "split": "development", "combinations": rows})  # fmt: skip


if __name__ == "__main__":
    main()
