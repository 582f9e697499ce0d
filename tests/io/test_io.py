import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from anima.errors import InputError, SchemaError
from anima.io.arkit import HEAD_COLUMNS, LIVE_LINK_COLUMNS, read_live_link_csv, timecode
from anima.io.sequence import read_sequence, write_sequence
from anima.io.video import VideoWriter, probe_video, read_video

REPO = Path(__file__).resolve().parents[2]


def test_probe_real_clips_h264_and_hevc():
    from anima.io.assets import asset

    info = probe_video(asset("liveportrait-examples/assets/examples/driving/d0.mp4"))
    assert (info.fps, info.width, info.height, info.n_frames, info.codec) == (25.0, 512, 512, 78, "h264")
    hevc = probe_video(asset("talking-heads-misc/LatentSync/assets/demo1_video.mp4"))
    assert hevc.codec == "hevc" and (hevc.width, hevc.height) == (1080, 1920) and hevc.has_audio
    frames, _ = read_video(hevc.path, max_frames=3)
    assert frames.shape == (3, 1920, 1080, 3)


@pytest.mark.parametrize("kind", ["text", "empty", "broken_mp4"])
def test_unreadable_inputs_raise_clear_errors(videos, kind):
    with pytest.raises(InputError, match="video"):
        probe_video(videos[kind])


def test_missing_and_folder():
    with pytest.raises(InputError, match="not found"):
        probe_video("/nonexistent/clip.mp4")
    with pytest.raises(InputError, match="folder"):
        probe_video(REPO)


def test_vfr_is_detected_and_resampled(videos):
    info = probe_video(videos["vfr"])
    assert info.variable_frame_rate and info.warnings
    frames, _ = read_video(videos["vfr"])
    assert abs(len(frames) - info.duration * info.fps) <= 2


def test_truncated_keeps_decodable_frames(videos):
    info = probe_video(videos["truncated"])
    frames, _ = read_video(videos["truncated"])
    assert 10 < len(frames) < info.n_frames


def test_writer_roundtrip_with_audio(tmp_path):
    from anima.io.assets import asset

    wav = asset("videoretalking-examples/examples/audio/1.wav")
    out = tmp_path / "v.mp4"
    with VideoWriter(out, 25, (65, 48), audio_path=str(wav)) as w:  # odd size is padded to even
        for i in range(20):
            w.write(np.full((48, 65, 3), i * 10, np.uint8))
    info = probe_video(out)
    assert info.has_audio and (info.width, info.height) == (66, 48) and info.n_frames == 20


