import glob

import numpy as np
import pytest

from anima.core.skeleton import JOINT_NAMES, PARENTS, fix_bone_lengths
from anima.errors import InputError
from anima.io.assets import asset
from anima.io.bvh import bvh_to_anima_order, read_bvh, write_bvh


def test_reader_on_third_party_files():
    files = sorted(glob.glob(str(asset("bvh-samples")) + "/**/*.bvh", recursive=True))
    assert len(files) == 3
    for f in files:
        b = read_bvh(f)
        header = open(f).read().split("MOTION")[1].split()
        assert len(b.motion) == int(header[1]) and b.frame_time == pytest.approx(float(header[4]))
        P = b.positions()
        assert P.shape == (len(b.motion), len(b.names), 3) and np.isfinite(P).all()
        # forward kinematics keeps every bone at its offset length in every frame
        for j in range(1, len(b.names)):
            p = b.parents[j]
            has_pos = any(c.endswith("position") for c in b.channels[j])
            if p >= 0 and not has_pos:
                d = np.linalg.norm(P[:, j] - P[:, p], axis=-1)
                assert np.allclose(d, np.linalg.norm(b.offsets[j]), atol=1e-6)


def test_reader_rejects_garbage(tmp_path):
    (tmp_path / "x.bvh").write_text("HIERARCHY\nROOT a\n{\nOFFSET 0 0\n")
    with pytest.raises(InputError):
        read_bvh(tmp_path / "x.bvh")


def test_capture_to_bvh_round_trip_under_1cm(tmp_path):
    from anima.capture.pipeline import CaptureConfig, capture_video

    clip = "gesture-video/pats-crops/oliver1_gt.mp4"
    seq = capture_video(str(asset(clip)), CaptureConfig(max_frames=120), progress=False)
    p = write_bvh(tmp_path / "a.bvh", seq.body_joints, JOINT_NAMES, PARENTS, seq.fps)
    b = read_bvh(p)
    assert sorted(b.names) == sorted(JOINT_NAMES) and b.frame_time == pytest.approx(1 / seq.fps)
    back = bvh_to_anima_order(b, JOINT_NAMES) / 100.0
    ref = fix_bone_lengths(seq.body_joints)  # the BVH carries fixed (median) bone lengths
    ok = np.isfinite(ref).all(-1)
    err = np.linalg.norm(back - ref, axis=-1)[ok]
    assert err.mean() < 0.01, err.mean()
