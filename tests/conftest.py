import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("GLOG_minloglevel", "2")
os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")

from anima.io.assets import asset
from anima.io.video import FFMPEG

D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def d0_path() -> Path:
    return asset(D0)


@pytest.fixture(scope="session")
def shared_split_table() -> dict:
    """The split table of every video of the shared data (``anima.dataset.splits.table``: file and face-crop
    hashes of 100 videos, about 45 s), made once for the session's tests that check splits against it."""
    from anima.dataset import splits
    from anima.dataset.build import expand_videos
    from anima.io.assets import data_root

    return splits.table(expand_videos([str(data_root().resolve())]), data_root().resolve())


@pytest.fixture(scope="session")
def face_model():
    from anima.facemodel.ict import load_face_model

    return load_face_model()


class _Forked:
    """One ``tests/forkrun.py`` for the session: each command line runs in a fresh ``anima`` process forked from
    a parent that imported the command line once (its own descriptors, exit code, stdout and stderr), instead
    of a new interpreter paying ~1.5 s of imports per call."""

    def __init__(self):
        self.p = None
        self.n = 0

    def run(self, argv: list[str], timeout: float, env: dict) -> dict | None:
        if self.p is None or self.p.poll() is not None:
            self.p = subprocess.Popen(
                [sys.executable, str(Path(__file__).parent / "forkrun.py")],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
            )
        self.n += 1
        try:
            self.p.stdin.write(json.dumps({"id": self.n, "argv": argv, "env": env, "timeout": timeout}) + "\n")
            self.p.stdin.flush()
            line = self.p.stdout.readline()
        except (BrokenPipeError, OSError):
            line = ""
        return json.loads(line) if line else None


_FORKED = _Forked()


