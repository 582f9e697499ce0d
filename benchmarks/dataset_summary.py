"""A dataset build's figures as a result file, for the docs (numbers generated, not typed): videos,
clips and what removed them, windows, the split by source, frames, seconds and the build's wall time, read
from the build's manifest (no paths of the machine that built it).

    python benchmarks/dataset_summary.py ds [--out benchmarks/results/dataset_build.json]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.dataset.storage import check_dataset  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402


def summary(manifest: dict) -> dict:
    table = manifest.get("split_table") or {}
    sides = Counter(r["split"] for r in table.values())
    sources = {s: len({r["source"] for r in table.values() if r["split"] == s}) for s in sides}
    run = manifest.get("last_run") or {}
    return {
        "command": "anima dataset build ../shared/data --out ds",
        "anima_version": manifest.get("anima_version"),
        "videos": manifest["videos"],
        "videos_failed": len(manifest.get("videos_failed") or []),
        "clips_cut": manifest["clips_total"],
        "clips_kept": manifest["clips_kept"],
        "removed_by_rule": manifest["removed_by_rule"],
        "windows": manifest["windows"],
        "emotion_clips": len(manifest.get("emotion_clips") or {}),
        "frames": manifest["frames"],
        "seconds_of_video": manifest["seconds_of_video"],
        "split_videos": {s: sides.get(s, 0) for s in ("train", "val", "test")},
        "split_sources": {s: sources.get(s, 0) for s in ("train", "val", "test")},
        "test_fraction": round(sides.get("test", 0) / max(1, sum(sides.values())), 3),
        "split_rule": manifest.get("split_rule"),
        "wall_s": run.get("wall_s"),
        "workers": run.get("workers"),
        "summed_task_s": manifest.get("compute_s"),
    }


def storage(folder: Path) -> dict:
    """Bytes on disk of the build's artifacts: (text, motion) and (audio, motion) shards, per-video JSON."""

    def size(sub: str) -> int:
        return sum(f.stat().st_size for f in (folder / sub).rglob("*") if f.is_file())

    return {k: size(k) for k in ("shards/text_motion", "shards/audio_motion", "videos")}


def estimate(s: dict, clips: int = 70_000, clip_s: float = 7.5) -> dict:
    """A seed-sized corpus scaled from this build: ``clips`` clips of ``clip_s`` s of video each, at this
    build's whole-command cost (wall x workers, start-up and idle tails included, per second of video) and
    its bytes per clip, per window and per video (one video per clip: an upper bound for the JSON)."""
    core_s_per_video_s = s["wall_s"] * s["workers"] / s["seconds_of_video"]
    core_h = clips * clip_s * core_s_per_video_s / 3600
    b = s["bytes"]
    per_clip = b["shards/text_motion"] / s["clips_kept"]
    windows_per_clip = s["windows"] / s["clips_kept"]
    per_window = b["shards/audio_motion"] / s["windows"]
    per_video = b["videos"] / s["videos"]
    return {
        "clips": clips,
        "clip_s": clip_s,
        "core_s_per_video_s": core_s_per_video_s,
        "core_hours": core_h,
        "hours_on_64_cores": core_h / 64,
        "hours_on_128_cores": core_h / 128,
        "text_motion_kb_per_clip": per_clip / 1e3,
        "windows_per_clip": windows_per_clip,
        "audio_motion_kb_per_window": per_window / 1e3,
        "video_json_kb_per_video": per_video / 1e3,
        "text_motion_gb": clips * per_clip / 1e9,
        "audio_motion_gb": clips * windows_per_clip * per_window / 1e9,
        "video_json_gb": clips * per_video / 1e9,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "dataset_build.json"))
    a = ap.parse_args()
    out = summary(check_dataset(a.dataset))
    out["bytes"] = storage(Path(a.dataset))
    out["estimate_70k_clips"] = estimate(out)
    write_json(a.out, out)
    print(out)


if __name__ == "__main__":
    main()
