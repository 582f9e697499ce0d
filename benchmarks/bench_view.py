"""How fast ``anima view`` is in a real browser (headless Chromium, software WebGL, no GPU): the time from the
page starting to load to the page being interactive, and the frames per second the 3D view draws while
playing, for a 1-minute capture beside a 3-second one (same run, so the ratio is free of machine noise).

    python benchmarks/bench_view.py            # captures both clips first (~3 min)
    python benchmarks/bench_view.py --long DIR --short DIR

Writes benchmarks/results/view.json and prints a table. Target: the 1-minute capture interactive
within 2 s and drawn at the clip's frame rate; the face close-up measured against the page without it
(``#noface``), loaded in turns.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from browser import chromium, play_and_sample, served, wait_media, wait_ready

from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.sequence import read_sequence

LONG = "talking-heads-extra/pose_source2.mp4"  # 60 s, 25 fps
SHORT = "gesture-video/pats-crops/oliver1_gt.mp4"  # body and hands; 75 frames = 3 s


def capture(clip: str, out: Path, frames: int | None = None) -> Path:
    cmd = [sys.executable, "-m", "anima", "capture", str(asset(clip)), "--out", str(out), "--quiet"]
    subprocess.run(cmd + (["--max-frames", str(frames)] if frames else []), check=True)
    return out


def after_start(samples: list) -> tuple[float | None, float | None]:
    """From :func:`play_and_sample`'s samples: the seconds from play to the first new frame drawn, and the
    distinct frames drawn per second from then on (None when fewer than two samples followed it)."""
    t = [(s[4], s[6]) for s in samples]
    new = [k for k, s in enumerate(samples) if s[0] > 0]  # play starts at frame 0
    if len(new) < 2:
        return None, None
    (t0, n0), (t1, n1) = t[new[0]], t[-1]
    return t0, (n1 - n0) / (t1 - t0) if t1 > t0 else None


def measure(folder: Path, browser, repeats: int = 3, seconds: float = 6.0) -> dict:
    """The page as it is and without the face close-up (``#noface``), loaded in turns (the same machine load)."""
    seq = read_sequence(folder / "capture.npz", landmarks=False)
    ready, drawn = {"": [], "#noface": []}, {"": [], "#noface": []}
    start, steady = [], []
    with served(folder) as (url, _):
        for _ in range(repeats):
            for variant in ready:
                browser.get("about:blank")
                browser.get(url + variant)
                ready[variant].append(wait_ready(browser)["ms"])
                wait_media(browser)
                # play within the clip (a clip that ends stops drawing new frames)
                sample = play_and_sample(browser, min(seconds, seq.n_frames / seq.fps - 0.5))
                drawn[variant].append(sample["drawn_frames_per_s"])
                if not variant:
                    t0, rate = after_start(sample["samples"])
                    start.append(t0)
                    steady.append(rate)
    return {
        "frames": seq.n_frames,
        "seconds": round(seq.n_frames / seq.fps, 2),
        "fps": seq.fps,
        "body": bool(seq.body_joints is not None),
        "avatar_glb_mb": round((folder / "avatar.glb").stat().st_size / 1e6, 2),
        "ready_ms": [round(x) for x in ready[""]],
        "ready_ms_median": round(statistics.median(ready[""])),
        "drawn_fps": [round(x, 1) for x in drawn[""]],
        "drawn_fps_median": round(statistics.median(drawn[""]), 1),
        "drawn_over_clip_fps": round(statistics.median(drawn[""]) / seq.fps, 3),
        # the window above includes the start of playback (the videos starting, the first new frame): on a clip of
        # a few seconds that is a frame or two of the count; the rate from the first new frame on, beside it
        "first_new_frame_ms": [None if x is None else round(1000 * x) for x in start],
        "drawn_fps_after_start": [None if x is None else round(x, 1) for x in steady],
        "drawn_fps_after_start_median": round(statistics.median([x for x in steady if x is not None]), 1)
        if any(x is not None for x in steady)
        else None,
        "without_face_close_up": {
            "ready_ms_median": round(statistics.median(ready["#noface"])),
            "drawn_fps": [round(x, 1) for x in drawn["#noface"]],
            "drawn_fps_median": round(statistics.median(drawn["#noface"]), 1),
        },
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--long", type=Path, help="a capture folder of about a minute (default: capture one)")
    ap.add_argument("--short", type=Path, help="a capture folder of a few seconds (default: capture one)")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results" / "view.json")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        long_ = a.long or capture(LONG, Path(tmp) / "long")
        short = a.short or capture(SHORT, Path(tmp) / "short", 75)
        with chromium() as b:
            rows = {"1-minute capture": measure(long_, b), "3-second capture": measure(short, b)}
    r = {
        "browser": "headless Chromium (Debian), WebGL on SwiftShader (software), 2 CPU cores",
        "ready": "performance.now() at the page's `ready` (navigation start -> interactive: data, GLB parsed, "
        "first frame applied)",
        "rows": rows,
        "ready_ratio_long_over_short": round(
            rows["1-minute capture"]["ready_ms_median"] / rows["3-second capture"]["ready_ms_median"], 2
        ),
    }
    write_json(a.out, r)
    print("| capture | frames | GLB MB | ready ms (median of 3) | 3D frames drawn / s while playing | / clip fps "
          "| from the first new frame: frames / s | without the face close-up: frames / s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for name, x in rows.items():
        print(
            f"| {name} | {x['frames']} | {x['avatar_glb_mb']} | {x['ready_ms_median']} | {x['drawn_fps_median']} "
            f"| {x['drawn_over_clip_fps']} | {x['drawn_fps_after_start_median']} "
            f"| {x['without_face_close_up']['drawn_fps_median']} |"
        )
    print(f"ready time ratio, 1 minute / 3 seconds: {r['ready_ratio_long_over_short']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
