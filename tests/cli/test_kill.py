"""Killed at any moment, a command leaves the previous complete result or no result, never a partial file that
a reader accepts. Each command runs once to completion (its duration sets the kill window), then is killed
with SIGKILL at seeded random points, half of the time over a complete earlier result; after every kill each
file in the output is either absent, hidden (an unfinished temporary file, which no reader takes and the
next run removes) or complete by its own reader."""

import json
import random
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from anima.io.assets import asset
from anima.io.video import FFMPEG, probe_video

D0 = "liveportrait-examples/assets/examples/driving/d0.mp4"
SPEECH = "videoretalking-examples/examples/audio/1.wav"
OBAMA = "styletalk-samples/samples/source_video/video/Obama_clip1.mp4"
pytestmark = pytest.mark.slow  # dozens of real runs, killed (about two minutes)
KILLS = {"capture": 6, "export": 10, "text2face": 4, "gesture": 7, "reenact": 5, "dataset": 3}


class Runner:
    """Command lines run as fresh ``anima`` processes forked by ``tests/forkrun.py`` (the heavy imports done
    once, so a run starts in milliseconds and the kill windows are the commands' own work), each killed with
    SIGKILL (its whole process group: ffmpeg, Ray) when it runs past its time."""

    def __init__(self):
        self.p = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve().parents[1] / "forkrun.py")],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self.n = 0

    def run(self, argv, timeout: float = 600) -> dict:
        self.n += 1
        self.p.stdin.write(json.dumps({"id": self.n, "argv": [str(a) for a in argv], "timeout": timeout}) + "\n")
        self.p.stdin.flush()
        return json.loads(self.p.stdout.readline())

    def close(self):
        self.p.stdin.close()
        self.p.wait(60)


def _run(argv, runner: Runner, timeout=600) -> dict:
    r = runner.run(argv, timeout)
    assert r["rc"] == 0, (argv, r["stderr"][-1000:])
    return r


def _killed(argv, after_s: float, runner: Runner) -> None:
    runner.run(argv, after_s)  # SIGKILLed at after_s unless it finished first


def check_file(p: Path, frames: int | None) -> str | None:
    """None if ``p`` is complete by its reader, else what is wrong."""
    from anima.io.bvh import read_bvh
    from anima.io.sequence import read_sequence

    try:
        if p.name.startswith("."):
            if p.name == ".anima-folder":  # anima's marker: written atomically, always readable
                json.loads(p.read_text())
                return None
            if p.name.endswith(".anima.json"):  # the record beside an exported file: written after it, atomically
                json.loads(p.read_text())
                return None
            return None if ".anima-tmp-" in p.name or p.name == ".anima.lock" else f"unknown hidden file {p.name}"
        if p.suffix == ".npz":
            read_sequence(p, landmarks=False)
        elif p.suffix == ".csv":
            rows = p.read_text().splitlines()
            if frames is not None and len(rows) != frames + 1:
                return f"{len(rows) - 1} CSV rows of {frames}"
        elif p.suffix == ".glb":
            data = p.read_bytes()
            if data[:4] != b"glTF" or int.from_bytes(data[8:12], "little") != len(data):
                return "GLB length does not match"
        elif p.suffix == ".bvh":
            b = read_bvh(p)
            if frames is not None and len(b.motion) != frames:
                return f"{len(b.motion)} BVH frames of {frames}"
        elif p.suffix == ".mp4":
            info = probe_video(p)
            if frames is not None and abs(info.n_frames - frames) > 1:
                return f"{info.n_frames} video frames of {frames}"
        elif p.suffix == ".json":
            json.loads(p.read_text())
        elif p.suffix == ".parquet":
            import pyarrow.parquet as pq

            pq.read_table(p)
    except Exception as e:
        return f"{type(e).__name__}: {e}"
    return None


def check_folder(d: Path, frames: int | None = None) -> list[str]:
    """Problems in a result folder after a kill (see the module docstring); ``frames``: the expected frame
    count when the folder holds no sequence to read it from."""
    from anima.io.outdir import MANIFEST, check_complete

    if not d.exists():
        return []
    problems = []
    seqs = [p for p in d.glob("*.npz") if not p.name.startswith(".")]
    if seqs:
        from anima.io.sequence import read_sequence

        try:
            frames = read_sequence(seqs[0], landmarks=False).n_frames
        except Exception as e:
            return [f"{seqs[0].name}: {e}"]
    for p in d.rglob("*"):
        if p.is_file():
            why = check_file(p, frames if p.parent == d else None)
            if why:
                problems.append(f"{p.relative_to(d)}: {why}")
    if (d / MANIFEST).exists() and '"anima.result"' in (d / MANIFEST).read_text():
        try:
            check_complete(d)
        except Exception as e:
            problems.append(f"manifest.json written but the folder is not complete: {e}")
    return problems


