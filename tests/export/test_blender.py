"""Every BVH and GLB anima writes, opened by the tool it is for: headless Blender (``blender -b``) imports each
file as a user does (``tools/blender_inspect.py``) and says what it got. Checked from inside Blender: joint
count and names, frame count and rate, a T-pose rest, bones that move (and move where anima put them), and
the face's shape-key values at chosen frames equal to the artifact's weights."""

import json
import shutil
import subprocess

import numpy as np
import pytest

from anima.core import rig
from anima.core.bvh_math import forward_kinematics
from anima.io.assets import asset
from anima.io.sequence import read_sequence

pytestmark = pytest.mark.slow
REPO = __import__("pathlib").Path(__file__).resolve().parents[2]
SPEECH = "videoretalking-examples/examples/audio/1.wav"


def inspect(path, out_json, fps, frames=()):
    blender = shutil.which("blender")
    assert blender, "Blender is not installed: ./dev setup installs it (Debian package blender)"
    r = subprocess.run(
        [
            blender,
            "-b",
            "--factory-startup",
            "--python",
            str(REPO / "tools" / "blender_inspect.py"),
            "--",
            str(path),
            str(out_json),
            str(fps),
            *map(str, frames),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0 and out_json.exists(), (r.stdout + r.stderr)[-3000:]
    return json.loads(out_json.read_text())


@pytest.fixture(scope="module")
def results(tmp_path_factory, cli, gesture_ds):
    d = tmp_path_factory.mktemp("blender")
    r = cli(
        "capture",
        asset("gesture-video/pats-crops/oliver1_gt.mp4"),
        "--out",
        d / "capture",
        "--max-frames",
        "45",
        "--quiet",
        "--no-render",
    )
    assert r.returncode == 0, r.stderr
    r = cli("gesture", asset(SPEECH), "--db", gesture_ds, "--all-splits", "--out", d / "gesture", "--no-render")
    assert r.returncode == 0, r.stderr
    r = cli("text2face", "a woman smiles, then blinks", "--out", d / "t2f", "--length", "60", "--no-video")
    assert r.returncode == 0, r.stderr
    return d


def _blender_from_yup(P):
    """Blender imports Y-up files into its Z-up world: (x, y, z) -> (x, -z, y)."""
    return np.stack([P[..., 0], -P[..., 2], P[..., 1]], -1)


@pytest.mark.parametrize("kind,name", [("capture", "capture.npz"), ("gesture", "gesture.npz")])
def test_bvh_in_blender(results, kind, name, tmp_path):
    seq = read_sequence(results / kind / name)
    got = inspect(results / kind / "body.bvh", tmp_path / "b.json", seq.fps)
    assert got["bones"] == rig.NAMES and got["fps"] == pytest.approx(seq.fps)
    first, last = got["action_frame_range"]
    assert round(last - first) + 1 == seq.n_frames
    head = np.array(got["rest_head"])
    arm = head[rig.NAMES.index("LeftForeArm")] - head[rig.NAMES.index("LeftArm")]  # T-pose: arms out along +x
    spine = head[rig.NAMES.index("Neck")] - head[rig.NAMES.index("Spine")]  # and the spine up (+z in Blender)
    assert arm[0] > 0.95 * np.linalg.norm(arm) and spine[2] > 0.95 * np.linalg.norm(spine)
    H = np.array(got["pose_heads"]) / 100.0  # Blender units are the file's centimetres
    wrist = H[:, rig.NAMES.index("LeftHand")]
    assert np.ptp(wrist, axis=0).max() > 0.02  # the bones move
    lengths, _ = rig.measure_lengths(seq.body_joints)
    root, local, P = rig.rig_rotations(seq.body_joints, lengths)
    np.testing.assert_allclose(H, _blender_from_yup(P), atol=0.01)  # where anima put them


@pytest.mark.parametrize("kind,name", [("capture", "capture.npz"), ("gesture", "gesture.npz")])
def test_avatar_in_blender(results, kind, name, tmp_path):
    from anima.export.avatar import rig_motion

    seq = read_sequence(results / kind / name)
    picks = [0, seq.n_frames // 2, seq.n_frames - 1]
    got = inspect(results / kind / "avatar.glb", tmp_path / "a.json", seq.fps, picks)
    assert got["bones"] == rig.NAMES and got["fps"] == pytest.approx(seq.fps)
    first, last = got["action_frame_range"]
    assert round(last - first) + 1 == seq.n_frames
    head = np.array(got["rest_head"])
    arm = head[rig.NAMES.index("LeftForeArm")] - head[rig.NAMES.index("LeftArm")]
    assert arm[0] > 0.95 * np.linalg.norm(arm)
    m = rig_motion(seq)
    P = forward_kinematics(m["local"], rig.PARENTS_RIG, rig.rest_offsets(m["lengths"]), m["root"])
    H = np.array(got["pose_heads"])
    assert np.ptp(H[:, rig.NAMES.index("RightHand")], axis=0).max() > 0.02
    np.testing.assert_allclose(H, _blender_from_yup(P), atol=1e-3)
    assert len(got["shape_keys"]) == 54  # Basis + the 53 expressions
    for f in picks:
        values = got["shape_key_values"][str(f)]
        for i, n in enumerate(seq.expr_names):
            assert values[n] == pytest.approx(float(seq.expression[f, i]), abs=1e-5), (f, n)


def test_head_alone_in_blender(results, tmp_path):
    seq = read_sequence(results / "t2f" / "motion.npz")
    picks = [5, 30]
    got = inspect(results / "t2f" / "avatar.glb", tmp_path / "h.json", seq.fps, picks)
    assert "bones" not in got and len(got["shape_keys"]) == 54  # no body: the head alone
    for f in picks:
        for i, n in enumerate(seq.expr_names):
            assert got["shape_key_values"][str(f)][n] == pytest.approx(float(seq.expression[f, i]), abs=1e-5)


def test_avatar_files_validate_and_carry_the_speech(results):
    node = shutil.which("node")
    for kind in ("capture", "gesture", "t2f"):
        r = subprocess.run(
            [node, str(REPO / "tools" / "validate_gltf.js"), str(results / kind / "avatar.glb")],
            capture_output=True,
            text=True,
            timeout=300,
        )
        report = json.loads(r.stdout)
        assert report["issues"]["numErrors"] == 0, report["issues"]["messages"][:5]
    info = json.loads((results / "gesture" / "info.json").read_text())
    assert info["avatar"]["speech"] == "speech.wav" and info["avatar"]["speech_offset_s"] == 0.0
    assert (results / "gesture" / "speech.wav").stat().st_size > 10_000
