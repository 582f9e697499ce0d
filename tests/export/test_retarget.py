"""anima motion on a user's own avatar. A real capture and a gesture result retargeted onto anima's
character written as VRM and as Mixamo/Unreal-named glTF in several shapes (one in an A-pose with rolled
forearms), onto a rig the project never saw (every bone's axes turned at random, an A-pose, facing -z, another
name prefix) and onto the third-party VRM 1.0 sample keep the arm pose frame by frame, never jump, and keep
the feet above the floor; copying local rotations instead fails the same check. Faces reach ARKit-named morphs
or a VRM's expression presets; bad avatars are refused with the reason."""

import json
import struct
import subprocess

import numpy as np
import pytest
from hostile_avatars import unseen_rig

from anima.core import rig
from anima.core.contract import EXPR_NAMES
from anima.core.rotations import matrix_to_quat, quat_to_matrix, rotvec_to_matrix
from anima.io.arkit import ARKIT_NAMES
from anima.io.assets import asset

pytestmark = pytest.mark.slow  # real captures
SAMPLE_VRM = "avatars/VRMC_materials_mtoon_UV_Animation_Test.vrm"
SPEECH = "videoretalking-examples/examples/audio/1.wav"


def _angle(a, b):
    c = (a * b).sum(-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def arm_pose(pos) -> np.ndarray:
    """Per frame ``[F, 4]``: the elbow angles and the shoulder angles (upper arm against the hips-to-neck line;
    the head where the avatar has no neck) of both arms, from joint positions ``pos(name) -> [F, 3]``."""
    out = []
    for s in ("Left", "Right"):
        a, e, w = pos(f"{s}Arm"), pos(f"{s}ForeArm"), pos(f"{s}Hand")
        out += [_angle(e - a, w - e), _angle(e - a, pos("Neck") - pos("Hips"))]
    return np.stack(out, -1)


def _pack(path, doc, binary):
    js = json.dumps(doc).encode()
    js += b" " * ((4 - len(js) % 4) % 4)
    binary = binary + b"\0" * ((4 - len(binary) % 4) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    path.write_bytes(
        struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js), 0x4E4F534A) + js
        + struct.pack("<II", len(binary), 0x004E4942) + binary
    )  # fmt: skip
    return path


@pytest.fixture(scope="module")
def avatars(tmp_path_factory):
    from anima.export.vrm import write_character_avatar

    d = tmp_path_factory.mktemp("avatars")
    return {
        "character VRM (mean, T)": write_character_avatar(d / "mean.vrm"),
        "Mixamo GLB (tall, A, forearms rolled 90)": write_character_avatar(d / "tall.glb", "tall", "A", 90.0),
        "Unreal GLB (child, T)": write_character_avatar(d / "child.glb", "child", preset="unreal"),
        "character VRM (heavy, A, rolled 45)": write_character_avatar(d / "heavy.vrm", "heavy", "A", 45.0),
        "unseen rig (random axes, A, facing -z)": unseen_rig(d / "unseen.glb"),
        "VRM 1.0 sample (third party)": asset(SAMPLE_VRM),
    }


@pytest.fixture(scope="module")
def sources(captures, gesture_db, tmp_path_factory):
    """A real capture and a gesture result (speech the dataset never saw), as sequence files."""
    from anima.export.framing import generated_sequence
    from anima.gesture.run import synthesize
    from anima.io.sequence import write_sequence
    from anima.io.video import FFMPEG

    d = tmp_path_factory.mktemp("sources")
    speech = d / "speech.wav"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-i", str(asset(SPEECH)), "-t", "6", "-vn", str(speech)], check=True)
    J, _ = synthesize(str(speech), gesture_db)
    gesture = generated_sequence(15.0, body=J.astype(np.float32))  # contract: not (the gesture rate)
    return {
        "capture": write_sequence(captures["oliver1"], d / "capture.npz"),
        "gesture": write_sequence(gesture, d / "gesture.npz"),
    }


