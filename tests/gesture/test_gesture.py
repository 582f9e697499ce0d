"""Motion-matching gestures (seed 004 Algorithm 1) on a dataset built from real gesture clips: the fast
search equals the literal algorithm, controls hold, the command writes its files, bad inputs are clear."""
import json
import subprocess
import sys

import numpy as np
import pytest

from anima.io.assets import asset
from anima.io.video import FFMPEG

CLIPS = ["gesture-video/pats-crops/oliver1_gt.mp4", "gesture-video/pats-crops/oliver3_gt.mp4",
         "gesture-video/pats-crops/seth3_gt.mp4"]
SPEECH = "gesture-video/pats-crops/oliver2_gt.mp4"


def test_feature_layout():
    from anima.gesture.features import audio_features, pose_features
    S = np.arange(20 * 28, dtype=np.float32).reshape(20, 28)
    f = audio_features(S)
    assert f.shape == (20, 112)
    np.testing.assert_array_equal(f[0, 14:28], S[2, :14])  # t + 2
    np.testing.assert_array_equal(f[15, -14:], S[19, :14])  # past the end: the last frame
    J = np.random.default_rng(0).random((10, 55, 3)).astype(np.float32)
    assert pose_features(J).shape == (10, 96)


@pytest.fixture(scope="module")
def ds(tmp_path_factory):
    out = tmp_path_factory.mktemp("gds") / "ds"
    r = subprocess.run([sys.executable, "-m", "anima", "dataset", "build", *[str(asset(c)) for c in CLIPS],
                        "--out", str(out), "--min-len", "2", "--quiet", "--json"], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    return out


@pytest.fixture(scope="module")
def db(ds):
    from anima.gesture.database import from_dataset
    return from_dataset(ds, None)


def test_fast_search_equals_algorithm_1(db):
    from anima.audio.features import features_for_file
    from anima.gesture.control import parse_control, step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search, search_literal
    assert db.M >= 6
    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)[:80]
    p0 = db.P.reshape(-1, 96).mean(0)
    for k in (0, 2):
        a, pa = search_literal(db, F_in, k, p0)
        b, pb = search(db, F_in, k, p0)
        assert pa == pb and np.array_equal(a, b)
    masks, _ = step_masks(db, [parse_control("right_wrist_speed<=p40@0-3s")], 10, 8 / 15)
    a, pa = search_literal(db, F_in, 0, p0, masks)
    b, pb = search(db, F_in, 0, p0, masks)
    assert pa == pb and np.array_equal(a, b)


def test_control_holds_on_first_and_last_frame_of_each_window(db):
    from anima.audio.features import features_for_file
    from anima.gesture.control import control_features, parse_control, step_masks
    from anima.gesture.features import audio_features
    from anima.gesture.knn import search
    c = parse_control("left_wrist_height>=p70")
    F_in = audio_features(features_for_file(asset(SPEECH), 15.0).features)[:64]
    masks, rep = step_masks(db, [c], 8, 8 / 15)
    _, picks = search(db, F_in, 0, db.P.reshape(-1, 96).mean(0), masks)
    h = control_features(db.G)["left_wrist_height"]
    thr = rep[0]["threshold"]
    for m, r in picks:
        assert h[m, r] >= thr and h[m, r + 7] >= thr


def _run(*args):
    return subprocess.run([sys.executable, "-m", "anima", "gesture", *args], capture_output=True, text=True)


def test_gesture_command_outputs_and_bad_inputs(ds, tmp_path):
    from anima.io.video import probe_video
    wav44 = tmp_path / "speech44k.wav"  # a sample rate other than 16 kHz is resampled
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "4", "-vn", "-ar", "44100",
                    str(wav44)], check=True)
    out = tmp_path / "g"
    r = _run(str(wav44), "--db", str(ds), "--all-splits", "--out", str(out), "--json",
             "--control", "hand_symmetry>=5.0@0-2s")  # impossible: relaxed, with a note
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    assert info["frames"] == 61 and info["controls"][0]["relaxed_to"] is not None
    assert "relaxed" in r.stderr
    J = np.load(out / "gesture.npz")["joints"]
    assert J.shape == (61, 55, 3) and np.isfinite(J).all()
    assert (out / "gesture.bvh").read_text().startswith("HIERARCHY")
    assert probe_video(out / "skeleton.mp4").has_audio
    r = _run(str(wav44), "--db", str(ds), "--out", str(tmp_path / "x"), "--control", "elbow_twist>=p50")
    assert r.returncode == 2 and "unknown control" in r.stderr and "Traceback" not in r.stderr
    short = tmp_path / "short.wav"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(wav44), "-t", "0.3", str(short)], check=True)
    r = _run(str(short), "--db", str(ds), "--out", str(tmp_path / "y"))
    assert r.returncode == 2 and "at least" in r.stderr


def test_eval_gesture_leave_one_video_out(ds):
    from anima.eval.gesture import evaluate
    r = evaluate(str(ds))
    assert r["videos"] == 3 and r["minutes_of_audio_motion"] > 0.2
    assert set(r["minutes_per_speaker"]) == {"oliver", "seth"}
    ca = r["control_adherence"]
    assert ca["left_wrist_height>=p85"]["mean"] > ca["none"]["mean"] > ca["left_wrist_height<=p15"]["mean"]
    assert r["knn"]["l1_cm"] > 0 and r["knn"]["diversity_cm"] > 0
