import glob

import numpy as np
import pytest

from anima.errors import InputError
from anima.io.assets import asset
from anima.io.bvh import read_bvh


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
    """A real capture exported to BVH and read back: the rig's names, its T-pose rest in metres, and forward
    kinematics of the file within 1 cm of the character's posed joints."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video
    from anima.core import rig
    from anima.export.avatar import character_motion
    from anima.export.formats import export_bvh

    clip = "gesture-video/pats-crops/oliver1_gt.mp4"
    seq = capture_video(str(asset(clip)), CaptureConfig(max_frames=120), progress=False)
    p = export_bvh(seq, tmp_path / "a.bvh")
    b = read_bvh(p)
    assert b.names == list(rig.NAMES) and b.frame_time == pytest.approx(1 / seq.fps)
    m = character_motion(seq)
    np.testing.assert_allclose(b.offsets[1:], rig.rest_offsets(m["rest"])[1:], atol=1e-5)  # T-pose rest, metres
    arm = b.offsets[rig.IX["LeftForeArm"]]
    assert arm[0] > 0.2 and abs(arm[1]) < 1e-3 and abs(arm[2]) < 1e-3  # the left upper arm out along +x
    err = np.linalg.norm(b.positions() - m["positions"], axis=-1)
    assert err.mean() < 0.01 and err.max() < 0.02, (err.mean(), err.max())
    # one skeleton: every frame has the rig's bone lengths
    L = np.linalg.norm(b.positions() - b.positions()[:, np.maximum(b.parents, 0)], axis=-1)[:, 1:]
    assert np.allclose(L, np.linalg.norm(b.offsets[1:], axis=-1), atol=1e-4)
