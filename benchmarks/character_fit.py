"""The character's proportions on every shared gesture clip: each clip captured (body and hands,
the first ``--frames`` frames), the character's shape fitted to its bone lengths, and per clip the captured and
the character's arm (shoulder to elbow to wrist, sides averaged), the error in %, the other measures' errors,
the character's height.

    python benchmarks/character_fit.py [--frames 90]

Writes benchmarks/results/character_fit.json and prints a markdown table. The target: every arm within 10 %.
"""

from __future__ import annotations

import argparse
import glob
from pathlib import Path

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_video
from anima.export.avatar import character_motion
from anima.facemodel.character import tracked_measures
from anima.io.assets import data_root
from anima.io.atomic import write_json

CLIPS = (
    "gesture-video/pats-crops/*.mp4",
    "gesture-video/tango-interviews/*.mp4",
    "talking-heads-misc/LatentSync/assets/*.mp4",
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "character_fit.json"))
    a = ap.parse_args()
    root = data_root()
    rows = []
    print("| clip | captured arm m | character arm m | error % | height m | other measures' errors % |")
    print("|---|---|---|---|---|---|")
    for pattern in CLIPS:
        for clip in sorted(glob.glob(str(root / pattern))):
            seq = capture_video(clip, CaptureConfig(max_frames=a.frames), progress=False)
            if seq.body_joints is None:
                continue
            m = tracked_measures(seq.body_joints)
            if "upper_arm" not in m or "forearm" not in m:
                rows.append({"clip": Path(clip).name, "arm": "not seen"})
                continue
            mo = character_motion(seq)
            fit = mo["report"]["shape_fit"]
            arm = m["upper_arm"] + m["forearm"]
            char = fit["upper_arm"]["character_m"] + fit["forearm"]["character_m"]
            row = {
                "clip": str(Path(clip).relative_to(root)),
                "frames": seq.n_frames,
                "captured_arm_m": round(arm, 4),
                "character_arm_m": round(char, 4),
                "arm_error_pct": round(100 * (char - arm) / arm, 2),
                "height_m": mo["report"]["height_m"],
                "measures": fit,
            }
            rows.append(row)
            others = ", ".join(
                f"{k} {v['error_pct']:+.1f}" for k, v in fit.items() if k not in ("upper_arm", "forearm")
            )
            print(
                f"| {row['clip']} | {arm:.3f} | {char:.3f} | {row['arm_error_pct']:+.1f} | {row['height_m']:.2f} | "
                f"{others} |",
                flush=True,
            )
    errs = [abs(r["arm_error_pct"]) for r in rows if "arm_error_pct" in r]
    summary = {"clips": len(rows), "within_10pct": sum(e <= 10 for e in errs), "max_abs_error_pct": max(errs)}
    print(summary)
    write_json(a.out, {"frames_per_clip": a.frames, "summary": summary, "rows": rows})


if __name__ == "__main__":
    main()
