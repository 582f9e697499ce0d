"""Do the exported face weights keep acted emotions? A FACS reading of ``arkit.csv`` on labelled emotion clips.

    python benchmarks/emotion_facs.py   # writes benchmarks/results/emotion_facs.json (about a minute on 2 cores)
    python benchmarks/emotion_facs.py --work /tmp/emotion_facs --fresh   # capture again (e.g. after a fix)

**A development check, not a held-out test**: these clips have been looked at while building the face (CREMA-D's
six takes are development clips of ``face_readback.py`` and ``neutral_reference.py``; MEAD's were read back
once), and the numbers are few: CREMA-D is ONE actor (1001, one sentence, six 2-s takes: angry, disgusted,
fearful, happy, neutral, sad); MEAD (EAMM's test copies) is six face crops named contempt, disgusted, fear,
happy, sad, surprised, with NO neutral take. A score here says whether the exported weights carry an emotion a
FACS reader would recognise on these twelve clips, nothing more.

**Capture** as a user does: ``anima capture CLIP --out WORK/NAME --face-only --no-render`` (the shipped
defaults), cached under ``--work`` (an existing ``arkit.csv`` is reused unless ``--fresh``). The check reads
ONLY the exported ``arkit.csv`` (:func:`anima.io.arkit.read_live_link_csv`, Live Link's ARKit column names),
never anima's landmarks or fit: what a user gets.

**The FACS reading** (its constants below were fixed from the literature before any clip was scored, and are not
tuned on these clips):

* ARKit channel -> action unit: the usual ARKit/FACS correspondence (Apple's ARFaceAnchor.BlendShapeLocation
  descriptions, as tabulated in the ARKit-to-FACS cheat sheets used by animators): :data:`AU_CHANNELS`. A
  bilateral AU is the mean of its Left and Right channels, per frame; ``U12``/``U14`` (unilateral smile and
  dimple, contempt's) are ``|Left - Right|`` per frame.
* An AU's activation on a take: its clip mean minus the reference's, floored at 0. The reference is the same
  actor's neutral take where there is one (CREMA-D: NEU's clip mean); MEAD has no neutral take, so there the
  reference is the clip's own 10th percentile of that AU (what the face does above its own quietest frames: a
  held expression that never relaxes reads low this way). As a second reading, ``absolute``, the clip means
  themselves with no reference (anima's export already takes out the rest face it estimates).
* Emotion prototypes: Ekman & Friesen's EMFACS predictions as tabulated in the FACS literature (Ekman, Friesen &
  Hager 2002, FACS Investigator's Guide; the usual "emotion: AUs" table): happiness 6+12, sadness 1+4+15,
  surprise 1+2+5+26, fear 1+2+4+5+7+20+26, anger 4+5+7+23, disgust 9+15+16, contempt unilateral 12+14:
  :data:`PROTOTYPES`.
* Classification: each prototype's normalised match score is the cosine between the take's activation vector
  (every AU of :data:`AU_CHANNELS` plus U12, U14) and the prototype's 0/1 vector; the take gets the prototype with
  the best score. Chance: 1 in 7. The neutral take is the reference, so it is not classified (not counted).

Also reported: the smile channel (``mouthSmile``, clip mean, Left/Right averaged) of each CREMA-D take minus the
neutral take's (the complaint: it rises on angry, sad, fearful and disgusted faces), and the neutral take's
``mouthSmile`` and ``browDown`` clip means. Each of those rests on ONE actor's takes, one take each.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

import anima
from anima.io.arkit import read_live_link_csv
from anima.io.assets import asset
from anima.io.atomic import write_json

# ARKit channel (Live Link's column names) -> FACS action unit. The usual correspondence (Apple's blend-shape
# descriptions; ARKit-to-FACS tables): fixed before scoring any clip, not tuned on them.
AU_CHANNELS = {
    "AU1": ["BrowInnerUp"],  # inner brow raiser
    "AU2": ["BrowOuterUpLeft", "BrowOuterUpRight"],  # outer brow raiser
    "AU4": ["BrowDownLeft", "BrowDownRight"],  # brow lowerer
    "AU5": ["EyeWideLeft", "EyeWideRight"],  # upper lid raiser
    "AU6": ["CheekSquintLeft", "CheekSquintRight"],  # cheek raiser
    "AU7": ["EyeSquintLeft", "EyeSquintRight"],  # lid tightener
    "AU9": ["NoseSneerLeft", "NoseSneerRight"],  # nose wrinkler
    "AU10": ["MouthUpperUpLeft", "MouthUpperUpRight"],  # upper lip raiser
    "AU12": ["MouthSmileLeft", "MouthSmileRight"],  # lip corner puller
    "AU14": ["MouthDimpleLeft", "MouthDimpleRight"],  # dimpler
    "AU15": ["MouthFrownLeft", "MouthFrownRight"],  # lip corner depressor
    "AU16": ["MouthLowerDownLeft", "MouthLowerDownRight"],  # lower lip depressor
    "AU17": ["MouthShrugLower"],  # chin raiser
    "AU18": ["MouthPucker"],  # lip pucker
    "AU20": ["MouthStretchLeft", "MouthStretchRight"],  # lip stretcher
    "AU22": ["MouthFunnel"],  # lip funneler
    "AU23": ["MouthPressLeft", "MouthPressRight"],  # lip tightener / pressor (AU23/24: ARKit has one pair)
    "AU26": ["JawOpen"],  # jaw drop (AU25/26)
    "AU28": ["MouthRollLower", "MouthRollUpper"],  # lip suck
    "AU45": ["EyeBlinkLeft", "EyeBlinkRight"],  # blink / eyes closed (AU43/45)
}
UNILATERAL = {"U12": ("MouthSmileLeft", "MouthSmileRight"), "U14": ("MouthDimpleLeft", "MouthDimpleRight")}
FEATURES = list(AU_CHANNELS) + list(UNILATERAL)

# Ekman & Friesen's EMFACS prototypes (Ekman, Friesen & Hager 2002, FACS Investigator's Guide; the standard
# emotion -> AU table): fixed before scoring any clip, not tuned on them.
PROTOTYPES = {
    "happy": ["AU6", "AU12"],
    "sad": ["AU1", "AU4", "AU15"],
    "surprised": ["AU1", "AU2", "AU5", "AU26"],
    "fearful": ["AU1", "AU2", "AU4", "AU5", "AU7", "AU20", "AU26"],
    "angry": ["AU4", "AU5", "AU7", "AU23"],
    "disgusted": ["AU9", "AU15", "AU16"],
    "contempt": ["U12", "U14"],  # unilateral 12 + 14
}
MEAD_REF_PERCENTILE = 10  # the reference where a clip has no neutral take (MEAD): its own quietest 10 %

CREMA = "emotion-clips/crema-d/1001_DFA_{}_XX.flv"
MEAD = "emotion-clips/eamm-mead/{}.mp4"
# (set, name, clip, true label); label None: the set's neutral take (the reference, not classified)
CLIPS = [("crema-d", code, CREMA.format(code), label)
         for code, label in [("ANG", "angry"), ("DIS", "disgusted"), ("FEA", "fearful"), ("HAP", "happy"),
                             ("NEU", None), ("SAD", "sad")]] + \
        [("eamm-mead", name, MEAD.format(name), label)
         for name, label in [("contempt", "contempt"), ("disgusted", "disgusted"), ("fear", "fearful"),
                             ("happy", "happy"), ("sad", "sad"), ("surprised", "surprised")]]  # fmt: skip
NEGATIVE = ("angry", "sad", "fearful", "disgusted")  # where the smile must not rise above neutral's


def git(*args: str) -> str:
    return subprocess.run(["git", *args], capture_output=True, text=True, cwd=Path(__file__).parent).stdout.strip()


def capture(clip: str, out: Path, fresh: bool) -> Path:
    """``anima capture CLIP --out OUT --face-only --no-render`` (cached): the exported ``arkit.csv``."""
    csv = out / "arkit.csv"
    if csv.exists() and not fresh:
        return csv
    if out.exists():
        subprocess.run(["rm", "-rf", str(out)], check=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    exe = Path(sys.executable).parent / "anima"
    cmd = [str(exe), "capture", str(asset(clip)), "--out", str(out), "--face-only", "--no-render", "--quiet"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return csv


def frames_by_feature(csv: Path) -> dict[str, np.ndarray]:
    """Per-frame AU values read from the exported weights alone."""
    names, w = read_live_link_csv(csv)
    col = {n: w[:, i] for i, n in enumerate(names)}
    out = {au: np.mean([col[c] for c in chans], axis=0) for au, chans in AU_CHANNELS.items()}
    out.update({u: np.abs(col[a] - col[b]) for u, (a, b) in UNILATERAL.items()})
    out["mouthSmile"] = (col["MouthSmileLeft"] + col["MouthSmileRight"]) / 2
    out["browDown"] = (col["BrowDownLeft"] + col["BrowDownRight"]) / 2
    return out


def classify(act: dict[str, float]) -> tuple[str | None, dict[str, float]]:
    """Cosine of the activation vector with each prototype's 0/1 vector; the best prototype."""
    x = np.array([max(act[f], 0.0) for f in FEATURES])
    norm = float(np.linalg.norm(x))
    scores = {}
    for emo, aus in PROTOTYPES.items():
        p = np.array([1.0 if f in aus else 0.0 for f in FEATURES])
        scores[emo] = float(x @ p / (norm * np.linalg.norm(p))) if norm > 0 else 0.0
    best = max(scores, key=scores.get) if norm > 0 else None
    return best, scores


