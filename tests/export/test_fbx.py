"""`anima export fbx` (issue 49): Blender's own FBX exporter writes the character with the take; Blender's FBX
importer reads one skinned character back whose bones follow anima's own forward kinematics, and a second,
independent reader (ufbx) agrees: bones, blend shapes, units, the same joint positions."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from anima.core import rig
from anima.export.avatar import character_motion
from anima.export.fbx import fbx_version
from anima.export.framing import generated_sequence
from anima.io.sequence import write_sequence

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests" / "export"))


def _blender_from_yup(P):
    return np.stack([P[..., 0], -P[..., 2], P[..., 1]], -1)


@pytest.fixture(scope="module")
def take(captures, tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("fbx")
    seq = captures["seth3"]
    path = write_sequence(seq, d / "capture.npz")
    r = cli("export", "fbx", path, "--out", d / "take.fbx")
    assert r.returncode == 0, r.stderr
    return seq, d / "take.fbx", d


def test_blender_reads_one_skinned_character_that_follows_animas_bones(take, tmp_path):
    from test_blender import inspect

    seq, fbx, _ = take
    assert fbx_version(fbx) == 7400 and fbx.read_bytes()[:20] == b"Kaydara FBX Binary  "
    F = seq.n_frames
    picks = [0, F // 2, F - 1]
    got = inspect(fbx, tmp_path / "fbx.json", seq.fps, picks)
    arms = [o for o in got["objects"] if o[1] == "ARMATURE"]
    assert len(arms) == 1 and len(got["bones"]) >= 60
    skinned = [m for m in got["meshes"] if m["armature_modifier"]]
    assert len(skinned) == 1 and skinned[0]["skinned_vertices"] >= 8000
    assert len(got["shape_keys"]) >= 53  # the 53 face morphs as blend shapes (Blender adds its Basis)
    lo, hi = got["action_frame_range"]
    assert round(hi - lo) == F - 1  # the action spans the clip's frames (Blender's importer starts it at 1)
    m = character_motion(seq)
    _, P = rig.forward(m["local"], m["rest"], m["root"])
    names = rig.preset_names("anima")
    heads = got["pose_heads"]  # from the action's first frame
    for f in picks:
        H = {n: np.array(h) for n, h in zip(got["bones"], heads[f])}
        err = [np.linalg.norm(H[n] - _blender_from_yup(P[f, j])) for j, n in enumerate(names) if n in H]
        assert len(err) >= 60 and max(err) < 0.005, (f, max(err))


def test_a_second_reader_agrees(take):
    import ufbx

    seq, fbx, _ = take
    m = character_motion(seq)
    _, P = rig.forward(m["local"], m["rest"], m["root"])
    s = ufbx.load_file(str(fbx))
    keep = [s]  # the bindings free a scene when its object goes: hold every one until the end
    assert s.settings.unit_meters == pytest.approx(1.0)  # --units m: the metre, every value in metres
    mesh = s.meshes[0]
    skin, blend = mesh.skin_deformers[0], mesh.blend_deformers[0]
    keep += [mesh, skin, blend]
    assert len(skin.clusters) >= 60 and mesh.num_vertices >= 8000
    assert len(blend.channels) == 53
    names = rig.preset_names("anima")
    for f in (0, seq.n_frames // 2, seq.n_frames - 1):
        e = ufbx.evaluate_scene(s, s.anim, f / seq.fps)
        keep.append(e)
        err = []
        for j, n in enumerate(names):
            node = e.find_node(n)
            if node is not None:
                world = node.node_to_world
                c = world.c3
                err.append(np.linalg.norm(np.array([c.x, c.y, c.z]) - P[f, j]))
        assert len(err) >= 60 and max(err) < 0.005, (f, max(err))


def test_centimetres_a_face_only_result_and_no_blender(take, cli, tmp_path):
    import ufbx

    seq, _, d = take
    face = np.concatenate([seq.expression, seq.rotation], 1).astype(np.float32)
    path = write_sequence(generated_sequence(seq.fps, face=face[:20]), tmp_path / "motion.npz")
    r = cli("export", "fbx", path, "--out", tmp_path / "face.fbx", "--units", "cm")
    assert r.returncode == 0, r.stderr
    assert "no body" in r.stderr and "idle" in r.stderr  # said
    s = ufbx.load_file(str(tmp_path / "face.fbx"))  # the bindings' objects point into the scene: each one held
    mesh = s.meshes[0]
    blend = mesh.blend_deformers[0]
    assert s.settings.unit_meters == pytest.approx(0.01) and len(blend.channels) == 53
    node = s.find_node("Head")
    world = node.node_to_world
    head = world.c3
    assert 140 < head.y < 200  # centimetres: a head 1.4-2 m above the floor
    r = cli("export", "arkit", path, "--out", tmp_path / "a.csv", "--units", "cm")
    assert r.returncode == 2 and "FBX export only" in r.stderr
    # no writer on the machine: exit 3 with the install line, nothing written
    env = {**os.environ, "PATH": str(Path(sys.executable).parent)}
    assert shutil.which("blender", path=env["PATH"]) is None
    r = subprocess.run([sys.executable, "-m", "anima", "export", "fbx", str(path), "--out", str(tmp_path / "x.fbx")],
                       capture_output=True, text=True, env=env)  # fmt: skip
    assert r.returncode == 3 and "apt-get install blender" in r.stderr and not (tmp_path / "x.fbx").exists()