def _measure(out, seq_path):
    from anima.export.avatar import character_motion
    from anima.export.retarget import FEET, _plan, find_humanoid
    from anima.io.gltf_read import read_gltf
    from anima.io.sequence import read_sequence

    g = read_gltf(out)
    hum = find_humanoid(g)
    W = g.posed_worlds(0)
    src = character_motion(read_sequence(seq_path, landmarks=False))["positions"]
    neck = "Neck" if "Neck" in hum.nodes else "Head"

    def tgt(n):
        return W[:, hum.nodes[neck if n == "Neck" else n], :3, 3]

    def sp(n):
        return src[:, rig.IX[neck if n == "Neck" else n]]

    err = np.abs(arm_pose(tgt) - arm_pose(sp))
    steps = []
    for n, (aim, _) in _plan(set(hum.nodes)).items():
        if aim:
            d = tgt(aim) - tgt(n)
            steps.append(_angle(d[1:], d[:-1]).max())
    rest = g.world()
    feet = [hum.nodes[n] for n in FEET if n in hum.nodes]
    floor = rest[feet, 1, 3].min()
    low = W[:, feet, 1, 3].min()
    return err, max(steps), low - floor, g, hum


def test_retarget_keeps_the_arm_pose_on_every_avatar(avatars, sources, tmp_path):
    from anima.export.retarget import run

    rows = []
    for name, av in avatars.items():
        for kind, seq in sources.items():
            out = tmp_path / f"{len(rows)}{'.vrm' if str(av).endswith('.vrm') else '.glb'}"
            rep = run(seq, av, out)
            err, step, above, g, hum = _measure(out, seq)
            rows.append((name, kind, np.median(err), np.percentile(err, 95), step, above))
            assert len(hum.nodes) >= 51 and rep["body"]["hip_height_ratio"] > 0.5, (name, rep)
            assert json.loads(out.with_suffix(".json").read_text())["kind"] == "anima retarget"
    table = "\n".join(
        f"{n:42s} {k:8s} median {m:5.2f} p95 {p:5.2f} step {s:5.1f} feet {a:+.4f}" for n, k, m, p, s, a in rows
    )
    print(table)
    for *_, med, p95, step, above in rows:
        assert med <= 8.0 and p95 <= 20.0, table
        assert step <= 45.0, table
        assert above >= -1e-4, table


def test_copying_local_rotations_fails_the_same_check(avatars, sources):
    """The check can fail: anima's local rotations copied onto an A-pose rig with other bone axes put the arms
    far from the source's pose (the 'arms upside down' of other tools)."""
    from anima.export.avatar import character_motion
    from anima.export.retarget import find_humanoid
    from anima.io.gltf_read import read_gltf
    from anima.io.sequence import read_sequence

    g = read_gltf(avatars["unseen rig (random axes, A, facing -z)"])
    hum = find_humanoid(g)
    m = character_motion(read_sequence(sources["capture"], landmarks=False))
    q = matrix_to_quat(m["local"])
    frames = range(0, len(q), 10)
    W = np.stack([g.world({i: {"rotation": q[f, rig.IX[n]]} for n, i in hum.nodes.items()}) for f in frames])
    naive = arm_pose(lambda n: W[:, hum.nodes[n], :3, 3])
    src = arm_pose(lambda n: m["positions"][list(frames), rig.IX[n]])
    assert np.median(np.abs(naive - src)) > 20.0