def key_aus(act: dict[str, float], n: int = 4) -> str:
    top = sorted(((v, f) for f, v in act.items() if v >= 0.01), reverse=True)[:n]
    return " ".join(f"{f}:{v:.2f}" for v, f in top) or "none"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", default="/tmp/anima_emotion_facs", help="capture cache (one folder per clip)")
    ap.add_argument("--fresh", action="store_true", help="capture again even where arkit.csv is cached")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "emotion_facs.json"))
    a = ap.parse_args()

    data = {}
    for s, name, clip, _ in CLIPS:
        data[(s, name)] = frames_by_feature(capture(clip, Path(a.work) / f"{s}_{name}", a.fresh))
    neutral = {s: name for s, name, _, label in CLIPS if label is None}

    rows, totals = [], {}
    for reading in ("reference", "absolute"):
        for s, name, _clip, label in CLIPS:
            fr = data[(s, name)]
            means = {f: float(fr[f].mean()) for f in FEATURES}
            if reading == "absolute":
                ref, ref_name = dict.fromkeys(FEATURES, 0.0), "none"
            elif s in neutral:
                ref = {f: float(data[(s, neutral[s])][f].mean()) for f in FEATURES}
                ref_name = f"{neutral[s]} take"
            else:
                ref = {f: float(np.percentile(fr[f], MEAD_REF_PERCENTILE)) for f in FEATURES}
                ref_name = f"own p{MEAD_REF_PERCENTILE}"
            act = {f: max(means[f] - ref[f], 0.0) for f in FEATURES}
            pred, scores = (None, {}) if label is None and reading == "reference" else classify(act)
            smile = float(fr["mouthSmile"].mean())
            smile_n = float(data[(s, neutral[s])]["mouthSmile"].mean()) if s in neutral else None
            row = {
                "reading": reading,
                "set": s,
                "clip": name,
                "frames": int(len(fr["AU1"])),
                "true": label or "neutral",
                "predicted": pred or ("(reference)" if label is None else "none"),
                "recognised": None if label is None else pred == label,
                "reference": ref_name,
                "scores": {k: round(v, 3) for k, v in scores.items()},
                "key_aus": key_aus(act),
                "mouthSmile": round(smile, 4),
                "browDown": round(float(fr["browDown"].mean()), 4),
                "smile_delta": None if smile_n is None or label is None else round(smile - smile_n, 4),
                "activation": {f: round(v, 4) for f, v in act.items()},
            }
            rows.append(row)
        scored = [r for r in rows if r["reading"] == reading and r["recognised"] is not None]
        totals[reading] = {
            "recognised": sum(r["recognised"] for r in scored),
            "n": len(scored),
            "chance": round(1 / len(PROTOTYPES), 3),
            "expected_by_chance": round(len(scored) / len(PROTOTYPES), 2),
            "by_set": {
                s: f"{sum(r['recognised'] for r in scored if r['set'] == s)} of {sum(r['set'] == s for r in scored)}"
                for s in dict.fromkeys(r["set"] for r in scored)
            },
        }
    main_rows = [r for r in rows if r["reading"] == "reference"]
    deltas = {r["true"]: r["smile_delta"] for r in main_rows if r["set"] == "crema-d" and r["true"] in NEGATIVE}
    nr = next(r for r in main_rows if r["set"] == "crema-d" and r["true"] == "neutral")
    out = {
        "protocol": "benchmarks/emotion_facs.py docstring (development check, not a held-out test)",
        "commit": git("rev-parse", "--short", "HEAD"),
        "anima_source": str(Path(anima.__file__).parent),
        "anima_uncommitted": git("status", "--porcelain", "--", str(Path(anima.__file__).parent)).splitlines(),
        "data": "CREMA-D actor 1001 (one actor, six 2-s takes incl. neutral) and six MEAD crops (no neutral take)",
        "au_channels": AU_CHANNELS,
        "unilateral": {k: list(v) for k, v in UNILATERAL.items()},
        "prototypes": PROTOTYPES,
        "mead_reference_percentile": MEAD_REF_PERCENTILE,
        "totals": totals,
        "smile_delta_vs_neutral": {
            "clips": deltas,
            "max": max(deltas.values()),
            "mean": round(float(np.mean(list(deltas.values()))), 4),
            "target": "<= 0.02 on each",
            "n": f"{len(deltas)} takes of one actor (CREMA-D 1001); MEAD has no neutral take",
        },
        "neutral": {
            "mouthSmile": nr["mouthSmile"],
            "browDown": nr["browDown"],
            "target": "< 0.1 each",
            "n": "one neutral take of one actor (CREMA-D 1001 NEU)",
        },
        "rows": main_rows,
        "rows_absolute": [r for r in rows if r["reading"] == "absolute"],
    }
    write_json(a.out, out)
    for r in rows:
        sc = " ".join(f"{k[:4]}={v:.2f}" for k, v in r["scores"].items())
        print(f"{r['reading'][:3]} {r['set']:9s} {r['clip']:9s} {r['true']:9s} -> {r['predicted']:11s} "
              f"dSmile={r['smile_delta']} {sc} | {r['key_aus']}")  # fmt: skip
    print(json.dumps({k: out[k] for k in ("totals", "smile_delta_vs_neutral", "neutral")}, indent=1))


if __name__ == "__main__":
    main()
