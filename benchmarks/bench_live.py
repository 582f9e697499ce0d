"""``anima live`` in real time on 2 cores: real clips fed as a camera (``--realtime --loop``), the
page open in headless Chromium (software WebGL, on the same 2 cores). Per mode (face only on a 30-fps clip;
face + body + hands on a 25-fps clip): frames offered, tracked and dropped, the tracking rate, the latency from
a frame's arrival to its message (process) and to the page's receipt (glass to avatar, from the page's own
receipt times), and the process's memory over the run.

    python benchmarks/bench_live.py [--seconds 60] [--modes face,full]
    python benchmarks/bench_live.py --seconds 30 --modes full,full_vmc,full_vmc_no_page \
        --out benchmarks/results/live_vmc.json
    python benchmarks/bench_live.py --seconds 30 --modes full_no_page,full_vmc_no_page --repeats 3 \
        --out benchmarks/results/live_vmc_cost.json

Writes benchmarks/results/live.json. Targets: >= 95 % of offered frames tracked, latency median <= 100 ms and
p95 <= 150 ms, memory growth < 10 %. ``full_vmc`` is ``full`` with ``--vmc`` to a python-osc receiver on
127.0.0.1 (the tracking rate unchanged with it, >= 20 bundles a second arriving); ``full_vmc_no_page``
the same with anima's page not open (a VTuber app draws the avatar from the VMC stream), and ``full_no_page``
its like without ``--vmc``. ``--repeats N`` runs the modes interleaved N times (A B A B ...: a noisy machine's
drift falls on every mode alike) and adds, per mode, the median of its runs, and the ratio of each ``*vmc*``
mode's tracking rate to the same mode without VMC where both ran: what ``--vmc`` costs, measured side by side.
The receiver only keeps each packet and its arrival time while anima runs and parses them (python-osc) after:
parsing costs about three times what anima spends writing a bundle, and would otherwise be counted as anima's.
"""

from __future__ import annotations

import argparse
import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from browser import chromium
from vmc_receiver import VmcReceiver

from anima.io.assets import asset
from anima.io.atomic import write_json

CLIPS = {
    "face": ("liveportrait-examples/assets/examples/driving/d6.mp4", ["--face-only"]),  # 30 fps
    "full": ("gesture-video/pats-crops/oliver1_gt.mp4", []),  # 25 fps, body and hands
    "full1": ("gesture-video/pats-crops/oliver1_gt.mp4", ["--trackers", "1"]),  # one Holistic: lower latency?
    "full_vmc": ("gesture-video/pats-crops/oliver1_gt.mp4", ["--vmc"]),  # and the VMC protocol to a receiver
    "full_vmc_no_page": ("gesture-video/pats-crops/oliver1_gt.mp4", ["--vmc"]),  # a VTuber app shows it: no page
    "full_no_page": ("gesture-video/pats-crops/oliver1_gt.mp4", []),  # full_vmc_no_page's like, without VMC
}
NO_PAGE = {"full_vmc_no_page", "full_no_page"}  # modes run without anima's page open (a receiver draws the avatar)
WITHOUT_VMC = {"full_vmc": "full", "full_vmc_no_page": "full_no_page"}  # each VMC mode's like without it


def run(mode: str, seconds: float) -> dict:
    if "--vmc" not in CLIPS[mode][1]:
        return _run(mode, seconds, [])
    with VmcReceiver(idle_s=15.0) as rx:
        row = _run(mode, seconds, [f"127.0.0.1:{rx.port}"])
    t = np.array([f["t"] for f in rx.frames])
    row["vmc"] = {"bundles": len(t), "fps": round((len(t) - 1) / (t[-1] - t[0]), 2) if len(t) > 1 else 0.0,
                  "protocol_errors": len(rx.bad)}  # fmt: skip
    return row