def test_faces_reach_arkit_morphs_or_vrm_expressions(avatars, captures, tmp_path):
    """The capture blinks and talks: on the character's VRM its ARKit-named morphs carry the weights; on a VRM
    the project never saw whose morphs have other names, its blink and viseme expressions move (read back
    through the expression binds from the written animation) and follow the source."""
    from anima.export.avatar import character_face
    from anima.export.retarget import run
    from anima.export.vrm import arkit_weights, vrm_expressions
    from anima.io.gltf_read import read_gltf
    from anima.io.sequence import read_sequence, write_sequence

    seq_path = write_sequence(captures["oliver1"], tmp_path / "c.npz")
    seq = read_sequence(seq_path)
    face = character_face(seq)  # what anima's character shows, so what every export carries
    want = vrm_expressions(arkit_weights(face, list(EXPR_NAMES)))
    rep = run(seq_path, avatars["character VRM (mean, T)"], tmp_path / "a.vrm")
    assert rep["face"]["via"] == "morph targets named like ARKit" and len(rep["face"]["found_a_home"]) == 52
    g = read_gltf(tmp_path / "a.vrm")
    (node, _), (_, w) = next(iter((k, v) for k, v in g.animation(0).items() if k[1] == "weights"))
    k = g.doc["meshes"][g.nodes[node]["mesh"]]["extras"]["targetNames"].index("eyeBlinkLeft")
    np.testing.assert_allclose(w[:, k], face[:, EXPR_NAMES.index("eyeBlink_L")], atol=1e-6)

    # a VRM whose morph targets are not named like ARKit (as VRoid's are not): the expression presets
    src = read_gltf(avatars["character VRM (mean, T)"])
    doc = json.loads(json.dumps(src.doc))
    doc["meshes"][0]["extras"]["targetNames"] = [f"Fcl_{i:02d}" for i in range(len(ARKIT_NAMES))]
    unseen = _pack(tmp_path / "unseen.vrm", doc, src.bin)
    rep = run(seq_path, unseen, tmp_path / "b.vrm")
    assert rep["face"]["via"] == "VRM expression presets"
    assert {"aa", "ih", "ou", "ee", "oh", "blink", "blinkLeft", "blinkRight", "happy"} <= set(
        rep["face"]["found_a_home"]
    )
    assert rep["face"]["no_home"] == ["relaxed"] or "relaxed" in rep["face"]["found_a_home"]
    g = read_gltf(tmp_path / "b.vrm")
    w = next(v for k, v in g.animation(0).items() if k[1] == "weights")[1]
    presets = doc["extensions"]["VRMC_vrm"]["expressions"]["preset"]
    expect = np.zeros_like(w)
    for name, e in presets.items():
        for b in e["morphTargetBinds"]:
            expect[:, b["index"]] += want.get(name, 0.0) * b["weight"]
    np.testing.assert_allclose(w, np.clip(expect, 0, 1), atol=1e-5)  # every preset through its binds
    for morph, ict, name in (("eyeBlinkLeft", "eyeBlink_L", "blink"), ("jawOpen", "jawOpen", "aa")):  # they move
        k, i = ARKIT_NAMES.index(morph), EXPR_NAMES.index(ict)  # with the face
        assert any(b["index"] == k for b in presets[name]["morphTargetBinds"])
        assert np.ptp(w[:, k]) > 0.2 and np.corrcoef(w[:, k], face[:, i])[0, 1] > 0.95, morph


def test_cli_and_refusals(cli, avatars, captures, sources, tmp_path):
    from anima.export.framing import generated_sequence
    from anima.io.gltf_read import read_gltf
    from anima.io.sequence import write_sequence

    res = tmp_path / "res"
    res.mkdir()
    write_sequence(captures["seth3"], res / "capture.npz")
    r = cli(
        "retarget", res, "--avatar", avatars["Mixamo GLB (tall, A, forearms rolled 90)"], "--out", tmp_path / "o.glb"
    )
    assert r.returncode == 0, r.stderr
    assert "mixamo names" in r.stdout and (tmp_path / "o.json").is_file()
    g = read_gltf(tmp_path / "o.glb")
    assert g.doc["animations"][0]["name"] == "anima" and len(g.doc["animations"]) == 2  # its own animation kept
    assert g.doc["scenes"][0]["extras"]["anima_frame_end"] == captures["seth3"].n_frames - 1

    # a face-only result: the face alone goes onto the avatar
    seq = captures["seth3"]
    face = np.concatenate([seq.expression, seq.rotation], 1).astype(np.float32)
    write_sequence(generated_sequence(seq.fps, face=face), tmp_path / "motion.npz")
    r = cli("retarget", tmp_path / "motion.npz", "--avatar", avatars["character VRM (mean, T)"], "--out",
            tmp_path / "f.vrm", "--json")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["body"].startswith("none in this sequence")

    # refusals: one line, the reason, nothing written
    from anima.export.vrm import character_avatar  # noqa: F401  (the avatars above come from it)

    src = read_gltf(avatars["character VRM (mean, T)"])
    nohuman = json.loads(json.dumps(src.doc))
    for i, nd in enumerate(nohuman["nodes"]):
        nd["name"] = f"bone_{i}"
    del nohuman["extensions"], nohuman["extensionsUsed"]
    v0 = json.loads(json.dumps(src.doc))
    v0["extensions"] = {"VRM": {"exporterVersion": "UniVRM-0.99"}}
    noskin = {k: v for k, v in nohuman.items() if k != "skins"}
    noskin["nodes"] = [{k: v for k, v in nd.items() if k != "skin"} for nd in nohuman["nodes"]]
    big = tmp_path / "big.glb"
    with open(big, "wb") as fh:
        fh.truncate(201 * 2**20)
    cases = {
        "no humanoid": (_pack(tmp_path / "nohuman.glb", nohuman, src.bin), 4, "missing hips, spine, head"),
        "no skin": (_pack(tmp_path / "noskin.glb", noskin, src.bin), 4, "no skin"),
        "VRM 0.x": (_pack(tmp_path / "v0.vrm", v0, src.bin), 4, "VRM 0.x"),
        "over 200 MB": (big, 2, "at most 200 MB"),
    }  # fmt: skip
    for name, (av, code, words) in cases.items():
        out = tmp_path / f"x_{code}.glb"
        r = cli("retarget", sources["capture"], "--avatar", av, "--out", out)
        assert r.returncode == code and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, (name, r.stderr)
        assert not out.exists()
    r = cli("retarget", sources["capture"], "--avatar", avatars["Unreal GLB (child, T)"], "--out", tmp_path / "x.vrm")
    assert r.returncode == 2 and "needs a VRM avatar" in r.stderr
    user = tmp_path / "mine.glb"
    user.write_bytes(b"glTF not anima's")
    r = cli("retarget", sources["capture"], "--avatar", avatars["Unreal GLB (child, T)"], "--out", user)
    assert r.returncode == 2 and user.read_bytes() == b"glTF not anima's"