def test_sequence_roundtrip_and_schema_errors(d0_capture, tmp_path):
    p = write_sequence(d0_capture, tmp_path / "face.npz")
    s = read_sequence(p)
    assert s.n_frames == d0_capture.n_frames and s.fps == 25.0
    assert np.allclose(s.expression, d0_capture.expression, atol=1e-6)
    assert s.meta["source"]["codec"] == "h264" and s.meta["tracker"]["landmarks"] == 478
    summ = s.summary()
    assert summ["tracked_fraction"] == 1.0 and 0 < summ["mean_fit_nme"] < 0.03
    # a newer schema version is refused with a clear message
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("meta")))
    meta["version"] = 99
    np.savez(tmp_path / "new.npz", meta=np.asarray(json.dumps(meta)), **arrays)
    with pytest.raises(SchemaError, match="newer"):
        read_sequence(tmp_path / "new.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(InputError):
        read_sequence(tmp_path / "junk.npz")


def test_live_link_csv_layout(d0_capture, tmp_path):
    from anima.export.formats import export_arkit_csv

    p = export_arkit_csv(d0_capture, tmp_path / "a.csv")
    cols, vals = read_live_link_csv(p)
    assert len(LIVE_LINK_COLUMNS) == 52 and cols == LIVE_LINK_COLUMNS + HEAD_COLUMNS
    assert vals.shape == (d0_capture.n_frames, 61)
    first = p.read_text().splitlines()[1].split(",")
    assert first[0] == "00:00:00:00.000" and first[1] == "61"
    j = LIVE_LINK_COLUMNS.index("MouthSmileLeft")
    assert vals[30:50, j].mean() > 0.3
    assert timecode(26, 25.0) == "00:00:01:01.000"


def test_glb_passes_khronos_validator(d0_capture, tmp_path):
    from anima.export.formats import export_glb

    p = export_glb(d0_capture, tmp_path / "face.glb")
    node = shutil.which("node")
    assert node, "node is required (the validator is the npm package gltf-validator; .ci/run installs it)"
    assert (REPO / "node_modules" / "gltf-validator").is_dir(), "run `npm ci` (installs gltf-validator)"
    r = subprocess.run(
        [node, str(REPO / "tools" / "validate_gltf.js"), str(p)], capture_output=True, text=True, cwd=REPO, timeout=120
    )
    rep = json.loads(r.stdout)
    assert r.returncode == 0 and rep["issues"]["numErrors"] == 0, rep["issues"]
    assert rep["info"]["hasMorphTargets"] and rep["info"]["animationCount"] == 1


def _md5s(frames) -> list[str]:
    import hashlib

    return [hashlib.md5(np.ascontiguousarray(f).tobytes()).hexdigest() for f in frames]


@pytest.mark.parametrize(
    "clip",
    [
        # a timestamp seek lands one frame early on FLV (and on the last frames of LatentSync's demo2 HEVC,
        # left out here: decoding its 502 frames of 1080x1920 took 12 s of the suite's 30-min budget)
        "emotion-clips/crema-d/1001_DFA_ANG_XX.flv",
        "liveportrait-examples/assets/examples/driving/d6.mp4",  # long enough to seek into (1,008 frames)
        "shifted",  # d6 with its clock starting at 10 s
    ],
)
def test_a_frame_range_decodes_exactly_the_frames_of_a_whole_pass(clip, tmp_path):
    """The chunks of a long video in a dataset build decode only their frames: the pixels must be those a
    whole-video decode gives at the same indices, at the start, the middle and the end."""
    from anima.io.assets import asset
    from anima.io.video import FFMPEG, frame_times, iter_frame_range, iter_frames

    if clip == "shifted":
        path = tmp_path / "shifted.mp4"
        src = asset("liveportrait-examples/assets/examples/driving/d6.mp4")
        subprocess.run(
            [FFMPEG, "-v", "error", "-i", str(src), "-c", "copy", "-output_ts_offset", "10", str(path)], check=True
        )
    else:
        path = asset(clip)
    info = probe_video(path)
    n = info.n_frames
    ranges = [(0, 4), (1, 3), (n // 3, n // 3 + 30), (n // 2 + 7, n // 2 + 9), (n - 5, n + 10)]
    wanted = {k for a, b in ranges for k in range(a, min(b, n))}
    whole, count = {}, 0
    for k, f in enumerate(iter_frames(info)):
        count += 1
        if k in wanted:
            whole[k] = _md5s([f])[0]
    t = frame_times(path)
    assert len(t) == count == n
    for a, b in ranges:
        got = list(iter_frame_range(info, a, b, times=t))
        assert [k for k, _ in got] == list(range(a, min(b, n))), (a, b)
        assert _md5s(f for _, f in got) == [whole[k] for k in range(a, min(b, n))], (a, b)


def test_a_frame_range_refuses_a_variable_frame_rate_video(videos):
    from anima.io.video import iter_frame_range

    with pytest.raises(ValueError, match="constant-frame-rate"):
        list(iter_frame_range(probe_video(videos["vfr"]), 0, 5))


def test_results_name_paths_the_same_wherever_the_folders_sit(tmp_path, monkeypatch):
    """shown_path: a project file by its path from the repository root, data and user files by their
    folder's variable; anything else unchanged (results must not record where this copy happens to sit)."""
    from anima.io.assets import REPO_ROOT, shown_path

    monkeypatch.setenv("ANIMA_DATA", str(tmp_path / "data"))
    monkeypatch.setenv("ANIMA_HOME", str(tmp_path / "home"))
    assert shown_path(REPO_ROOT / "anima" / "eval" / "prompts" / "x.json") == "anima/eval/prompts/x.json"
    assert shown_path(tmp_path / "data" / "ict-facekit" / "a.npz") == "$ANIMA_DATA/ict-facekit/a.npz"
    assert shown_path(tmp_path / "data") == "$ANIMA_DATA"
    assert shown_path(tmp_path / "home" / "models" / "pose_lifter.pt") == "$ANIMA_HOME/models/pose_lifter.pt"
    assert shown_path(tmp_path / "elsewhere.pt") == str(tmp_path / "elsewhere.pt")
    assert shown_path("ds") == "ds"
