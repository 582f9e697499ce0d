"""`anima export fbx`: Blender's own FBX exporter writes the character with the take; Blender's FBX importer
reads one skinned character back whose bones follow anima's own forward kinematics, and a second, independent
reader (ufbx, as Unity and Unreal read FBX) agrees: bones, blend shapes, units, the same joint positions and
skinned vertices, unturned root nodes, a UV set and an embedded base-colour texture, the take's frames."""

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
    assert len(got["shape_keys"]) >= 53  # the 52 ARKit face morphs as blend shapes, and Blender's Basis
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
    assert len(blend.channels) == 52  # ARKit's
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


KTIME = 46_186_158_000  # FBX time units a second


def _identity(node) -> bool:
    t = node.local_transform
    r, x, sc = t.rotation, t.translation, t.scale
    turned = max(abs(r.x), abs(r.y), abs(r.z)) > 1e-5 or abs(r.w) < 1 - 1e-6
    moved = max(abs(x.x), abs(x.y), abs(x.z)) > 1e-6
    scaled = max(abs(sc.x - 1), abs(sc.y - 1), abs(sc.z - 1)) > 1e-5
    return not (turned or moved or scaled)


def test_what_an_engine_imports_unturned_textured_and_the_takes_frames(take):
    """Read back with ufbx (default options), as Unity's and Unreal's importers read it: the scene root's
    children (the armature's node, the mesh's) carry no rotation, translation or scale (the axes converted in the
    data); the mesh has a UV set and one material whose base colour is an embedded texture that carries the
    character's colours (at the middle of each triangle of more than a few pixels, the texture's colour is the
    vertex colours' there); the take and the file's time span are the clip's frames; and skinned, with the blend
    shapes, every vertex is where anima's own skinning puts it at three frames (within 1 mm)."""
    import gc

    import cv2
    import ufbx

    from anima.export.avatar import OnCharacter
    from anima.facemodel.character import arkit_dense, load_character, skin, to_arkit
    from anima.io.sequence import read_sequence

    _, fbx, d = take
    seq = read_sequence(d / "capture.npz")  # as the export read it (the landmarks set the lids, lips, brows)
    F, fps = seq.n_frames, seq.fps
    ch, on = load_character(), OnCharacter(seq)
    m, W = on.motion(), to_arkit(on.face())  # the file's face: its 52 ARKit morphs
    D = arkit_dense().reshape(len(W[0]), -1)
    picks = (0, F // 2, F - 1)
    want = {f: skin(m["vertices"] + (W[f : f + 1].astype(np.float32) @ D).reshape(1, -1, 3), m["rest"],
                    m["global"][f : f + 1], m["positions"][f : f + 1], ch)[0] for f in picks}  # fmt: skip
    gc.disable()  # the bindings' objects point into the scene: each one held, none collected out of order
    try:
        s = ufbx.load_file(str(fbx))
        keep = [s]
        root = s.root_node
        kids = list(root.children)
        keep += [root, kids]
        assert sorted(n.name for n in kids) == ["character", "rig"]
        assert all(_identity(n) for n in kids), [(n.name, n.local_transform.rotation) for n in kids]
        mesh = s.meshes[0]
        keep.append(mesh)
        assert [u.name for u in mesh.uv_sets] == ["UVMap"] and len(mesh.materials) == 1
        mat = mesh.materials[0]
        tex = mat.pbr.base_color.texture
        keep += [mat, tex]
        assert tex is not None and len(tex.content) > 10_000  # embedded
        img = cv2.imdecode(np.frombuffer(bytes(tex.content), np.uint8), cv2.IMREAD_COLOR)[..., ::-1] / 255.0
        assert img.shape == (2048, 2048, 3)
        uv, col = mesh.vertex_uv, mesh.vertex_color
        keep += [uv, col]
        U = np.array([[p.x, p.y] for p in uv.values])[np.array(list(uv.indices))]
        C = np.array([[c.x, c.y, c.z] for c in col.values])[np.array(list(col.indices))]  # sRGB, as the texture
        faces = mesh.faces
        keep.append(faces)
        tri = np.array([[f.index_begin + k for k in range(3)] for f in faces if f.num_indices == 3])
        area = 0.5 * np.abs(np.cross(U[tri[:, 1]] - U[tri[:, 0]], U[tri[:, 2]] - U[tri[:, 0]])) * 2048**2
        big = tri[area > 8]
        assert len(big) > 5000
        mid_uv, mid_col = U[big].mean(1), C[big].mean(1)
        px = np.clip((mid_uv * 2048 - 0.5).round().astype(int), 0, 2047)
        got = img[2047 - px[:, 1], px[:, 0]]
        err = np.abs(got - mid_col).max(-1) * 255
        assert np.median(err) <= 2 and np.percentile(err, 95) <= 8, (np.median(err), np.percentile(err, 95))
        away = np.abs(img - np.median(img.reshape(-1, 3), 0)).max(-1) > 0.2
        assert 1e-4 < away.mean() < 0.2  # the skin, and the lips', brows', eyes' colours on it
        stack = s.anim_stacks[0]
        keep.append(stack)
        assert stack.time_begin == pytest.approx(0) and stack.time_end == pytest.approx((F - 1) / fps, abs=1e-4)
        props = s.settings.props
        keep.append(props)
        span = [props.find_prop(n).value_int / KTIME for n in ("TimeSpanStart", "TimeSpanStop")]
        assert span == pytest.approx([0, (F - 1) / fps], abs=1e-4)
        for f in picks:
            e = ufbx.evaluate_scene(s, s.anim, f / fps, evaluate_skinning=True)
            em = e.meshes[0]
            sp = em.skinned_position
            keep += [e, em, sp]
            got = np.array([[v.x, v.y, v.z] for v in sp.values])[np.array(list(sp.indices))]
            vi = np.array(list(mesh.vertex_indices))
            err = np.linalg.norm(got - want[f][vi], axis=-1)
            assert err.max() < 0.001, (f, err.max())
    finally:
        gc.enable()


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
    assert s.settings.unit_meters == pytest.approx(0.01) and len(blend.channels) == 52
    root = s.root_node
    kids = list(root.children)
    rot = [n.local_transform.rotation for n in kids]
    assert len(kids) == 2 and all(abs(r.w) > 1 - 1e-6 for r in rot)  # unturned in centimetres too
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