def test_vrma_holds_the_motion_and_the_expressions(sources, tmp_path):
    """``anima export vrma``: the rig's humanoid (VRM names, T-pose rest) whose forward kinematics give the
    character's joints, and the expression presets as the extension's nodes."""
    from anima.export.avatar import character_motion
    from anima.export.formats import export_file
    from anima.io.gltf_read import read_gltf
    from anima.io.sequence import read_sequence

    out = export_file("vrma", sources["capture"], tmp_path / "take.vrma")
    g = read_gltf(out)
    ext = g.doc["extensions"]["VRMC_vrm_animation"]
    assert ext["specVersion"] == "1.0" and len(ext["humanoid"]["humanBones"]) >= 52
    assert set(ext["expressions"]["preset"]) >= {"aa", "ih", "ou", "ee", "oh", "blink", "lookUp", "happy"}
    W = g.posed_worlds(0)
    P = character_motion(read_sequence(sources["capture"], landmarks=False))["positions"]
    hips = ext["humanoid"]["humanBones"]["hips"]["node"]
    hand = ext["humanoid"]["humanBones"]["leftHand"]["node"]
    np.testing.assert_allclose(W[:, hand, :3, 3] - W[:, hips, :3, 3], P[:, rig.IX["LeftHand"]] - P[:, rig.IX["Hips"]],
                               atol=1e-4)  # fmt: skip
    aa = g.animation(0)[(ext["expressions"]["preset"]["aa"]["node"], "translation")][1][:, 0]
    assert np.ptp(aa) > 0.1 and aa.min() >= 0 and aa.max() <= 1


def test_quat_to_matrix_inverts_matrix_to_quat():
    R = rotvec_to_matrix(np.random.default_rng(0).normal(size=(50, 3)))
    np.testing.assert_allclose(quat_to_matrix(matrix_to_quat(R)), R, atol=1e-9)


def test_outputs_pass_the_khronos_validator(avatars, sources, tmp_path):
    import shutil
    from pathlib import Path

    from anima.export.formats import export_file
    from anima.export.retarget import run

    repo = Path(__file__).resolve().parents[2]
    files = [
        run(sources["gesture"], avatars["character VRM (heavy, A, rolled 45)"], tmp_path / "a.vrm")["outputs"][0],
        run(sources["capture"], avatars["unseen rig (random axes, A, facing -z)"], tmp_path / "b.glb")["outputs"][0],
        export_file("vrma", sources["capture"], tmp_path / "c.vrma"),
        avatars["character VRM (mean, T)"],
    ]
    for f in files:
        r = subprocess.run([shutil.which("node"), str(repo / "tools" / "validate_gltf.js"), str(f)],
                           capture_output=True, text=True, timeout=120)  # fmt: skip
        rep = json.loads(r.stdout)
        assert rep["issues"]["numErrors"] == 0, (f, rep["issues"]["messages"][:5])
