"""Does ``anima capture --neutral`` keep a clip-long expression?

    python benchmarks/neutral_reference.py    # writes benchmarks/results/neutral_reference.json (about a minute)

**Clips**: CREMA-D's actor 1001, sentence DFA, six 2-s takes (angry, disgusted, fearful, happy, neutral, sad;
development data: the same clips the annotation evaluation's capture check reads), captured with the shipped
defaults (``anima capture``, no videos).

**Compared**: the character's 53 weights (:func:`anima.export.avatar.character_face`, what every animation
shows, its lids and lips set from the capture's landmarks) with each take's rest face estimated from the take
itself (the default) and with the neutral take given as ``--neutral``
(:func:`anima.capture.run.neutral_reference` on its ``capture.npz``). Per take, clip means over the tracked
frames; the checks are those of ``anima eval annotations``' ``capture_emotions`` (each emotion's weight above
the neutral take's), applied to the character's weights instead of the raw fit.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from anima.capture.config import CaptureConfig
from anima.capture.run import neutral_reference, run
from anima.core.contract import EXPR_NAMES
from anima.export.avatar import character_face
from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.sequence import read_sequence

CLIP = "emotion-clips/crema-d/1001_DFA_{}_XX.flv"
TAKES = {"angry": "ANG", "disgusted": "DIS", "fearful": "FEA", "happy": "HAP", "neutral": "NEU", "sad": "SAD"}
CHECKS = [("angry", "browDown"), ("angry", "noseSneer"), ("disgusted", "browDown"), ("disgusted", "noseSneer"),
          ("fearful", "browInnerUp"), ("fearful", "eyeWide"), ("happy", "mouthSmile"), ("sad", "browInnerUp"),
          ("sad", "mouthFrown")]  # fmt: skip


def clip_mean(seq, base: str) -> float:
    """The character's ``base`` weight (both sides), meaned over the tracked frames."""
    k = [i for i, n in enumerate(EXPR_NAMES) if n.startswith(base + "_") or n == base]
    return float(character_face(seq)[seq.tracked][:, k].mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "neutral_reference.json"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        seqs = {}
        for name, code in TAKES.items():
            run(str(asset(CLIP.format(code))), Path(tmp) / name, CaptureConfig(), render=False, progress=False)
            seqs[name] = read_sequence(Path(tmp) / name / "capture.npz")  # its landmarks: the lids and lips
        rest = neutral_reference(str(Path(tmp) / "neutral" / "capture.npz"), CaptureConfig(), progress=False)
    means = {}
    for how in ("own", "neutral_take"):
        for name, seq in seqs.items():
            seq.meta.pop("rest_face", None)
            if how == "neutral_take":  # as `anima capture ... --neutral neutral/capture.npz` stores it
                seq.meta["rest_face"] = {"channels": rest, "from": "neutral/capture.npz"}
            bases = {b for _, b in CHECKS} | {"mouthSmile", "browDown"}
            means[(how, name)] = {b: round(clip_mean(seq, b), 4) for b in sorted(bases)}
    out = {"protocol": "benchmarks/neutral_reference.py docstring", "rest_face": rest, "checks": [], "held": {}}
    for how in ("own", "neutral_take"):
        held = 0
        for emo, b in CHECKS:
            c, n = means[(how, emo)][b], means[(how, "neutral")][b]
            out["checks"].append({"rest": how, "emotion": emo, "weight": b, "clip": c, "neutral": n, "holds": c > n})
            held += c > n
        out["held"][how] = held
        out[f"neutral_take_{how}"] = {b: means[(how, "neutral")][b] for b in ("mouthSmile", "browDown")}
        out[f"angry_browDown_{how}"] = means[(how, "angry")]["browDown"]
    out["data"] = "CREMA-D actor 1001, sentence DFA: six 2-s takes (development data)"
    print(json.dumps(out, indent=1))
    write_json(a.out, out)


if __name__ == "__main__":
    main()
