"""Fitting: exact recovery on synthetic model landmarks (maths), and meaning on a real clip."""

import json
from pathlib import Path

import numpy as np

from anima.capture.config import FitConfig
from anima.capture.fit import LandmarkBasis, fit_frames, fit_identity
from anima.core.rotations import euler_to_matrix
from anima.facemodel.correspondence import load_correspondence

LABELS = json.loads((Path(__file__).resolve().parents[1] / "labels" / "d0_labels.json").read_text())


def _synthetic(face_model, F=6, seed=0):
    rng = np.random.default_rng(seed)
    basis = LandmarkBasis.build(face_model, load_correspondence())
    ident = rng.normal(0, 0.8, 100)
    expr = np.zeros((F, 53))
    for f in range(F):
        on = rng.choice(53, 6, replace=False)
        expr[f, on] = rng.uniform(0.2, 0.9, 6)
    R = euler_to_matrix(rng.uniform(-0.4, 0.4, F), rng.uniform(-0.2, 0.2, F), rng.uniform(-0.2, 0.2, F))
    s = rng.uniform(8, 20, F)
    t = np.c_[rng.uniform(150, 350, F), -rng.uniform(150, 350, F), np.zeros(F)]
    V = basis.points(ident, expr)
    P = s[:, None, None] * V @ R.transpose(0, 2, 1) + t[:, None]
    return basis, ident, expr, R, s, t, P


def test_fit_recovers_pose_and_expression_from_exact_landmarks(face_model):
    basis, ident, expr, R, s, t, P = _synthetic(face_model)
    cfg = FitConfig(lam_expr=1e-4, lam_expr_l1=0.0, qp_sweeps=2000, n_alternations=12)
    fit = fit_frames(P, basis, ident, cfg)
    assert np.allclose(fit.R, R, atol=2e-2)
    assert np.allclose(fit.scale, s, rtol=1e-2)
    assert np.abs(fit.expr - expr).mean() < 0.025
    assert fit.err_px.max() < 0.5
    assert ((fit.expr >= 0) & (fit.expr <= 1)).all()


def test_identity_fit_is_robust_to_outlier_landmarks(face_model):
    basis, ident, expr, R, s, t, P = _synthetic(face_model, F=8, seed=1)
    P = P.copy()
    rng = np.random.default_rng(5)
    bad = rng.choice(P.shape[1], 20, replace=False)
    P[:, bad, :2] += rng.normal(0, 40, (P.shape[0], 20, 2))  # grossly wrong landmarks

    def shape_err(huber):
        est = fit_identity(P, basis, FitConfig(lam_id=0.05, huber_cm=huber))
        return np.abs(basis.shape(est) - basis.shape(ident)).mean()

    mean_err = np.abs(basis.mean - basis.shape(ident)).mean()
    robust, plain = shape_err(0.3), shape_err(1e9)
    assert robust < 0.5 * mean_err
    assert robust < 0.9 * plain


def test_d0_blinks_and_smile_where_labelled(d0_capture):
    """Real clip, labels from watching the frames (tests/labels/d0_labels.json)."""
    seq = d0_capture
    assert seq.tracked.all()
    n = seq.expr_names
    blink = LABELS["blinks"][0]["closed_frames"]
    for side in ("L", "R"):
        e = seq.expression[:, n.index(f"eyeBlink_{side}")]
        peak = int(np.argmax(e))
        assert blink[0] - 2 <= peak <= blink[-1] + 2, (side, peak)
        outside = np.r_[0 : blink[0] - 3, blink[-1] + 4 : len(e)]
        assert e[peak] > e[outside].max() + 0.1
    a, b = LABELS["smile"]["frames"]
    smile = seq.expression[:, [n.index("mouthSmile_L"), n.index("mouthSmile_R")]].mean(1)
    neutral = np.r_[tuple(slice(x, y + 1) for x, y in LABELS["neutral"])]
    assert smile[a : b + 1].min() > 0.3
    assert smile[neutral].max() < 0.15
