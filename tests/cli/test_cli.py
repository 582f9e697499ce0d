"""End-to-end tests of the ``anima`` command on real data, and its behaviour on bad input."""

import json
import subprocess
import sys

import numpy as np
import pytest

from anima.io.sequence import FLAG_NO_FACE, read_sequence


def test_help_for_every_command(cli):
    for cmd in (
        [],
        ["capture"],
        ["info"],
        ["export"],
        ["eval", "landmarks"],
        ["eval", "stability"],
        ["facemodel", "import"],
        ["facemodel", "correspondence"],
        ["facemodel", "landmarks68"],
        ["audio", "features"],
    ):
        r = cli(*cmd, "--help")
        assert r.returncode == 0 and "usage: anima" in r.stdout, cmd


def test_capture_end_to_end_on_real_clip(d0_path, tmp_path, cli):
    out = tmp_path / "out"
    r = cli("capture", d0_path, "--out", out, "--max-frames", "40", "--json", "--quiet")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["frames"] == 40 and summary["tracked_fraction"] == 1.0
    assert {"start", "capture", "write", "render", "total"} <= set(summary["time_s"])
    for name in ("capture.npz", "arkit.csv", "face.glb", "overlay.mp4", "mesh.mp4"):
        assert (out / name).stat().st_size > 1000, name
    from anima.io.video import read_video

    frames, info = read_video(out / "overlay.mp4")
    assert len(frames) == 40 and info.fps == 25.0
    src, _ = read_video(d0_path, max_frames=40)
    # the mesh is drawn over the face: the face region changed, the corners did not
    diff = np.abs(frames.astype(int) - src.astype(int)).mean(-1)
    assert diff[:, 200:330, 180:330].mean() > 15 and diff[:, -40:, -40:].mean() < 5
    r = cli("info", out / "capture.npz", "--json")
    info = json.loads(r.stdout)
    assert info["frames"] == 40 and info["mean_fit_error_px"] < 5 and "mean_fit_nme" in info
    r = cli("export", "glb", out / "capture.npz", "--out", tmp_path / "again.glb")
    assert r.returncode == 0 and (tmp_path / "again.glb").exists()
    # `anima export ... | true`: the reader of stdout is gone; the file is written, no traceback, no error
    p = subprocess.Popen(
        [sys.executable, "-m", "anima", "export", "arkit", out / "capture.npz", "--out", tmp_path / "x.csv"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    p.stdout.close()
    err = p.stderr.read().decode()
    assert p.wait() in (0, 141) and err == "" and (tmp_path / "x.csv").stat().st_size > 1000


@pytest.mark.parametrize(
    "kind,expect",
    [
        ("text", "not a readable video"),
        ("empty", "empty"),
        ("broken_mp4", "not a readable video"),
        ("noface", "no person"),
        ("tiny", "too small"),
    ],
)
def test_bad_input_clear_message_nonzero_exit(videos, tmp_path, kind, expect, cli):
    r = cli("capture", videos[kind], "--out", tmp_path / kind, "--quiet", "--no-render")
    assert r.returncode != 0
    assert expect in r.stderr and r.stderr.startswith("anima: error:"), r.stderr


def test_missing_file(tmp_path, cli):
    r = cli("capture", tmp_path / "nope.mp4", "--out", tmp_path / "o")
    assert r.returncode == 2 and "not found" in r.stderr
    r = cli("info", tmp_path / "nope.npz")
    assert r.returncode == 2 and "not found" in r.stderr


@pytest.mark.parametrize("kind", ["gray", "two_faces", "vfr", "truncated", "partial", "fps1000"])
def test_unusual_input_still_captured(videos, tmp_path, kind, cli):
    out = tmp_path / kind
    r = cli("capture", videos[kind], "--out", out, "--quiet", "--no-render", "--json")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    seq = read_sequence(out / "capture.npz")
    assert seq.n_frames == s["frames"] > 0
    if kind == "partial":  # frames without a face are kept and flagged, not dropped
        no_face = (seq.flags & FLAG_NO_FACE) > 0
        assert 0.3 < no_face.mean() < 0.7 and not no_face[:20].any() and no_face[-10:].all()
        assert np.isfinite(seq.expression).all()
    else:
        assert s["tracked_fraction"] > 0.9
    if kind in ("vfr", "truncated"):
        assert s["warnings"], "the user is told about resampling / truncation"
    if kind == "fps1000":
        assert seq.fps == pytest.approx(1000, rel=1e-3) and seq.n_frames == 30


def test_audio_features_command(tmp_path, cli):
    from anima.io.assets import asset

    out = tmp_path / "f.npz"
    r = cli(
        "audio",
        "features",
        asset("videoretalking-examples/examples/audio/1.wav"),
        "--fps",
        "15",
        "--out",
        out,
        "--json",
    )
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    with np.load(out) as z:
        assert z["features"].shape == (s["frames"], 28) and np.isfinite(z["features"]).all()
    r = cli("audio", "features", asset("liveportrait-examples/assets/examples/driving/d0.mp4"), "--out", out)
    assert r.returncode == 2 and "no audio track" in r.stderr
    # the output's suffix is the format's: another name is refused and nothing is written
    r = cli("audio", "features", asset("videoretalking-examples/examples/audio/1.wav"), "--out", tmp_path / "x.dat")
    assert r.returncode == 2 and "expected a .npz file" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.npz"]
    # run again into its own file: replaced (anima's by its content); a user's .npz is not
    r = cli("audio", "features", asset("videoretalking-examples/examples/audio/1.wav"), "--out", out)
    assert r.returncode == 0, r.stderr
    np.savez(tmp_path / "mine.npz", x=np.zeros(3))
    r = cli("audio", "features", asset("videoretalking-examples/examples/audio/1.wav"), "--out", tmp_path / "mine.npz")
    assert r.returncode == 2 and "anima wrote" in r.stderr


def test_capture_body_outputs_and_bvh_export(tmp_path, cli):
    from anima.io.assets import asset
    from anima.io.bvh import read_bvh
    from anima.io.video import probe_video

    clip = asset("gesture-video/tango-interviews/speaker8_jjRWaMCWs44_00-00-30.16_00-00-33.32.mp4")
    out = tmp_path / "o"
    r = cli("capture", clip, "--out", out, "--max-frames", "30", "--json", "--quiet")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    assert s["body_tracked_fraction"] == 1.0 and s["speech"]["present"]
    for name in ("body.bvh", "skeleton_overlay.mp4", "avatar.mp4", "avatar.glb", "speech.wav"):
        assert (out / name).stat().st_size > 1000, name
    info = probe_video(out / "avatar.mp4")
    assert info.has_audio and info.n_frames == 30
    run = json.loads((out / "info.json").read_text())  # the BVH line agrees with the manifest
    assert run["bvh"] == "written" and "body.bvh" in json.loads((out / "manifest.json").read_text())["files"]
    r = cli("export", "bvh", out / "capture.npz", "--out", tmp_path / "g.bvh", "--fps", "15")
    assert r.returncode == 0, r.stderr
    b = read_bvh(tmp_path / "g.bvh")
    from anima.core.rig import NAMES

    assert abs(b.frame_time - 1 / 15) < 1e-6 and b.names == list(NAMES)  # the character's rig
    r = cli("capture", clip, "--out", tmp_path / "f", "--max-frames", "10", "--face-only", "--quiet", "--json")
    assert r.returncode == 0 and "body_tracked_fraction" not in json.loads(r.stdout)
    avatar = json.loads((tmp_path / "f" / "info.json").read_text())["avatar"]  # a face-only clip: the idle body, said
    assert avatar["body"].startswith("idle") and avatar["legs"] == "standing"
    r = cli("export", "bvh", tmp_path / "f" / "capture.npz", "--out", tmp_path / "x.bvh")
    assert r.returncode == 2 and "no body" in r.stderr


def test_bad_audio_keeps_motion(videos, tmp_path, d0_path, cli):
    from anima.io.video import FFMPEG

    silent = tmp_path / "silent.wav"
    subprocess.run(
        [FFMPEG, "-v", "error", "-f", "lavfi", "-i", "anullsrc=r=16000:cl=mono", "-t", "2", str(silent)], check=True
    )
    r = cli(
        "capture",
        d0_path,
        "--out",
        tmp_path / "s",
        "--max-frames",
        "10",
        "--audio",
        silent,
        "--quiet",
        "--no-render",
        "--json",
    )
    assert r.returncode == 0 and json.loads(r.stdout)["speech"]["silent"] is True
    # an --audio that cannot be read is refused before any tracking ...
    r = cli("capture", d0_path, "--out", tmp_path / "v", "--max-frames", "10", "--audio", videos["text"], "--quiet")
    assert r.returncode == 2 and "--audio-optional" in r.stderr and not (tmp_path / "v" / "capture.npz").exists()
    # ... unless the user says the motion alone will do
    r = cli(
        "capture",
        d0_path,
        "--out",
        tmp_path / "u",
        "--max-frames",
        "10",
        "--audio",
        videos["text"],
        "--audio-optional",
        "--quiet",
        "--no-render",
        "--json",
    )
    assert r.returncode == 0, r.stderr
    sp = json.loads(r.stdout)["speech"]
    assert sp["present"] is False and "unreadable" in sp["reason"]
    assert read_sequence(tmp_path / "u" / "capture.npz").n_frames == 10


def test_exports_replace_only_files_anima_wrote(tmp_path, cli):
    """Each export format writes its own suffix; run twice into the same path, the second run replaces the
    first's file (anima's, by its content); a user's file of that name and suffix is never replaced (the
    refusals are in the bad-input matrix)."""
    import numpy as np

    from anima.export.framing import generated_sequence
    from anima.io import owned
    from anima.io.sequence import write_sequence

    rng = np.random.default_rng(0)
    face = np.concatenate([rng.random((12, 53)) * 0.3, rng.normal(0, 0.05, (12, 3))], 1).astype(np.float32)
    body = rng.normal(0, 0.2, (12, 55, 3)).astype(np.float32)
    seq = write_sequence(generated_sequence(15.0, face=face, body=body), tmp_path / "take.npz")
    for fmt, name in (("arkit", "t.csv"), ("bvh", "t.bvh"), ("glb", "t.glb"), ("vrma", "t.vrma"),
                      ("avatar", "t.vrm"), ("avatar", "a.glb")):  # fmt: skip
        for _ in range(2):
            r = cli("export", fmt, seq, "--out", tmp_path / name)
            assert r.returncode == 0, (fmt, r.stderr)
        assert owned.BY_SUFFIX[(tmp_path / name).suffix](tmp_path / name), name
        mine = tmp_path / f"mine{(tmp_path / name).suffix}"
        mine.write_bytes(b"my own file")
        r = cli("export", fmt, seq, "--out", mine)
        assert r.returncode == 2 and "anima wrote" in r.stderr and mine.read_bytes() == b"my own file"


def test_what_prints_after_the_result_goes_to_stderr():
    """A library's late words (Ray's message thread, an exit handler) never follow ``--json`` on stdout."""
    code = (
        "import atexit, sys; from anima.cli import main as m; "
        "atexit.register(lambda: print('a late word')); sys.argv = ['anima', '--version']; m.run()"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "a late word" not in r.stdout and "a late word" in r.stderr
    assert r.stdout.strip().startswith("anima"), r.stdout
