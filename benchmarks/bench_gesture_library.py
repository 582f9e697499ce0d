"""Gestures from a motion library, before and after the stroke placement (and the library variants): beat
consistency, strokes on stressed syllables, FGD, loops. Two libraries: the built-in one, and one baked with
`anima library build` from the shared research clips (gesture-video/pats-crops and gesture-video/tango-interviews),
searched **leave-one-speaker-out**: each speaker's speech is gestured with a library built without that speaker
(the speakers are the PATS / TANGO names in the file names, `anima.eval.gesture.metrics.speaker_of`). The built-in
library holds none of these speakers. Writes benchmarks/results/gesture_library.json.

    python benchmarks/bench_gesture_library.py [--library /tmp/anima_research_library.npz]

The research library is baked once into --library (TV footage and CC BY-NC clips: kept out of the repository) and
reused while its sources' sha256 match. Rows, per library (each the command's behaviour with those settings):

* before: the search as it was (no variants, no-repeat 4 s, no stroke rank, no re-timing);
* variants: + the library's mirrored and speed-varied windows and the library's no-repeat span;
* variants + stroke rank: + the stroke rank in the search (weight 3);
* after (the command now): + re-timing by up to 2 frames so strokes meet stresses.

Per output (15 fps): beat consistency (`anima.eval.gesture.metrics.beat_consistency`: motion beats, the wrists'
speed minima, against the audio onsets; Li et al. 2021), the strokes against the stresses
(`anima.gesture.strokes.alignment`), jerk, wrist motion; FGD per held-out speaker with captured windows (an
autoencoder trained on the other speakers' captured windows, distances of its per-step codes: a few windows each;
window-weighted mean); loops on a 60-s speech outside both libraries (talking-heads-extra/pose_source2.mp4): the
share of 8-frame steps replaying source motion output in the previous 20 s (a mirrored copy counted as its source,
and apart).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from anima.audio.features import read_audio, speech_features  # noqa: E402
from anima.audio.stress import find_stresses  # noqa: E402
from anima.eval.gesture.metrics import (  # noqa: E402
    audio_onsets,
    beat_consistency,
    bootstrap_over_groups,
    jerk,
    replayed,
    speaker_of,
    wrist_motion,
)
from anima.gesture.config import GestureConfig  # noqa: E402
from anima.gesture.database import distinct_seconds, from_library, with_variants  # noqa: E402
from anima.gesture.knn import MatchDB  # noqa: E402
from anima.gesture.run import SEED_SEARCH, library_no_repeat_s, synthesize  # noqa: E402
from anima.gesture.strokes import alignment  # noqa: E402
from anima.io.assets import data_root  # noqa: E402
from anima.io.atomic import write_json  # noqa: E402
from anima.io.outdir import sha256  # noqa: E402

FPS = 15.0  # contract: not (the gesture search's rate, checked against the library below)
FOLDERS = ["gesture-video/pats-crops", "gesture-video/tango-interviews"]
LONG_SPEECH = "talking-heads-extra/pose_source2.mp4"
CFG = GestureConfig()
CONDITIONS = {
    "before": dict(variants=False, stroke_rank=0.0, stroke_shift=0.0, library_no_repeat=False),
    "variants": dict(variants=True, stroke_rank=0.0, stroke_shift=0.0, library_no_repeat=True),
    "variants + stroke rank": dict(
        variants=True, stroke_rank=CFG.stroke_rank, stroke_shift=0.0, library_no_repeat=True
    ),
    "after": dict(variants=True, stroke_rank=CFG.stroke_rank, stroke_shift=CFG.stroke_shift, library_no_repeat=True),
}


def research_clips(root: Path) -> list[Path]:
    return sorted(p for f in FOLDERS for p in (root / f).glob("*.mp4"))


def bake(clips: list[Path], path: Path) -> dict:
    """The research library at ``path``: reused when its sources are these clips (same sha256), else baked with
    the command's function (``anima library build``). Returns how it was made: baked now or reused, the seconds and
    frames of its bake (kept beside it, ``path`` + ``.bake.json``, so a rerun reports the bake it reuses)."""
    from anima.library import builtin

    want = {str(c.resolve()): sha256(c) for c in clips}
    note = Path(str(path) + ".bake.json")
    if path.is_file() and note.is_file():
        try:
            have = {s["path"]: s["sha256"] for s in builtin.load(path).provenance.get("sources", [])}
            if have == want:
                return json.loads(note.read_text()) | {"bake": "reused (same sources)"}
        except Exception:
            pass
    from anima.gesture.library import build

    t = time.perf_counter()
    prov = build([str(c) for c in clips], path, progress=True, command="benchmarks/bench_gesture_library.py")
    seconds = time.perf_counter() - t
    frames = sum(s["frames_captured"] for s in prov["sources"])
    info = {
        "bake_s": round(seconds, 1),
        "frames": frames,
        "video_s": round(sum(s["seconds"] for s in prov["sources"]), 1),
        "frames_per_s": round(frames / seconds, 1),
        "cpus": os.cpu_count(),
    }
    write_json(note, info)
    return info | {"bake": "baked now"}


def no_repeat_for(db: MatchDB, library_rule: bool) -> float:
    return library_no_repeat_s(db, CFG.no_repeat_s) if library_rule else CFG.no_repeat_s


def gestures(speech: str, db: MatchDB, cond: dict) -> tuple[np.ndarray, dict]:
    cfg = replace(SEED_SEARCH, no_repeat_s=no_repeat_for(db, cond["library_no_repeat"]),
                  stroke_rank=cond["stroke_rank"], stroke_shift=cond["stroke_shift"])  # fmt: skip
    return synthesize(speech, db, cfg)


def windows_of(J: np.ndarray, T: int = 64, hop: int = 32) -> np.ndarray:
    return (
        np.stack([J[s : s + T] for s in range(0, len(J) - T + 1, hop)])
        if len(J) >= T
        else np.zeros((0, T) + J.shape[1:])
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--library", default=os.path.join(os.environ.get("TMPDIR", "/tmp"), "anima_research_library.npz"))
    ap.add_argument("--fgd-steps", type=int, default=1500)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "gesture_library.json"))
    a = ap.parse_args()
    import torch

    torch.set_num_threads(1)  # the autoencoders are small: one thread is many times faster on a busy machine
    from anima.eval.gesture.fgd import train_fgd

    t_all = time.perf_counter()
    root = data_root().resolve()
    clips = research_clips(root)
    made = bake(clips, Path(a.library))
    research = from_library(a.library, variants=False)
    builtin_db = from_library(None, variants=False)
    assert abs(research.fps - FPS) < 1e-9 and abs(builtin_db.fps - FPS) < 1e-9
    r_speaker = np.array([speaker_of(s) for s, _ in research.source])
    speakers = sorted({speaker_of(str(c)) for c in clips})
    prep = {}
    for c in clips:
        x = read_audio(c)
        prep[c] = {
            "stress": find_stresses(x).times_s,
            "onsets": audio_onsets(speech_features(x, FPS).features, FPS),
            "seconds": len(x) / 16000,
        }
    rows = defaultdict(lambda: defaultdict(list))  # (library, condition) -> metric -> values (one per clip)
    fgd = defaultdict(lambda: defaultdict(dict))  # (library, condition) -> speaker -> (distance, windows)
    fold_info = {}
    for sp in speakers:
        own = [c for c in clips if speaker_of(str(c)) == sp]
        rest = np.flatnonzero(r_speaker != sp)
        libs = {
            "built-in": {False: builtin_db, True: with_variants(builtin_db)},
            "research, leave-one-speaker-out": {
                False: research.subset(rest),
                True: with_variants(research.subset(rest)),
            },
        }
        real = research.G[r_speaker == sp]
        fold_info[sp] = {
            "clips": len(own),
            "speech_s": round(sum(prep[c]["seconds"] for c in own), 1),
            "research_library_windows_without_speaker": int(len(rest)),
            "research_library_s_without_speaker": round(distinct_seconds(research.subset(rest)), 1),
            "captured_windows_of_speaker": int(len(real)),
        }
        aes = []  # two feature networks (seeds 0 and 1): how far FGD moves with the network alone
        if len(real) and len(rest):
            aes = [train_fgd(research.G[rest], steps=a.fgd_steps, seed=seed) for seed in (0, 1)]
        for lib, dbs in libs.items():
            for name, cond in CONDITIONS.items():
                gen = []
                for c in own:
                    J, _ = gestures(str(c), dbs[cond["variants"]], cond)
                    p = prep[c]
                    al = alignment(J, p["stress"], FPS)
                    r = rows[lib, name]
                    r["beat_consistency"].append(beat_consistency(J, p["onsets"], FPS))
                    r["stress_to_stroke_s"].append(al["stress_to_stroke_s"])
                    r["stresses_hit"].append(al.get("stresses_hit", np.nan))
                    r["strokes_on_stress"].append(al.get("strokes_on_stress", np.nan))
                    r["strokes_per_s"].append(al["strokes_per_s"])
                    r["jerk"].append(jerk(J, FPS))
                    r["wrist_motion_cm"].append(wrist_motion(J))
                    r["seconds"].append(p["seconds"])
                    r["stresses"].append(al["stresses"])
                    r["speaker"].append(sp)
                    gen.append(windows_of(J.reshape(len(J), -1)))
                gen = np.concatenate(gen) if gen else np.zeros((0, 64, 165))
                if aes and len(gen):
                    d0, d1 = (ae.frame_distance(real, gen) for ae in aes)
                    fgd[lib, name][sp] = (d0, int(len(real)), int(len(gen)), d1)
        print(f"{sp}: {fold_info[sp]}", flush=True)
    out_rows = {}
    for (lib, name), r in rows.items():
        w = np.array(r["seconds"])
        row = {
            k: round(float(np.average(np.nan_to_num(np.array(r[k]), nan=0.0), weights=w)), 4)
            for k in ("beat_consistency", "stress_to_stroke_s", "stresses_hit", "strokes_on_stress", "strokes_per_s",
                      "jerk", "wrist_motion_cm")
        }  # fmt: skip
        f = fgd[lib, name]
        nreal = sum(v[1] for v in f.values())
        row["fgd"] = round(sum(v[0] * v[1] for v in f.values()) / nreal, 3) if nreal else None
        row["fgd_feature_seed_1"] = round(sum(v[3] * v[1] for v in f.values()) / nreal, 3) if nreal else None
        row["fgd_real_windows"] = nreal
        row["fgd_speakers"] = {
            s: {"fgd": round(v[0], 3), "real_windows": v[1], "generated_windows": v[2]} for s, v in f.items()
        }
        row["clips"] = len(w)
        row["speakers"] = len(set(r["speaker"]))
        row["speech_s"] = round(float(w.sum()), 1)
        row["stresses"] = int(sum(r["stresses"]))
        if name != "before":  # paired with "before", clip by clip: 95 % over speakers (whole speakers resampled)
            b = rows[lib, "before"]
            groups = np.array(r["speaker"])
            row["change_vs_before_ci95_over_speakers"] = {
                k: [round(v, 4) for v in bootstrap_over_groups(np.nan_to_num(np.array(r[k]) - np.array(b[k])), groups)]
                for k in ("beat_consistency", "stress_to_stroke_s", "stresses_hit")
            }
        out_rows.setdefault(lib, {})[name] = row
    table = []  # the rows as one table (docs/gesture.md renders it with tools/doc_tables.py)
    for lib, rr in out_rows.items():
        for name, row in rr.items():
            ci = row.get("change_vs_before_ci95_over_speakers", {})
            table.append(
                {
                    "library": lib,
                    "search": name,
                    "speakers": row["speakers"],
                    "speech_s": row["speech_s"],
                    "stresses": row["stresses"],
                    "beat_consistency": round(row["beat_consistency"], 3),
                    "stress_to_stroke_s": round(row["stress_to_stroke_s"], 3),
                    "stresses_hit": round(row["stresses_hit"], 2),
                    "strokes_per_s": round(row["strokes_per_s"], 2),
                    "jerk": round(row["jerk"], 1),
                    "fgd": None if row["fgd"] is None else round(row["fgd"], 2),
                    "fgd_feature_seed_1": None
                    if row["fgd_feature_seed_1"] is None
                    else round(row["fgd_feature_seed_1"], 2),
                    "fgd_real_windows": row["fgd_real_windows"],
                    "hit_change_ci95": "[{:.2f}, {:.2f}]".format(*ci["stresses_hit"]) if ci else None,
                    "bc_change_ci95": "[{:.3f}, {:.3f}]".format(*ci["beat_consistency"]) if ci else None,
                }
            )
    # loops on a long speech outside both libraries
    long_speech = str(root / LONG_SPEECH)
    loops = {}
    for lib, db in (("built-in", builtin_db), ("research, all speakers", research)):
        for name in ("before", "after"):
            cond = CONDITIONS[name]
            d = with_variants(db) if cond["variants"] else db
            J, info = gestures(long_speech, d, cond)
            picks = info["picks"]
            loops.setdefault(lib, {})[name] = {
                "replayed_within_20_s": round(replayed(d.source, d.rate, picks, FPS, 8, 20.0, fold_mirror=True), 3),
                "replayed_within_20_s_mirror_apart": round(replayed(d.source, d.rate, picks, FPS, 8, 20.0, False), 3),
                "distinct_windows_used": len({m for m, _ in picks}),
                "database_windows": int(d.M),
                "no_repeat_s": round(no_repeat_for(d, cond["library_no_repeat"]), 2),
                "stresses_hit": round(
                    alignment(J, find_stresses(read_audio(long_speech)).times_s, FPS)["stresses_hit"], 3
                ),
            }
    res = {
        "what": "gestures from a motion library for unseen speakers' speech, before/after the stroke placement "
        "(15 fps; means over clips weighted by their seconds)",
        "protocol": "leave-one-speaker-out: each research speaker's clips gestured from the research library less "
        "that speaker; the built-in library holds none of them",
        "research_library": {
            "path": a.library,
            **made,
            "videos": len(clips),
            "windows": int(research.M),
            "distinct_s": round(distinct_seconds(research), 1),
            "speakers_with_windows": sorted(set(r_speaker.tolist())),
        },
        "builtin_library": {"windows": int(builtin_db.M), "distinct_s": round(distinct_seconds(builtin_db), 1)},
        "speakers": fold_info,
        "speech": {
            "clips": len(clips),
            "speakers": len(speakers),
            "seconds": round(sum(p["seconds"] for p in prep.values()), 1),
        },
        "settings": {"stroke_rank": CFG.stroke_rank, "stroke_shift_frames": CFG.stroke_shift, "fgd_steps": a.fgd_steps},
        "rows": out_rows,
        "table": table,
        "loops_60s_speech": {"speech": LONG_SPEECH, **loops},
        "wall_s": round(time.perf_counter() - t_all, 1),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
        "when": time.strftime("%Y-%m-%d %H:%M"),
    }
    write_json(a.out, res)
    for lib, rr in out_rows.items():
        for name, row in rr.items():
            print(f"{lib:34s} {name:24s} BC {row['beat_consistency']:.3f}  stress->stroke "
                  f"{row['stress_to_stroke_s']:.3f} s  hit {row['stresses_hit']:.2f}  FGD {row['fgd']}  "
                  f"jerk {row['jerk']:.1f}")  # fmt: skip
    print(json.dumps(loops, indent=1))
    print(f"wrote {a.out} in {res['wall_s']} s")


if __name__ == "__main__":
    main()
