"""Cold start with no dataset: `anima text2face PROMPT` and `anima gesture SPEECH` on the built-in
motion library, each in a fresh process (the way a user runs them), without and with the videos (side by
side in one run: the difference is the render's cost). Writes benchmarks/results/builtin.json.

    python benchmarks/bench_builtin.py [--repeats 5]

Target: under 3 s each, cold, on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.io.assets import asset  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402

PROMPT = "she winks, then looks up and puffs out her cheeks"
SPEECH = "videoretalking-examples/examples/audio/1.wav"


def timed(args: list[str], repeats: int) -> dict:
    runs = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "anima", *args, "--out", f"{tmp}/o"], capture_output=True)
            runs.append(time.perf_counter() - t)
            if r.returncode:
                raise SystemExit(r.stderr.decode()[-2000:])
    return {"median_s": round(statistics.median(runs), 3), "runs_s": [round(x, 3) for x in runs]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "builtin.json"))
    a = ap.parse_args()
    speech = str(asset(SPEECH))
    rows = {
        "text2face --no-video": timed(["text2face", PROMPT, "--no-video"], a.repeats),
        "gesture --no-render": timed(["gesture", speech, "--no-render"], a.repeats),
        "text2face (face.mp4 + avatar.mp4)": timed(["text2face", PROMPT], a.repeats),
        "gesture (videos)": timed(["gesture", speech], a.repeats),
    }
    out = {
        "what": "wall time of a fresh `anima` process with no --db (the built-in library), prompt and speech below",
        "prompt": PROMPT,
        "speech": SPEECH,
        "target_s": 3.0,
        "rows": rows,
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "when": time.strftime("%Y-%m-%d %H:%M"),
    }
    write_json(a.out, out)
    for k, v in rows.items():
        print(f"{k:40s} {v['median_s']:.2f} s  {v['runs_s']}")


if __name__ == "__main__":
    main()
