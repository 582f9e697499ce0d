"""Import CelebV-Text style attribute annotations.

Accepted JSON (one file for many videos; unknown keys are ignored)::

    {
      "schema": "celebvtext-actions/1",                  (optional)
      "clips": {
        "<video file stem>": {
          "gender": "female" | "male" | null,             (optional; else neutral subject words)
          "actions":  [{"name": "talk",  "start": 0.0, "end": 5.2}, ...],   seconds
          "emotions": [{"name": "happy", "start": 1.0, "end": 3.0}, ...]
        }
      }
    }

CelebV-Text's own per-clip lists ``[[name, start, end], ...]`` under "actions"/"emotions" are accepted too.
:func:`load_annotations` validates and raises :class:`InputError` naming the first problem.
"""

from __future__ import annotations

import math
from pathlib import Path

from anima.errors import InputError
from anima.io.validate import read_json

CREMA_D = {"ANG": "angry", "DIS": "disgusted", "FEA": "fearful", "HAP": "happy", "NEU": "neutral", "SAD": "sad"}
MEAD = {
    "angry": "angry",
    "contempt": "contempt",
    "disgusted": "disgusted",
    "fear": "fearful",
    "happy": "happy",
    "neutral": "neutral",
    "sad": "sad",
    "surprised": "surprised",
}
STYLE_WORDS = {"furious": "angry", "sad": "sad", "surprise": "surprised", "happy": "happy"}


def emotion_from_path(path: str | Path) -> str | None:
    """The emotion an emotion clip's file name states, else None: CREMA-D's ``<actor>_<sentence>_<EMO>_<level>``
    codes, MEAD's emotion-named crops (``emotion-clips/eamm-mead/fear.mp4``), and StyleTalk's style clips
    named by their emotion (``furious_talk1_clip1``, ``sadgirl_clip1``, ``vscodehappy_clip1``)."""
    p = Path(path)
    stem = p.stem
    parts = stem.split("_")
    if len(parts) == 4 and parts[0].isdigit() and parts[2] in CREMA_D:
        return CREMA_D[parts[2]]
    if "emotion-clips" in p.parts and stem.lower() in MEAD:
        return MEAD[stem.lower()]
    if "style_clips" in p.parts:
        low = stem.lower()
        for w, emo in STYLE_WORDS.items():
            if w in low:
                return emo
    return None


def _events(items, where: str) -> list[tuple[str, float, float]]:
    out = []
    if not isinstance(items, list):
        raise InputError(f"{where}: expected a list of events")
    for k, it in enumerate(items):
        if isinstance(it, dict):
            name, s, e = it.get("name"), it.get("start"), it.get("end")
        elif isinstance(it, (list, tuple)) and len(it) == 3:
            name, s, e = it
        else:
            raise InputError(f"{where}[{k}]: expected {{name, start, end}} or [name, start, end]")
        try:
            s, e = float(s), float(e)
        except (TypeError, ValueError):
            raise InputError(f"{where}[{k}]: start/end must be numbers (seconds)") from None
        if not (math.isfinite(s) and math.isfinite(e)):
            raise InputError(f"{where}[{k}]: start/end must be finite numbers (seconds)")
        if not isinstance(name, str) or not name or e <= s or s < 0:
            raise InputError(f"{where}[{k}]: need a name and 0 <= start < end")
        out.append((name.lower(), s, e))
    return out


def load_annotations(path: str | Path, known_videos: list[str] | None = None) -> dict[str, dict]:
    """``{video stem: {"gender": ..., "events": [(name, start, end), ...]}}``."""
    path = Path(path)
    data = read_json(path, "annotation file")
    clips = data.get("clips") if isinstance(data, dict) else None
    if not isinstance(clips, dict):
        raise InputError(f"{path}: expected an object with a 'clips' mapping (see anima/dataset/annotations.py)")
    out = {}
    for stem, c in clips.items():
        if not isinstance(c, dict):
            raise InputError(f"{path}: clip {stem!r} must be an object")
        ev = _events(c.get("actions", []), f"{path}: {stem}.actions") + _events(
            c.get("emotions", []), f"{path}: {stem}.emotions"
        )
        g = c.get("gender")
        if g not in (None, "female", "male"):
            raise InputError(f"{path}: {stem}.gender must be 'female', 'male' or null")
        out[stem] = {"gender": g, "events": sorted(ev, key=lambda x: x[1])}
    if known_videos is not None:
        unknown = sorted(set(out) - set(known_videos))
        if unknown:
            raise InputError(
                f"{path}: annotations name clips that are not among the videos: {unknown[:5]}"
                + (" ..." if len(unknown) > 5 else "")
            )
    return out
