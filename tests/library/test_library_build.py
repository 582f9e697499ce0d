"""`anima library build`: a user's footage baked into a motion library that `gesture --library` and
`text2face --library` use instead of the built-in one, on a real clip and real speech; its bad inputs are one line
and exit 2."""

import json
import subprocess

import numpy as np

from anima.io.assets import asset
from anima.io.sequence import read_sequence
from anima.io.video import FFMPEG

CLIP = "gesture-video/pats-crops/oliver1_gt.mp4"
SPEECH = "videoretalking-examples/examples/audio/1.wav"


def _one_line(r, *words):
    assert r.returncode == 2, (r.returncode, r.stderr[-500:])
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("anima: error:"), r.stderr
    assert all(w in r.stderr for w in words), r.stderr


def test_a_library_from_five_seconds_of_a_real_clip_drives_gesture_and_text2face(cli, tmp_path):
    lib = tmp_path / "lib"
    r = cli("library", "build", asset(CLIP), "--out", lib, "--max-frames", "125", "--min-len", "3", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    info = json.loads(r.stdout)
    assert info["gesture_windows"] == 1 and info["face_clips"] == 1 and info["videos"] == 1
    assert {p.name for p in lib.iterdir() if not p.name.startswith(".")} == {
        "library.npz",
        "library.json",
        "manifest.json",
    }
    prov = json.loads((lib / "library.json").read_text())
    src = prov["sources"][0]  # where it came from: the file, its hash, how much motion it gave
    assert src["path"].endswith("oliver1_gt.mp4") and len(src["sha256"]) == 64 and src["frames_captured"] == 125
    assert prov["kind"] == "user" and "no licence filter" in prov["licence"] and "library build" in prov["command"]

    g = tmp_path / "g"
    r = cli("gesture", asset(SPEECH), "--library", lib, "--out", g, "--no-render", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    out = json.loads((g / "info.json").read_text())
    assert "library.npz" in out["database"] and "built-in" not in out["database"]
    assert out["database_windows"] > 1  # the window and its variants (mirrored, slower)
    assert out["strokes"]["stresses"] >= 3
    seq = read_sequence(g / "gesture.npz")
    assert seq.fps == 30.0 and np.isfinite(seq.body_joints).all() and seq.body_joints.std(0).max() > 0.01

    t = tmp_path / "t"
    r = cli("text2face", "she smiles, then blinks", "--library", lib, "--out", t, "--no-video", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    assert "library.npz" in json.loads((t / "info.json").read_text())["library"]

    one = tmp_path / "one.npz"  # a single file, replaced by a rerun (anima's own); a user's file of that name is kept
    for _ in range(2):
        r = cli("library", "build", asset(CLIP), "--out", one, "--max-frames", "100", "--min-len", "3", "--quiet")
        assert r.returncode == 0 and one.is_file(), r.stderr[-2000:]
    assert "oliver1_gt.mp4" in json.loads(str(np.load(one)["provenance"]))["sources"][0]["path"]
    # 4 s of video: a face clip, but no 4.3-s gesture window
    _one_line(cli("gesture", asset(SPEECH), "--library", one, "--out", tmp_path / "g1"), "no (audio, gesture) window")
    mine = tmp_path / "mine.npz"
    np.savez(mine, x=np.zeros(3))
    _one_line(cli("library", "build", asset(CLIP), "--out", mine), "not a motion library")


def test_bad_inputs_are_refused_before_any_capture(cli, tmp_path):
    nobody = tmp_path / "nobody.mp4"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-f", "lavfi", "-i", "testsrc=size=256x256:rate=25", "-t", "2",
                    "-pix_fmt", "yuv420p", str(nobody)], check=True)  # fmt: skip
    text = tmp_path / "notes.mp4"
    text.write_text("not a video\n")
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "lib"
    _one_line(cli("library", "build", tmp_path / "missing.mp4", "--out", out), "not found")
    _one_line(cli("library", "build", text, "--out", out), "not a readable video")
    _one_line(cli("library", "build", asset(SPEECH), "--out", out), "not a readable video")
    _one_line(cli("library", "build", empty, "--out", out), "no video")
    _one_line(cli("library", "build", asset(CLIP), nobody, "--out", out), "no person found", "nobody.mp4")
    assert not out.exists()  # nothing was written (nor captured: the check comes first)
    _one_line(cli("library", "build", asset(CLIP), "--out", text), "not a folder")
    _one_line(cli("gesture", asset(SPEECH), "--library", tmp_path / "nope", "--out", tmp_path / "g"), "--library")
    _one_line(cli("gesture", asset(SPEECH), "--library", empty, "--out", tmp_path / "g"), "not a motion library")
    _one_line(cli("text2face", "he nods", "--library", text, "--out", tmp_path / "t"), "--library")
