"""Body + hands skeleton: definition, assembly on a real gesture clip, cleaning."""

import json

import numpy as np
import pytest

from anima.capture.body import assemble, bone_length_cv, clean
from anima.core.skeleton import BODY_JOINTS, JOINT_NAMES, LEFT_HAND, N_JOINTS, PARENTS, RIGHT_HAND
from anima.io.assets import asset
from anima.io.sequence import read_sequence, write_sequence

TANGO = "gesture-video/tango-interviews/speaker7_iuYlGRnC7J8_00-00-0.00_00-00-3.25.mp4"


def test_skeleton_definition():
    assert N_JOINTS == 55 and len(set(JOINT_NAMES)) == 55
    assert PARENTS[0] == -1 and all(PARENTS[j] < j for j in range(1, 55))  # parents come first
    assert JOINT_NAMES[PARENTS[JOINT_NAMES.index("left_hand_wrist")]] == "left_wrist"
    assert JOINT_NAMES[PARENTS[JOINT_NAMES.index("right_hand_index_mcp")]] == "right_hand_wrist"


@pytest.fixture(scope="module")
def tango_track():
    from anima.io.video import read_video
    from anima.track import get

    frames, info = read_video(asset(TANGO))
    with get().holistic() as h:
        hf = [h(f) for f in frames]
    return assemble(hf, info.width, info.height, info.fps)


def test_assembly_on_real_clip(tango_track):
    J = tango_track.joints
    body_ok = np.isfinite(J[:, :13]).all((1, 2))
    assert body_ok.mean() > 0.9
    assert np.allclose(J[body_ok, 0], 0)  # pelvis-relative
    span = np.linalg.norm(
        J[body_ok, BODY_JOINTS.index("left_shoulder")] - J[body_ok, BODY_JOINTS.index("right_shoulder")], axis=-1
    )
    assert 0.25 < np.median(span) < 0.5  # metres
    # the subject's left shoulder is on the image right (+x) when facing the camera
    assert np.median(J[body_ok, BODY_JOINTS.index("left_shoulder"), 0]) > 0
    for sl, wrist in ((LEFT_HAND, "left_wrist"), (RIGHT_HAND, "right_wrist")):
        ok = np.isfinite(J[:, sl]).all((1, 2)) & body_ok
        assert ok.mean() > 0.8
        assert np.allclose(J[ok, sl.start], J[ok, BODY_JOINTS.index(wrist)])  # attached at the wrist
        hand = np.median(np.linalg.norm(J[ok, sl.start + 9] - J[ok, sl.start], axis=-1))
        assert 0.03 < hand < 0.15  # wrist to middle-finger knuckle, metres


def test_cleaning_fills_short_gaps_flags_long_ones_and_lowers_bone_cv(tango_track):
    t = tango_track
    J = t.joints.copy()
    conf = t.conf.copy()
    J[20:25, LEFT_HAND] = np.nan  # a short drop-out ...
    conf[20:25, LEFT_HAND] = 0
    J[40:70, RIGHT_HAND] = np.nan  # ... and a long one
    conf[40:70, RIGHT_HAND] = 0
    from anima.capture.body import BodyTrack

    c = clean(BodyTrack(J, conf, t.fps), max_gap=8)
    assert np.isfinite(c.joints[20:25, LEFT_HAND]).all() and c.interpolated[20:25, LEFT_HAND].all()
    assert not np.isfinite(c.joints[40:70, RIGHT_HAND]).any()
    assert bone_length_cv(c.joints) < bone_length_cv(t.joints)
    fixed = clean(t, fixed_bones=True)
    assert bone_length_cv(fixed.joints) < 1e-6
    r = clean(t, resample_fps=15)
    assert r.fps == 15 and abs(len(r.joints) - (len(J) - 1) / t.fps * 15) <= 1


def test_capture_artifact_v2_and_v1_compat(tmp_path, d0_capture):
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    seq = capture_video(str(asset(TANGO)), CaptureConfig(max_frames=40), progress=False)
    assert seq.body_joints.shape == (40, 55, 3) and seq.speech.shape == (40, 28)
    assert seq.meta["audio"]["present"] and seq.speech_valid.all()
    p = write_sequence(seq, tmp_path / "c.npz")
    back = read_sequence(p)
    assert np.allclose(back.body_joints, seq.body_joints, equal_nan=True, atol=1e-6)
    s = back.summary()
    assert s["body_tracked_fraction"] > 0.9 and "left_hand_after_interpolation" in s
    # a version-1 file (face only, written by the first release) still loads
    v1 = write_sequence(d0_capture, tmp_path / "v1.npz")
    with np.load(v1) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("meta")))
    meta["version"] = 1
    np.savez(tmp_path / "old.npz", meta=np.asarray(json.dumps(meta)), **arrays)
    old = read_sequence(tmp_path / "old.npz")
    assert old.body_joints is None and old.speech is None and old.n_frames == d0_capture.n_frames


def test_video_without_audio_keeps_motion_and_says_why(d0_path):
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    seq = capture_video(str(d0_path), CaptureConfig(max_frames=20), progress=False)
    assert seq.speech is None and seq.meta["audio"]["present"] is False
    assert "no audio track" in seq.meta["audio"]["reason"]
    assert seq.body_joints is not None  # a head-and-shoulders clip: body partly in view
    sep = capture_video(
        str(d0_path),
        CaptureConfig(max_frames=20, face_only=True),
        audio=str(asset("videoretalking-examples/examples/audio/1.wav")),
        progress=False,
    )
    assert sep.speech.shape == (20, 28) and sep.body_joints is None


def test_hands_whose_wrist_is_unsure_are_kept(tango_track):
    """A seen hand survives a body wrist dropped by the confidence filter for longer than the gap filling:
    it keeps its own wrist (where the detector put it) instead of vanishing."""
    import dataclasses

    from anima.core.skeleton import BODY_JOINTS

    track = dataclasses.replace(tango_track, conf=tango_track.conf.copy())
    lw = BODY_JOINTS.index("left_wrist")
    seen = np.isfinite(track.joints[:, LEFT_HAND]).all((1, 2))
    assert seen.sum() > 30
    span = np.flatnonzero(seen)[5:25]  # 20 frames: longer than max_gap
    track.conf[span, lw] = 0.1  # the body wrist is unsure there
    out = clean(track, min_conf=0.5, max_gap=8)
    assert not np.isfinite(out.joints[span, lw]).all()  # the unsure body wrist is dropped ...
    assert np.isfinite(out.joints[span][:, LEFT_HAND]).all()  # ... the hand is not
    hand = out.joints[span][:, LEFT_HAND]
    size = np.linalg.norm(hand[:, 12] - hand[:, 0], axis=-1)  # wrist to middle fingertip
    assert (0.05 < size).all() and (size < 0.3).all()


def test_summary_counts_joints_after_the_confidence_filter(tmp_path, tango_track):
    """Tracked fractions are read after the confidence filter, per joint group: a clip whose hips are never
    confidently seen reads hips 0, whatever the raw detector returned."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    seq = capture_video(str(asset(TANGO)), CaptureConfig(max_frames=30), progress=False)
    seq.body_conf[:, 1:3] = 0.2  # hips below the filter's 0.5
    s = seq.summary()
    assert s["joint_groups_tracked"]["hips"] == 0.0 and s["body_tracked_fraction"] > 0.9
    assert s["bvh"].startswith("written")
