"""`anima export fbx`: Blender's own FBX exporter writes the character with the take; Blender's FBX importer
reads one skinned character back whose bones follow anima's own forward kinematics, and a second, independent
reader (ufbx, as Unity and Unreal read FBX) agrees: bones, blend shapes, units, the same joint positions and
skinned vertices, unturned root nodes, a UV set and an embedded base-colour texture, the take's frames."""

import json
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


def test_a_second_reader_agrees(take, tmp_path):
    seq, fbx, _ = take
    m = character_motion(seq)
    _, P = rig.forward(m["local"], m["rest"], m["root"])
    names = rig.preset_names("anima")
    picks = (0, seq.n_frames // 2, seq.n_frames - 1)
    got = read_with_ufbx(fbx, tmp_path / "ufbx.npz", [f / seq.fps for f in picks], names)
    assert got["unit_meters"] == pytest.approx(1.0)  # --units m: the metre, every value in metres
    assert got["skin_clusters"] >= 60 and got["num_vertices"] >= 8000
    assert got["blend_channels"] == 52  # ARKit's
    for i, f in enumerate(picks):
        there = ~np.isnan(got["world"][i, :, 0])
        err = np.linalg.norm(got["world"][i][there] - P[f][there], axis=-1)
        assert there.sum() >= 60 and err.max() < 0.005, (f, err.max())


KTIME = 46_186_158_000  # FBX time units a second


def read_with_ufbx(fbx: Path, out: Path, times=(), names=()) -> dict:
    """What ufbx reads in ``fbx`` (tests/export/ufbx_probe.py, in a process of its own: its bindings can crash
    on release, and a crash there must fail one test, not end the session)."""
    r = subprocess.run([sys.executable, "-X", "faulthandler", str(REPO / "tests" / "export" / "ufbx_probe.py"),
                        str(fbx), str(out), json.dumps(list(times)), json.dumps(list(names))],
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    assert r.returncode == 0, f"ufbx_probe exit {r.returncode}: {r.stderr[-4000:]}"
    with np.load(out) as z:
        return {k: z[k] for k in z.files}


def _identity(rotation, translation, scale) -> bool:
    r, x, sc = rotation, translation, scale
    turned = max(abs(r[0]), abs(r[1]), abs(r[2])) > 1e-5 or abs(r[3]) < 1 - 1e-6
    moved = max(abs(x[0]), abs(x[1]), abs(x[2])) > 1e-6
    scaled = max(abs(sc[0] - 1), abs(sc[1] - 1), abs(sc[2] - 1)) > 1e-5
    return not (turned or moved or scaled)


def test_what_an_engine_imports_unturned_textured_and_the_takes_frames(take, tmp_path):
    """Read back with ufbx (default options), as Unity's and Unreal's importers read it: the scene root's
    children (the armature's node, the mesh's) carry no rotation, translation or scale (the axes converted in the
    data); the mesh has a UV set and one material whose base colour is an embedded texture that carries the
    character's colours (at the middle of each triangle of more than a few pixels, the texture's colour is the
    vertex colours' there); the take and the file's time span are the clip's frames; and skinned, with the blend
    shapes, every vertex is where anima's own skinning puts it at three frames (within 1 mm)."""
    import cv2

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
    got = read_with_ufbx(fbx, tmp_path / "ufbx.npz", [f / fps for f in picks])
    assert sorted(got["kid_names"]) == ["character", "rig"]
    kids = zip(got["kid_rotation"], got["kid_translation"], got["kid_scale"])
    assert all(_identity(*k) for k in kids), (got["kid_names"], got["kid_rotation"])
    assert list(got["uv_sets"]) == ["UVMap"] and got["materials"] == 1
    assert len(got["texture"]) > 10_000  # embedded
    img = cv2.imdecode(got["texture"], cv2.IMREAD_COLOR)[..., ::-1] / 255.0
    assert img.shape == (2048, 2048, 3)
    U, C, tri = got["uv"], got["color"], got["triangles"]  # colours in sRGB, as the texture
    area = 0.5 * np.abs(np.cross(U[tri[:, 1]] - U[tri[:, 0]], U[tri[:, 2]] - U[tri[:, 0]])) * 2048**2
    big = tri[area > 8]
    assert len(big) > 5000
    mid_uv, mid_col = U[big].mean(1), C[big].mean(1)
    px = np.clip((mid_uv * 2048 - 0.5).round().astype(int), 0, 2047)
    col = img[2047 - px[:, 1], px[:, 0]]
    err = np.abs(col - mid_col).max(-1) * 255
    assert np.median(err) <= 2 and np.percentile(err, 95) <= 8, (np.median(err), np.percentile(err, 95))
    away = np.abs(img - np.median(img.reshape(-1, 3), 0)).max(-1) > 0.2
    assert 1e-4 < away.mean() < 0.2  # the skin, and the lips', brows', eyes' colours on it
    assert got["stack_span"] == pytest.approx([0, (F - 1) / fps])
    assert got["time_span_ktime"] / KTIME == pytest.approx([0, (F - 1) / fps], abs=1e-4)
    vi = got["vertex_indices"]
    for i, f in enumerate(picks):
        err = np.linalg.norm(got["skinned"][i] - want[f][vi], axis=-1)
        assert err.max() < 0.001, (f, err.max())


def test_centimetres_a_face_only_result_and_no_blender(take, cli, tmp_path):
    seq, _, d = take
    face = np.concatenate([seq.expression, seq.rotation], 1).astype(np.float32)
    path = write_sequence(generated_sequence(seq.fps, face=face[:20]), tmp_path / "motion.npz")
    r = cli("export", "fbx", path, "--out", tmp_path / "face.fbx", "--units", "cm")
    assert r.returncode == 0, r.stderr
    assert "no body" in r.stderr and "idle" in r.stderr  # said
    got = read_with_ufbx(tmp_path / "face.fbx", tmp_path / "ufbx.npz", [0.0], ["Head"])
    assert got["unit_meters"] == pytest.approx(0.01) and got["blend_channels"] == 52
    rot = got["kid_rotation"]
    assert len(rot) == 2 and (np.abs(rot[:, 3]) > 1 - 1e-6).all()  # unturned in centimetres too
    head = got["world"][0, 0]
    assert 140 < head[1] < 200  # centimetres: a head 1.4-2 m above the floor
    r = cli("export", "arkit", path, "--out", tmp_path / "a.csv", "--units", "cm")
    assert r.returncode == 2 and "FBX export only" in r.stderr
    # no writer on the machine: exit 3 with the install line, nothing written
    env = {**os.environ, "PATH": str(Path(sys.executable).parent)}
    assert shutil.which("blender", path=env["PATH"]) is None
    r = subprocess.run([sys.executable, "-m", "anima", "export", "fbx", str(path), "--out", str(tmp_path / "x.fbx")],
                       capture_output=True, text=True, env=env)  # fmt: skip
    assert r.returncode == 3 and "apt-get install blender" in r.stderr and not (tmp_path / "x.fbx").exists()
