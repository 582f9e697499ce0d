"""Every BVH and GLB anima writes, opened by the tool it is for: headless Blender (``blender -b``) imports each
file as a user does (``tools/blender_inspect.py`` for a BVH, ``tools/blender_import.py`` for an avatar) and says
what it got. Checked from inside Blender: joint count and names, frame count and rate, a T-pose rest, bones
that move (and move where anima put them), one skinned human of human height, and the face's shape-key values
at chosen frames equal to the artifact's weights."""

import json
import shutil
import subprocess

import numpy as np
import pytest

from anima.core import rig
from anima.core.contract import EXPR_NAMES
from anima.facemodel.character import to_arkit
from anima.io.arkit import ARKIT_NAMES
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
        "--posture",
        "standing",  # the host sits at his desk; standing, the render shows a whole person's silhouette
        "--quiet",
        "--no-render",
    )
    assert r.returncode == 0, r.stderr
    r = cli("gesture", asset(SPEECH), "--db", gesture_ds, "--all-splits", "--out", d / "gesture", "--no-render")
    assert r.returncode == 0, r.stderr
    r = cli("text2face", "a woman smiles, then blinks", "--out", d / "t2f", "--length", "80", "--no-video")
    assert r.returncode == 0, r.stderr
    return d


def _blender_from_yup(P):
    """Blender imports Y-up files into its Z-up world: (x, y, z) -> (x, -z, y)."""
    return np.stack([P[..., 0], -P[..., 2], P[..., 1]], -1)


