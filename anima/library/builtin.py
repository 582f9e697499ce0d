"""The built-in motion library: what ``anima text2face PROMPT`` and ``anima gesture SPEECH`` use when no
``--db`` is given. One writer (:func:`write_library`, used by ``tools/bake_library.py``) and one reader
(:func:`load`) of ``anima/library/data/builtin.npz`` and its provenance ``builtin.json``.

Arrays (``np.load``, no pickles):

* ``face_motion [sum F, 56]`` float16: the (text, motion) clips' expression weights and head rotation at the
  text rate, one after another; ``face_start [C + 1]`` int64 the clip boundaries; ``face_events`` a JSON list
  (per clip) of ``[attribute, start_s, end_s]``; ``face_clip`` the clips' names;
* ``gesture_F``, ``gesture_P``, ``gesture_G``, ``gesture_S``: the k-NN matching database's audio features,
  pose features, joints and speech features per (audio, motion) window
  (:class:`anima.gesture.knn.MatchDB`); ``gesture_source`` a JSON list of ``[window source, start_s]``;
  ``gesture_fps``;
* ``speech_face_*``: the talking face's mouth model (:func:`anima.gesture.face.fit_speech_face`).

``builtin.json`` lists every source video (its path under the data root, licence, sha256), the dataset
build that made the arrays, and the install size.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from anima.core.contract import FACE_DIM
from anima.errors import InputError
from anima.io.atomic import write_json, write_npz

DATA = Path(__file__).parent / "data"
LIBRARY = DATA / "builtin.npz"
PROVENANCE = DATA / "builtin.json"
VERSION = 1


@dataclass
class Builtin:
    """The library's arrays (see the module docstring), read once per process."""

    face_motion: list[np.ndarray]
    face_events: list[list[tuple[str, float, float]]]
    face_clip: list[str]
    face_fps: float
    gesture: dict[str, np.ndarray]
    gesture_source: list[tuple[str, float]]
    gesture_fps: float
    speech_face: dict[str, np.ndarray] | None
    provenance: dict


def write_library(
    path: str | Path,
    face_motion: list[np.ndarray],
    face_events: list[list],
    face_clip: list[str],
    face_fps: float,
    gesture: dict[str, np.ndarray],
    gesture_source: list[tuple[str, float]],
    gesture_fps: float,
    speech_face: dict[str, np.ndarray] | None,
    provenance: dict,
) -> tuple[Path, Path]:
    """Write the library (``path``, ``.npz``) and its provenance (``path`` with ``.json``), each atomically."""
    path = Path(path)
    start = np.concatenate([[0], np.cumsum([len(m) for m in face_motion])]).astype(np.int64)
    arrays = {
        "version": np.int64(VERSION),
        "face_motion": np.concatenate(face_motion).astype(np.float16),
        "face_start": start,
        "face_events": np.str_(json.dumps(face_events)),
        "face_clip": np.array(face_clip, dtype=str),
        "face_fps": np.float64(face_fps),
        "gesture_F": gesture["F"].astype(np.float32),
        "gesture_P": gesture["P"].astype(np.float32),
        "gesture_G": gesture["G"].astype(np.float16),
        "gesture_S": gesture["S"].astype(np.float16),
        "gesture_source": np.str_(json.dumps(gesture_source)),
        "gesture_fps": np.float64(gesture_fps),
    }
    for k, v in (speech_face or {}).items():
        arrays[f"speech_face_{k}"] = np.asarray(v)
    npz = write_npz(path, **arrays)
    meta = dict(provenance) | {"version": VERSION, "size_bytes": npz.stat().st_size}
    return npz, write_json(path.with_suffix(".json"), meta)


def available() -> bool:
    return LIBRARY.is_file()


@lru_cache(maxsize=2)
def load(path: str | Path = LIBRARY) -> Builtin:
    """The library at ``path`` (default: the one anima ships). A missing or unreadable file is an
    :class:`InputError` saying how to get one (``--db``, or ``tools/bake_library.py``)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(
            f"no built-in motion library at {path}: give --db DATASET (a folder from `anima dataset build`), "
            "or bake one with tools/bake_library.py"
        )
    try:
        with np.load(path, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
        if int(a["version"]) != VERSION:
            raise ValueError(f"version {int(a['version'])}, expected {VERSION}")
        motion = a["face_motion"].astype(np.float32)
        start = a["face_start"]
        if motion.ndim != 2 or motion.shape[1] != FACE_DIM or start[-1] != len(motion):
            raise ValueError("face_motion does not match the face contract")
        prov_path = path.with_suffix(".json")
        provenance = json.loads(prov_path.read_text()) if prov_path.is_file() else {}
    except (OSError, ValueError, KeyError) as e:
        raise InputError(f"the built-in motion library {path} is unreadable ({e}): bake it again") from None
    sf = {k[len("speech_face_") :]: v for k, v in a.items() if k.startswith("speech_face_")}
    return Builtin(
        face_motion=[motion[start[i] : start[i + 1]] for i in range(len(start) - 1)],
        face_events=[[(str(x), float(s), float(e)) for x, s, e in ev] for ev in json.loads(str(a["face_events"]))],
        face_clip=[str(c) for c in a["face_clip"]],
        face_fps=float(a["face_fps"]),
        gesture={k: a[f"gesture_{k}"].astype(np.float32) for k in "FPGS"},
        gesture_source=[(str(s), float(t)) for s, t in json.loads(str(a["gesture_source"]))],
        gesture_fps=float(a["gesture_fps"]),
        speech_face=sf or None,
        provenance=provenance,
    )


def summary(path: str | Path = LIBRARY) -> str:
    """One line for ``info.json`` and notes: what the built-in library holds."""
    b = load(path)
    p = b.provenance
    return (
        f"the built-in motion library ({len(b.face_clip)} face clips, {len(b.gesture_source)} gesture windows "
        f"from {p.get('videos', '?')} videos of the shared data's train split; docs/library.md)"
    )
