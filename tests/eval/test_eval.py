"""Evaluations on real data: they must run and show what the issue asks (fit beats raw MediaPipe on the
AFLW2000-3D samples; smoothing removes jitter without costing accuracy)."""

import numpy as np

from anima.capture.calibrate68 import calibrate_ibug68
from anima.eval.landmarks import evaluate_aflw
from anima.eval.metrics import mean_acceleration, nme_bbox
from anima.eval.stability import stability_of_clip
from anima.facemodel.landmarks68 import ibug68_vertices, upstream_ibug68
from anima.io.assets import asset


def test_nme_protocol():
    gt = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 40.0], [0.0, 40.0]])
    assert np.isclose(nme_bbox(gt + [2.0, 0.0], gt), 2.0 / 20.0)  # sqrt(10 * 40) = 20


def test_acceleration_of_constant_velocity_is_zero():
    x = np.arange(10.0)[:, None, None] * np.ones((1, 3, 2))
    assert mean_acceleration(x) == 0.0


def test_aflw_fit_beats_raw_mediapipe():
    r = evaluate_aflw()
    assert r["images"] == 16 and r["detected"] == 16
    assert r["nme_fit"] < r["nme_mediapipe"]
    assert r["nme_fit"] < 0.05
    assert r["nme_fit_by_group"]["eyes"] < 0.04


def test_landmark_calibration_is_reproducible_and_helps(face_model):
    r = calibrate_ibug68()
    assert r["calibration_nme_points_17_67_after"] < 0.8 * r["calibration_nme_points_17_67_before"]
    shipped = ibug68_vertices(face_model)
    assert (np.asarray(r["vertices"]) == shipped).mean() > 0.9
    assert (shipped[:17] == upstream_ibug68(face_model)[:17]).all()


def test_smoothing_removes_jitter_without_costing_accuracy():
    r = stability_of_clip(str(asset("styletalk-samples/samples/source_video/video/andrew_clip_1.mp4")), 150)
    assert r["tracked"] == 1.0
    assert r["acc_reduction"] >= 0.4
    assert r["error_ratio_smoothed_vs_unsmoothed"] <= 1.10


def test_bootstrap_over_videos_resamples_whole_videos():
    from anima.eval.gesture.metrics import bootstrap_over_groups

    rng = np.random.default_rng(0)
    groups = np.repeat(np.arange(12), 40)
    x = (rng.random(len(groups)) < np.repeat(rng.uniform(0.3, 0.9, 12), 40)).astype(float)
    lo, hi = bootstrap_over_groups(x, groups)
    assert lo < x.mean() < hi and bootstrap_over_groups(x, groups) == [lo, hi]  # seeded
    # frames within a video are not independent: the interval over videos is wider than one over frames
    lo_f, hi_f = bootstrap_over_groups(x, np.arange(len(x)))
    assert hi - lo > 1.5 * (hi_f - lo_f)
    # one video: nothing to resample, the interval is its mean
    assert bootstrap_over_groups(x[:40], groups[:40]) == [x[:40].mean()] * 2
