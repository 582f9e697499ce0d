"""The built-in motion library. Its provenance is checked against the real shared data (every source
file there, with the same sha256, licensed for an MIT package, in the training split), it reads back what its
writer wrote, and `anima text2face PROMPT` / `anima gesture SPEECH` work with no dataset."""

import hashlib
import json

import numpy as np

from anima.core.contract import EXPR_NAMES
from anima.io.assets import asset, data_root
from anima.io.sequence import read_sequence
from anima.library import builtin
from anima.library.sources import licence_of
from anima.text2face.compose import detect_motion

SPEECH = "videoretalking-examples/examples/audio/1.wav"


def test_every_source_is_shared_data_licensed_for_the_package_and_a_training_video(shared_split_table):
    b = builtin.load()
    p = b.provenance
    assert p["videos"] == len(p["sources"]) > 20 and p["face_clips"] == len(b.face_clip)
    root = data_root().resolve()
    table = {r["key_path"]: r["split"] for r in shared_split_table.values()}
    for s in p["sources"]:
        path = root / s["path"]
        assert path.is_file(), s["path"]
        lic, ok = licence_of(s["path"])
        assert ok and lic == s["licence"], s
        assert hashlib.sha256(path.read_bytes()).hexdigest() == s["sha256"], s["path"]
        assert table[s["path"]] == "train", s["path"]  # no validation or test video of an evaluation
    # what stays out says why, and nothing of a left-out source is in the library
    assert {"gesture-video/pats-crops/", "emotion-clips/eamm-mead/"} <= {
        r["prefix"] for r in p["licence_table"] if not r["included"]
    }
    assert not any(c.startswith(("gesture-video/", "emotion-clips/", "pose3d/")) for c in b.face_clip)
    assert not any(s.startswith(("gesture-video/", "emotion-clips/")) for s, _ in b.gesture_source)
    assert builtin.LIBRARY.stat().st_size == p["size_bytes"] < 5_000_000


def test_the_library_reads_back_what_its_writer_wrote(tmp_path):
    b = builtin.load()
    out = tmp_path / "lib.npz"
    builtin.write_library(out, b.face_motion, b.face_events, b.face_clip, b.face_fps, b.gesture, b.gesture_source,
                          b.gesture_fps, b.speech_face, b.provenance)  # fmt: skip
    c = builtin.load(out)
    assert c.face_clip == b.face_clip and c.face_events == b.face_events and c.gesture_source == b.gesture_source
    for x, y in zip(c.face_motion, b.face_motion):
        np.testing.assert_array_equal(x, y)
    for k in "FPGS":
        np.testing.assert_array_equal(c.gesture[k], b.gesture[k])
    (tmp_path / "bad.npz").write_bytes(b"not a library")
    try:
        builtin.load(tmp_path / "bad.npz")
    except Exception as e:
        assert "unreadable" in str(e)
    else:
        raise AssertionError("a corrupt library was read")


def test_text2face_and_gesture_work_with_no_dataset(cli, tmp_path):
    out = tmp_path / "t"
    r = cli("text2face", "she smiles, then blinks twice", "--out", out, "--no-video", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    info = json.loads((out / "info.json").read_text())
    assert info["method"] == "timeline" and "built-in" in info["library"] and info["dataset"] is None
    seq = read_sequence(out / "motion.npz")
    found = [a for a, _, _ in detect_motion(np.concatenate([seq.expression, seq.rotation], 1), seq.fps)]
    assert "smile" in found and found.count("blink") >= 2, found
    other = tmp_path / "o"
    assert cli("text2face", "he frowns and shakes his head", "--out", other, "--no-video").returncode == 0
    assert not np.allclose(read_sequence(other / "motion.npz").expression[:90], seq.expression[:90])

    g = tmp_path / "g"
    r = cli("gesture", asset(SPEECH), "--out", g, "--no-render", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    info = json.loads((g / "info.json").read_text())
    assert "built-in" in info["database"]
    seq = read_sequence(g / "gesture.npz")
    assert seq.body_joints is not None and np.isfinite(seq.body_joints).all()
    assert seq.body_joints.std(0).max() > 0.01  # the hands move
    jaw = seq.expression[:, list(EXPR_NAMES).index("jawOpen")]
    assert jaw.std() > 0.02  # the face talks