def _run(mode: str, seconds: float, more: list[str]) -> dict:
    clip, extra = CLIPS[mode]
    extra = extra + more
    cmd = [sys.executable, "-m", "anima", "live", str(asset(clip)), "--realtime", "--loop", "--no-browser",
           "--json", "--max-seconds", str(seconds + 30), *extra]  # fmt: skip
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # fmt: skip
    url = re.search(r"(http://\S+/index\.html)", p.stdout.readline()).group(1)
    page = None
    if mode in NO_PAGE:
        time.sleep(seconds)
    else:
        with chromium() as b:
            b.get(url)
            time.sleep(seconds)
            page = b.execute_script("return anima.live")
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    proc = json.loads(out[out.index("{") :])
    rss = proc["rss_mb"]
    if page is not None:
        lat, fr = np.array(page["latencies"], float), np.array(page["frames"], float)
        page = {
            "messages": page["received"],
            "fps": round((len(fr) - 1) / ((fr[-1, 1] - fr[0, 1]) / 1e3), 2) if len(fr) > 1 else 0.0,
            "glass_to_avatar_ms": {
                "median": round(float(np.median(lat)), 1),
                "p95": round(float(np.percentile(lat, 95)), 1),
            },  # fmt: skip
        }
    return {
        "clip": clip,
        "mode": proc["mode"],
        "seconds": seconds,
        "source_fps": proc["source_fps"],
        "frames_offered": proc["frames_offered"],
        "frames_tracked": proc["frames_tracked"],
        "tracked_fraction": proc["tracked_fraction"],
        "tracking_fps": proc["fps"],
        "latency_to_message_ms": proc["latency_ms"],
        "page": page,  # None: the page was not open
        "rss_mb": {
            "after_10s": rss[min(10, len(rss) - 1)],
            "end": rss[-1],
            "samples": len(rss),
            "growth_pct": round(100 * (rss[-1] / rss[min(10, len(rss) - 1)] - 1), 2),
        },  # fmt: skip
    }


def repeated(runs: dict[str, list[dict]]) -> dict:
    """Every run of each mode, the median tracking rate (and VMC bundles a second), and each VMC mode's rate
    over its like without VMC (the medians', and run by run: run k of both modes ran side by side)."""
    med = {}
    for m, rs in runs.items():
        med[m] = {"tracking_fps": [r["tracking_fps"] for r in rs],
                  "tracking_fps_median": float(np.median([r["tracking_fps"] for r in rs]))}  # fmt: skip
        if all("vmc" in r for r in rs):
            med[m]["vmc_fps"] = [r["vmc"]["fps"] for r in rs]
            med[m]["vmc_fps_median"] = float(np.median(med[m]["vmc_fps"]))
            med[m]["protocol_errors"] = sum(r["vmc"]["protocol_errors"] for r in rs)
    ratios = {}
    for m, base in WITHOUT_VMC.items():
        if m in runs and base in runs:
            pairs = [a["tracking_fps"] / b["tracking_fps"] for a, b in zip(runs[m], runs[base]) if b["tracking_fps"]]
            of_medians = med[m]["tracking_fps_median"] / med[base]["tracking_fps_median"]
            ratios[f"{m}/{base}"] = {"of_medians": round(of_medians, 3), "per_run": [round(x, 3) for x in pairs]}
    return {"repeats": len(next(iter(runs.values()))), "runs": runs, "medians": med, "vmc_cost_ratios": ratios}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--modes", default="face,full,full1")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "live.json"))
    ap.add_argument("--repeats", type=int, default=1, help="run the modes interleaved this many times")
    a = ap.parse_args()
    if a.repeats < 1:
        ap.error("--repeats: 1 or more")
    modes = a.modes.split(",")
    runs: dict[str, list[dict]] = {m: [] for m in modes}
    for _ in range(a.repeats):
        for m in modes:
            runs[m].append(run(m, a.seconds))
    rows = {m: r[0] for m, r in runs.items()}
    doc = {"machine": "2 cores, no GPU; headless Chromium (SwiftShader) on the same cores", **rows}
    if a.repeats > 1:
        doc = {**doc, **repeated(runs)}
    write_json(a.out, doc)
    for m, r in rows.items():
        pg = r["page"]
        page = (f"page {pg['fps']} fps, glass to avatar {pg['glass_to_avatar_ms']['median']} / "
                f"{pg['glass_to_avatar_ms']['p95']} ms" if pg else "no page")  # fmt: skip
        print(f"{m:5s} tracked {100 * r['tracked_fraction']:.1f} % of {r['frames_offered']} at {r['source_fps']:g} fps "
              f"({r['tracking_fps']} fps); {page}; memory {r['rss_mb']['after_10s']} -> {r['rss_mb']['end']} MB"
              + (f"; VMC {r['vmc']['fps']} bundles/s" if "vmc" in r else ""))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
