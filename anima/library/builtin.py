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

A user's own library (``anima library build``) has the same arrays; it is a folder (``library.npz`` with its
provenance ``library.json`` beside it) or a single ``.npz``. Every library also holds its provenance as the
``provenance`` member (JSON), so a single file says where it came from; :func:`resolve` turns a ``--library``
argument into the ``.npz`` to read.
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
FOLDER_FILE = "library.npz"  # the library in a folder written by `anima library build`
MEMBERS = ("version", "face_motion", "gesture_F")  # what makes an npz a motion library (anima.io.owned.npz)


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
    sidecar: bool = True,
) -> tuple[Path, Path | None]:
    """Write the library (``path``, ``.npz``, its provenance inside) and, with ``sidecar``, its provenance with
    the file's size beside it (``path`` with ``.json``), each atomically."""
    path = Path(path)
    start = np.concatenate([[0], np.cumsum([len(m) for m in face_motion])]).astype(np.int64)
    arrays = {
        "version": np.int64(VERSION),
        "face_motion": np.concatenate([np.zeros((0, FACE_DIM)), *face_motion]).astype(np.float16),
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
        "provenance": np.str_(json.dumps(dict(provenance) | {"version": VERSION})),
    }
    for k, v in (speech_face or {}).items():
        arrays[f"speech_face_{k}"] = np.asarray(v)
    npz = write_npz(path, **arrays)
    if not sidecar:
        return npz, None
    meta = dict(provenance) | {"version": VERSION, "size_bytes": npz.stat().st_size}
    return npz, write_json(path.with_suffix(".json"), meta)


def available() -> bool:
    return LIBRARY.is_file()


def resolve(library: str | Path | None) -> Path:
    """The ``.npz`` of a ``--library`` argument: a folder from ``anima library build`` (its ``library.npz``) or
    a library file; None: the built-in library. Anything else is an :class:`InputError`."""
    if library is None:
        return LIBRARY
    p = Path(library)
    if p.is_dir():
        if not (p / FOLDER_FILE).is_file():
            raise InputError(f"--library {p}: not a motion library folder (no {FOLDER_FILE}; `anima library build`)")
        return p / FOLDER_FILE
    if not p.exists():
        raise InputError(f"--library {p}: no such file or folder")
    if p.suffix.lower() != ".npz":
        raise InputError(f"--library {p}: expected a folder or .npz from `anima library build`")
    return p


@lru_cache(maxsize=4)
def load(path: str | Path = LIBRARY) -> Builtin:
    """The library at ``path`` (default: the one anima ships). A missing or unreadable file is an
    :class:`InputError` saying how to get one (``--db``, or ``tools/bake_library.py``)."""
    path = Path(path)
    if not path.is_file():
        if path != LIBRARY:
            raise InputError(f"no motion library at {path}: make one with `anima library build`")
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
        if prov_path.is_file():
            provenance = json.loads(prov_path.read_text())
        else:
            provenance = json.loads(str(a["provenance"])) if "provenance" in a else {}
    except (OSError, ValueError, KeyError) as e:
        what = "the built-in motion library" if path == LIBRARY else "the motion library"
        raise InputError(f"{what} {path} is unreadable ({e}): bake it again") from None
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
    """One line for ``info.json`` and notes: what the library (default: the built-in one) holds."""
    b = load(path)
    p = b.provenance
    if Path(path) != LIBRARY:
        return (
            f"the motion library {path} ({len(b.face_clip)} face clips, {len(b.gesture_source)} gesture windows "
            f"from {p.get('videos', '?')} videos, {p.get('gesture_seconds_distinct', '?')} s of gesture; "
            f"made by {p.get('baked_with', '?')})"
        )
    return (
        f"the built-in motion library ({len(b.face_clip)} face clips, {len(b.gesture_source)} gesture windows "
        f"from {p.get('videos', '?')} videos of the shared data's train split; docs/library.md)"
    )
