"""``anima facemodel landmarks68``: choose the 68 iBUG landmark vertices on annotated faces (never the
AFLW2000-3D test images): fit the model to MediaPipe on each calibration face
(:mod:`anima.capture.landmark_sets`) and pick, per point, the ICT vertex whose projection best matches the
annotations (:func:`anima.facemodel.landmarks68.calibrate`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from anima.capture.config import FitConfig
from anima.capture.fit import LandmarkBasis, fit_frames, fit_identity
from anima.capture.landmark_sets import calibration_samples
from anima.core.camera import camera_to_image, mediapipe_to_camera
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.facemodel.landmarks68 import FILENAME, calibrate
from anima.io.assets import package_data
from anima.io.atomic import write_text
from anima.io.outdir import check_out_file
from anima.track import get


def calibrate_ibug68(radius_cm: float = 1.2) -> dict:
    """Fit the model to MediaPipe on the calibration faces (``landmark_sets``, disjoint from AFLW2000-3D)
    and choose the 68 landmark vertices there (``anima.facemodel.landmarks68.calibrate``)."""
    model, corr, cfg = load_face_model(), load_correspondence(), FitConfig()
    basis = LandmarkBasis.build(model, corr, cfg.use_iris)
    uvs, gts, names = [], [], []
    with get().face_mesh(static=True) as tr:
        for s in calibration_samples():
            lm = tr(np.ascontiguousarray(s.rgb))
            if lm is None:
                continue
            H, W = s.rgb.shape[:2]
            P = mediapipe_to_camera(lm, W, H)[None, basis.index]
            identity = fit_identity(P, basis, cfg)
            fit = fit_frames(P, basis, identity, cfg)
            V = model.vertices(identity, fit.expr[0])[:9409].astype(np.float64)
            uvs.append(camera_to_image(fit.scale[0] * V @ fit.R[0].T + fit.t[0]))
            gts.append(s.pts)
            names.append(s.name)
    vertices, before, after = calibrate(model, uvs, gts, radius_cm)
    return {
        "vertices": vertices.tolist(),
        "radius_cm": radius_cm,
        "samples": names,
        "calibration_nme_points_17_67_before": float(np.nanmean(before)),
        "calibration_nme_points_17_67_after": float(np.nanmean(after)),
        "note": "jawline 0-16: ICT's documented Multi-PIE jawline substitutes (not calibrated)",
    }


def write_ibug68(radius_cm: float = 1.2, out: str | Path | None = None) -> dict:
    """Calibrate and write the vertex file (default: the packaged one); returns its summary."""
    dest = check_out_file(
        Path(out) if out else package_data(FILENAME), suffixes=(".json",),
        ours=lambda q: "vertices" in json.loads(q.read_text()), what="an iBUG-68 vertex file",
    )  # fmt: skip
    r = calibrate_ibug68(radius_cm)
    write_text(dest, json.dumps(r, indent=1))
    return {k: v for k, v in r.items() if k not in ("vertices", "samples")} | {
        "out": str(dest),
        "n_samples": len(r["samples"]),
    }