def anima_cli(*args, timeout: float = 900, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run the ``anima`` command as a user does, in a new process (forked from a parent that imported the
    command line once; a new interpreter if that parent is gone); whatever happens, stderr holds no traceback
    (errors are one line). ``env``: the command's environment (what differs from this one is set)."""
    argv = [str(a) for a in args]
    delta = {k: v for k, v in (env or {}).items() if os.environ.get(k) != v}
    r = _FORKED.run(argv, timeout, delta)
    if r is None:  # the forking parent died: run as a new interpreter
        cp = subprocess.run(
            [sys.executable, "-m", "anima", *argv], capture_output=True, text=True, timeout=timeout, env=env
        )
    else:
        if r["rc"] == -9:
            raise subprocess.TimeoutExpired([sys.executable, "-m", "anima", *argv], timeout, r["stdout"], r["stderr"])
        cp = subprocess.CompletedProcess([sys.executable, "-m", "anima", *argv], r["rc"], r["stdout"], r["stderr"])
    assert "Traceback" not in cp.stderr, cp.stderr[-3000:]
    return cp


@pytest.fixture(scope="session")
def cli():
    """The one command runner of the suite: ``cli("capture", video, "--out", out)``."""
    return anima_cli


def ffmpeg(*args: str) -> None:
    subprocess.run([FFMPEG, "-hide_banner", "-nostdin", "-v", "error", "-y", *args], check=True)


@pytest.fixture(scope="session")
def d0_capture(tmp_path_factory, d0_path):
    """The real d0 clip (smile + blink) captured once for the session."""
    from anima.capture.pipeline import capture_face

    return capture_face(str(d0_path), progress=False)


@pytest.fixture(scope="session")
def videos(tmp_path_factory, d0_path) -> dict:
    """Bad or unusual inputs derived from the real d0 clip with ffmpeg."""
    d = tmp_path_factory.mktemp("videos")
    out = {}
    out["gray"] = d / "gray.mp4"
    ffmpeg(
        "-i",
        str(d0_path),
        "-t",
        "1.2",
        "-vf",
        "format=gray",
        "-c:v",
        "libx264",
        "-pix_fmt",
        "yuv420p",
        str(out["gray"]),
    )
    out["tiny"] = d / "tiny.mp4"
    ffmpeg("-i", str(d0_path), "-t", "0.5", "-vf", "scale=24:24", "-c:v", "libx264", str(out["tiny"]))
    out["noface"] = d / "noface.mp4"
    ffmpeg(
        "-f",
        "lavfi",
        "-i",
        "testsrc=size=256x256:rate=25",
        "-t",
        "1",
        "-c:v",
        "libx264",
        "-pix_fmt",
        "yuv420p",
        str(out["noface"]),
    )
    out["partial"] = d / "partial.mp4"  # 1 s of face, then 1 s without
    ffmpeg(
        "-i",
        str(d0_path),
        "-f",
        "lavfi",
        "-i",
        "testsrc=size=512x512:rate=25",
        "-filter_complex",
        "[0:v]trim=duration=1,setpts=PTS-STARTPTS[a];[1:v]trim=duration=1,setpts=PTS-STARTPTS,format=yuv420p[b];"
        "[a][b]concat=n=2:v=1[v]",
        "-map",
        "[v]",
        "-c:v",
        "libx264",
        str(out["partial"]),
    )
    out["two_faces"] = d / "two.mp4"
    ffmpeg(
        "-i",
        str(d0_path),
        "-i",
        str(d0_path),
        "-t",
        "1",
        "-filter_complex",
        "[0:v]scale=256:256[a];[1:v]scale=200:200,pad=256:256:28:28[b];[a][b]hstack",
        "-c:v",
        "libx264",
        str(out["two_faces"]),
    )
    out["fps1000"] = d / "fps1000.mp4"  # a high-speed camera's 1000 fps (ffmpeg says "1k fps")
    ffmpeg(
        "-i",
        str(d0_path),
        "-frames:v",
        "30",
        "-vf",
        "setpts=PTS/40",
        "-r",
        "1000",
        "-c:v",
        "libx264",
        str(out["fps1000"]),
    )
    out["vfr"] = d / "vfr.mp4"
    ffmpeg(
        "-i",
        str(d0_path),
        "-t",
        "2",
        "-vf",
        "setpts='(N+floor(N/2))/25/TB'",
        "-vsync",
        "vfr",
        "-c:v",
        "libx264",
        str(out["vfr"]),
    )
    ffmpeg("-i", str(d0_path), "-c", "copy", "-movflags", "+faststart", str(d / "faststart.mp4"))
    data = (d / "faststart.mp4").read_bytes()
    out["truncated"] = d / "truncated.mp4"  # an interrupted download: index first, 60 % of the data
    out["truncated"].write_bytes(data[: int(len(data) * 0.6)])
    out["text"] = d / "notes.mp4"
    out["text"].write_text("this is not a video\n" * 20)
    out["empty"] = d / "empty.mp4"
    out["empty"].write_bytes(b"")
    out["broken_mp4"] = d / "broken.mp4"
    raw = d0_path.read_bytes()  # index at the end: cut before it, nothing is decodable
    out["broken_mp4"].write_bytes(raw[: len(raw) // 3])
    return out


GESTURE_CLIPS = [
    "gesture-video/pats-crops/oliver1_gt.mp4",
    "gesture-video/pats-crops/oliver3_gt.mp4",
    "gesture-video/pats-crops/seth3_gt.mp4",
    "styletalk-samples/samples/source_video/video/feifeili_clip3.mp4",
]


@pytest.fixture(scope="session")
def gesture_ds(tmp_path_factory, cli):
    """A dataset built once from real clips: three PATS gesture clips (body, hands and speech) and one StyleTalk
    talking head whose speech ships as a separate WAV (face-only windows)."""
    out = tmp_path_factory.mktemp("gds") / "ds"
    r = cli("dataset", "build", *[asset(c) for c in GESTURE_CLIPS], "--out", out, "--min-len", "2", "--quiet", "--json")
    assert r.returncode == 0, r.stderr[-2000:]
    return out


PATS = ["oliver1", "seth3", "noah1", "chem1"]


@pytest.fixture(scope="session")
def captures():
    """Four PATS clips (body, hands, face, speech), 90 frames each, captured once with the real pipeline (the
    rig, retarget and live tests share them)."""
    from anima.capture.config import CaptureConfig
    from anima.capture.pipeline import capture_video

    return {
        n: capture_video(
            str(asset(f"gesture-video/pats-crops/{n}_gt.mp4")), CaptureConfig(max_frames=90), progress=False
        )
        for n in PATS
    }


@pytest.fixture(scope="session")
def gesture_db(gesture_ds):
    """The motion-matching database of ``gesture_ds`` (every split), built once for the session."""
    from anima.gesture.database import from_dataset

    return from_dataset(gesture_ds, None)


def synthetic_rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


# Fixtures that run MediaPipe, the command line or training on real clips: a test that uses one is `slow`
# (`./dev test -m "not slow"` is the quick loop; CI runs everything).
SLOW_FIXTURES = {
    "cli",
    "d0_capture",
    "videos",
    "ds",
    "db",
    "obama_db",
    "tiny_model",
    "windows",
    "shipped",
    "gesture_ds",
}


def pytest_collection_modifyitems(config, items):
    for item in items:
        if SLOW_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