@pytest.fixture(scope="module")
def inputs(tmp_path_factory, gesture_ds):
    d = tmp_path_factory.mktemp("kill")
    actor = d / "actor.mp4"
    subprocess.run(
        [FFMPEG, "-v", "error", "-y", "-i", str(asset(D0)), "-t", "1.2", "-c:v", "libx264", str(actor)], check=True
    )
    target = d / "target.mp4"  # 4.5 s of the Obama clip (112 frames: a database needs 100)
    subprocess.run(
        [FFMPEG, "-v", "error", "-y", "-i", str(asset(OBAMA)), "-t", "4.5", "-c:v", "libx264", "-an", str(target)],
        check=True,
    )
    seq = d / "seq"
    runner = Runner()
    _run(["capture", asset(D0), "--out", seq, "--max-frames", "60", "--quiet", "--no-render"], runner)
    db = d / "obama.npz"
    _run(["reenact", "--actor", actor, "--target", target, "--out", d / "warm.mp4", "--db", db, "--quiet"], runner)
    runner.close()
    return {"dir": d, "actor": actor, "target": target, "seq": seq / "capture.npz", "db": db, "ds": gesture_ds}


def _command(kind: str, inp: dict, out: Path) -> list:
    return {
        "capture": ["capture", asset(D0), "--out", out, "--max-frames", "20", "--quiet"],
        "export": ["export", "glb", inp["seq"], "--out", out / "face.glb"],
        # (videos are killed mid-encode by capture and reenact; text2face's are the same writer)
        "text2face": ["text2face", "a woman smiles, then blinks", "--out", out, "--no-video"],
        "gesture": ["gesture", asset(SPEECH), "--db", inp["ds"], "--all-splits", "--out", out],
        "reenact": [
            "reenact",
            "--actor",
            inp["actor"],
            "--target",
            inp["target"],
            "--db",
            inp["db"],
            "--out",
            out / "re.mp4",
            "--quiet",
        ],
        "dataset": [
            "dataset",
            "build",
            asset("gesture-video/pats-crops/oliver4_gt.mp4"),
            asset("gesture-video/pats-crops/seth2_gt.mp4"),
            "--out",
            out,
            "--min-len",
            "2",
            "--max-frames",
            "60",
            "--workers",
            "1",
            "--quiet",
        ],
    }[kind]


def _one_kind(kind: str, inp: dict) -> list[str]:
    runner = Runner()
    try:
        return _kill_kind(kind, inp, runner)
    finally:
        runner.close()


def _complete(argv, runner: Runner, out: Path, frames) -> list[str]:
    """A run over what the kills left, which must complete. A run that dies of a signal of its own (seen once in
    a clean run: reenact, SIGABRT, nothing on stderr; the test passed when rerun) counts as one more kill: the
    folder is checked like after the others, the crash is printed with the child's fault-handler trace, and the
    run after it must complete."""
    r = runner.run(argv, 600)
    problems = []
    if r["rc"] < 0 and r["rc"] != -9:
        print(f"{argv[0]}: died of signal {-r['rc']}: {r['stderr'][-2000:]!r}")
        problems = [f"{argv[0]} crash: {p}" for p in check_folder(out, frames)]
        r = runner.run(argv, 600)
    assert r["rc"] == 0, (argv, r["stderr"][-1000:])
    return problems


def _kill_kind(kind: str, inp: dict, runner: Runner) -> list[str]:
    rng = random.Random(f"kill-{kind}")
    base = inp["dir"] / kind
    t0 = time.perf_counter()
    full = base / "full"
    full.mkdir(parents=True)
    _run(_command(kind, inp, full), runner)
    duration = time.perf_counter() - t0
    frames = probe_video(inp["actor"]).n_frames if kind == "reenact" else None
    problems = [f"{kind} (full run): {p}" for p in check_folder(full, frames)]
    out = base / "killed"  # every kill runs into what the previous one left; every third over a complete result
    out.mkdir()
    for k in range(KILLS[kind]):
        if k % 3 == 1:
            problems += _complete(_command(kind, inp, out), runner, out, frames)
        _killed(_command(kind, inp, out), rng.uniform(0.05, duration), runner)
        problems += [f"{kind} kill {k}: {p}" for p in check_folder(out, frames)]
    problems += _complete(_command(kind, inp, out), runner, out, frames)  # and a rerun after the last kill
    problems += [f"{kind} rerun after the kills: {p}" for p in check_folder(out, frames)]
    print(f"{kind}: full run {duration:.1f} s, {KILLS[kind]} kills, {time.perf_counter() - t0:.0f} s in all")
    return problems


def test_kills_leave_complete_results_or_none(inputs):
    assert sum(KILLS.values()) >= 35
    with ThreadPoolExecutor(2) as pool:  # the longest kinds first, so that the two runners end together
        order = ["capture", "dataset", "reenact", "gesture", "text2face", "export"]
        results = list(pool.map(lambda k: _one_kind(k, inputs), order))
    problems = [p for r in results for p in r]
    assert not problems, "\n".join(problems)