def blender_import(path, tmp_path, frames=(), render_frame=None):
    """``tools/blender_import.py`` as a user runs it: its report (and a front render at ``render_frame``)."""
    blender = shutil.which("blender")
    assert blender, "Blender is not installed: ./dev setup installs it (Debian package blender)"
    args = ["--report", str(tmp_path / "r.json"), "--frames", ",".join(map(str, frames))]
    if render_frame is not None:
        args += ["--render", str(tmp_path / "front.png"), "--frame", str(render_frame)]
    r = subprocess.run(
        [blender, "-b", "--factory-startup", "--python", str(REPO / "tools" / "blender_import.py"), "--", str(path)]
        + args,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0 and (tmp_path / "r.json").exists(), (r.stdout + r.stderr)[-3000:]
    return json.loads((tmp_path / "r.json").read_text())


@pytest.mark.parametrize("kind,name", [("capture", "capture.npz"), ("gesture", "gesture.npz")])
def test_bvh_in_blender(results, kind, name, tmp_path):
    """The body on the character's rig, in metres: Blender's default import (scale 1) gives a person of human
    size, a T-pose rest, and every joint where anima put it."""
    from anima.export.avatar import character_motion

    seq = read_sequence(results / kind / name)
    got = inspect(results / kind / "body.bvh", tmp_path / "b.json", seq.fps)
    assert got["bones"] == list(rig.NAMES) and got["fps"] == pytest.approx(seq.fps)
    first, last = got["action_frame_range"]
    assert round(last - first) + 1 == seq.n_frames
    head = np.array(got["rest_head"])
    arm = head[rig.IX["LeftForeArm"]] - head[rig.IX["LeftArm"]]  # T-pose: arms out along +x
    spine = head[rig.IX["Neck"]] - head[rig.IX["Spine"]]  # and the spine up (+z in Blender)
    assert arm[0] > 0.95 * np.linalg.norm(arm) and spine[2] > 0.95 * np.linalg.norm(spine)
    top = head[rig.IX["HeadTop_End"], 2] - min(head[rig.IX["LeftToe_End"], 2], head[rig.IX["LeftFoot"], 2])
    assert 1.4 < top < 1.95  # metres: a person, not a 170-unit giant
    H = np.array(got["pose_heads"])
    assert np.ptp(H[:, rig.IX["LeftHand"]], axis=0).max() > 0.02  # the bones move
    np.testing.assert_allclose(H, _blender_from_yup(character_motion(seq)["positions"]), atol=1e-3)


@pytest.mark.parametrize("kind,name", [("capture", "capture.npz"), ("gesture", "gesture.npz"), ("t2f", "motion.npz")])
def test_avatar_is_one_skinned_human_with_its_own_timeline_in_blender(results, kind, name, tmp_path):
    """A capture of a half-body clip, a gesture result and a text2face result each open in Blender as
    one skinned human 1.5-1.95 m tall whose scene plays the whole clip at its rate; its joints are where anima
    put them and its 52 face shape keys (ARKit's) carry the weights; a workbench render from the front shows a standing
    person (a tall silhouette with a head on top and two legs at the bottom)."""
    from anima.export.avatar import character_face, character_motion

    seq = read_sequence(results / kind / name)
    picks = [0, seq.n_frames // 2, seq.n_frames - 1]
    got = blender_import(results / kind / "avatar.glb", tmp_path, picks, render_frame=seq.n_frames // 2)
    assert len(got["meshes"]) == 1 and got["skinned"] == got["meshes"] and len(got["bones"]) == rig.N_RIG
    assert 1.5 <= got["height_m"] <= 1.95, got["height_m"]
    assert got["fps"] == pytest.approx(seq.fps) and got["frame_end"] - got["frame_start"] + 1 == seq.n_frames
    assert got["action_frame_range"] == pytest.approx([got["frame_start"], got["frame_end"]], abs=1e-3)
    P = character_motion(seq)["positions"]
    assert np.linalg.norm(np.diff(P, axis=0), axis=-1).max() < 0.20  # no joint jumps 20 cm in a frame
    for f in picks:
        np.testing.assert_allclose(np.array(got["pose_heads"][str(f)]), _blender_from_yup(P[f]), atol=1e-3)
    assert got["shape_keys"] == 53  # Basis + ARKit's 52
    W = character_face(seq)  # the character's own weights (by geometry, from the rest face)
    A = to_arkit(W)  # as its ARKit morphs carry them
    for f in picks:
        assert sorted(got["shape_key_values"][str(f)]) == sorted(["Basis", *ARKIT_NAMES])
        for k, n in enumerate(ARKIT_NAMES):
            assert got["shape_key_values"][str(f)][n] == pytest.approx(float(A[f, k]), abs=1e-5), (f, n)
    jaw = seq.expression[:, seq.expr_names.index("jawOpen")]  # the mouth goes by name: the fitted jaw itself
    by_name = character_face(seq, lips=False)  # ... before a capture's lips are set from its landmarks
    np.testing.assert_allclose(by_name[seq.tracked, EXPR_NAMES.index("jawOpen")], np.clip(jaw[seq.tracked], 0, 1),
                               atol=1e-6)  # fmt: skip
    if kind == "capture":  # the lips part as the landmarks show (anima.facemodel.transfer.Transfer.follow_lips)
        from anima.export.avatar import face_transfer
        from anima.facemodel.transfer import LIP_SHOWN, lip_opening

        opening = lip_opening(seq.landmarks, seq.width, seq.height)[seq.tracked]
        gap = face_transfer().lip_gaps(W[seq.tracked])
        shown = opening >= LIP_SHOWN[0]
        assert shown.sum() > 10
        r = np.corrcoef(opening[shown], gap[shown])[0, 1]
        assert r > 0.99, r
    import cv2

    img = cv2.imread(str(tmp_path / "front.png"), cv2.IMREAD_UNCHANGED)
    sil = img[..., 3] > 0
    ys, xs = np.nonzero(sil)
    h, w = ys.max() - ys.min(), xs.max() - xs.min()
    assert h > 1.6 * w and 0.1 < sil.mean() < 0.5, (h, w, sil.mean())
    top = sil[ys.min() : ys.min() + h // 12].sum(0)  # the head: a narrow top
    assert (top > 0).sum() < 0.5 * w
    feet = sil[ys.max() - h // 30]  # two feet apart at the bottom
    runs = np.flatnonzero(np.diff(np.concatenate([[0], feet.astype(int), [0]])) == 1)
    assert len(runs) >= 2


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
    assert (
        info["avatar"]["unit"] == "metre"
        and info["avatar"]["frames"] == read_sequence(results / "gesture" / "gesture.npz").n_frames
    )
    assert (results / "gesture" / "speech.wav").stat().st_size > 10_000


def test_a_retargeted_avatar_in_blender(results, tmp_path):
    """The capture retargeted onto a Mixamo-named A-pose character with rolled forearm axes imports
    in Blender as one skinned human playing anima's animation: every bone's head where anima's forward
    kinematics put it, at the first, middle and last frame."""
    from anima.export.retarget import find_humanoid, run
    from anima.export.vrm import write_character_avatar
    from anima.io.gltf_read import read_gltf

    avatar = write_character_avatar(tmp_path / "tall.glb", "tall", "A", 90.0)
    out = tmp_path / "retargeted.glb"
    run(results / "capture", avatar, out)
    seq = read_sequence(results / "capture" / "capture.npz")
    picks = [0, seq.n_frames // 2, seq.n_frames - 1]
    got = blender_import(out, tmp_path, picks)
    assert len(got["meshes"]) == 1 and got["skinned"] == got["meshes"] and len(got["bones"]) == rig.N_RIG
    assert got["fps"] == pytest.approx(seq.fps) and got["frame_end"] - got["frame_start"] + 1 == seq.n_frames
    g = read_gltf(out)
    W = g.posed_worlds(0)
    hum = find_humanoid(g)
    for f in picks:
        heads = dict(zip(got["bones"], got["pose_heads"][str(f)]))
        for n, i in hum.nodes.items():
            np.testing.assert_allclose(heads[g.names[i]], _blender_from_yup(W[f, i, :3, 3]), atol=2e-3, err_msg=n)
