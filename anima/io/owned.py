"""Whether an existing file is one anima wrote, checked by its content (never by its name alone): the only
files a single-file output (``--out FILE``) may replace. One check per kind of file anima writes, each reading
a bounded head of the file and running nothing:

* glTF / GLB / VRM / VRM Animation: a binary glTF whose ``asset.generator`` is ``anima``;
* npz: a zip of ``.npy`` members holding the members of the named kind;
* checkpoints: a torch zip (``data.pkl``) of anima's envelope (``anima.io.checkpoint``);
* JSON: a document whose ``schema`` / ``kind`` field is the named one;
* a video: one whose record beside it (``OUT.json``, written by anima with the video) names its sha256.

These say what *kind* of file a path holds. The exports (``anima export``, ``anima retarget``) also keep a
record beside each file they write (``.NAME.anima.json``: its size and sha256, :func:`write_record`): a file
with a record is replaced only while the whole file still matches it (:func:`recorded`), so a CSV that began
as anima's and gained a user's lines is the user's. Text formats a person edits (CSV, BVH) and FBX are
replaced only with such a record. The record lives beside the file, never inside its format, so every other
reader reads the file as before.

:data:`BY_SUFFIX` maps an output's suffix to its default check (``anima.io.outdir.check_out_file``).
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import struct
import zipfile
from pathlib import Path

from anima.io.atomic import write_json
from anima.io.checkpoint import looks_like_checkpoint

_GLB = 0x46546C67


def gltf(path: Path) -> bool:
    """A binary glTF (``.glb``, ``.vrm``, ``.vrma``) whose ``asset.generator`` is anima's."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(20)
            if len(head) < 20 or struct.unpack("<I", head[:4])[0] != _GLB:
                return False
            n, kind = struct.unpack("<II", head[12:20])
            if kind != 0x4E4F534A or n > 64 * 2**20:
                return False
            doc = json.loads(fh.read(n))
    except (OSError, ValueError, RecursionError):
        return False
    asset = doc.get("asset") if isinstance(doc, dict) else None
    return isinstance(asset, dict) and str(asset.get("generator", "")).split(" ")[0] == "anima"


def npz(*members: str):
    """A check for an npz holding ``members`` (a zip of ``NAME.npy`` files)."""

    def check(path: Path) -> bool:
        try:
            with zipfile.ZipFile(path) as z:
                names = {n.removesuffix(".npy") for n in z.namelist()}
        except (OSError, zipfile.BadZipFile, ValueError, EOFError):
            return False
        return bool(members) and set(members) <= names

    return check


def checkpoint(path: Path) -> bool:
    """A torch checkpoint of anima's envelope (``anima.io.checkpoint``), without loading it."""
    return looks_like_checkpoint(path)


def json_kind(field: str, *values: str):
    """A check for a JSON document whose ``field`` is one of ``values``."""

    def check(path: Path) -> bool:
        try:
            if path.stat().st_size > 64 * 2**20:
                return False
            d = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError, RecursionError):
            return False
        return isinstance(d, dict) and d.get(field) in values

    return check


def record_of(video: Path) -> Path:
    """The record anima writes beside a single video it makes (``OUT.json``)."""
    return Path(video).with_suffix(".json")


def video(path: Path) -> bool:
    """A video anima wrote: its record beside it (``OUT.json``) is anima's and names this file's sha256."""
    rec = record_of(path)
    try:
        if rec.stat().st_size > 16 * 2**20:
            return False
        d = json.loads(rec.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return False
    want = d.get("video_sha256") if isinstance(d, dict) and str(d.get("schema", "")).startswith("anima.") else None
    return isinstance(want, str) and want == sha256(path)


RECORD_SCHEMA = "anima.file"


def record_path(path: str | Path) -> Path:
    """Where anima keeps the record of a single file it wrote: ``.NAME.anima.json`` beside it."""
    path = Path(path)
    return path.with_name(f".{path.name}.anima.json")


def read_record(path: str | Path) -> dict | None:
    """The record beside ``path`` when it is a regular file of anima's schema, else None."""
    rec = record_path(path)
    try:
        st = os.lstat(rec)
        if not stat.S_ISREG(st.st_mode) or st.st_size > 1 << 16:
            return None
        d = json.loads(rec.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return None
    return d if isinstance(d, dict) and d.get("schema") == RECORD_SCHEMA else None


def recorded(path: str | Path) -> bool:
    """Whether ``path`` is, to the byte, the file anima last wrote there (its sha256 as recorded beside it)."""
    d = read_record(path)
    try:
        return d is not None and d.get("bytes") == Path(path).stat().st_size and d.get("sha256") == sha256(path)
    except OSError:
        return False


def write_record(path: str | Path, kind: str | None = None) -> Path:
    """Record, beside the file anima has just written at ``path``, its size and sha256 (atomic)."""
    path = Path(path)
    doc = {"schema": RECORD_SCHEMA, "version": 1, "file": path.name, "kind": kind, "bytes": path.stat().st_size,
           "sha256": sha256(path)}  # fmt: skip
    return write_json(record_path(path), doc, indent=None)


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


BY_SUFFIX = {
    ".glb": gltf,
    ".vrm": gltf,
    ".vrma": gltf,
    ".bvh": recorded,
    ".csv": recorded,
    ".fbx": recorded,
    ".pt": checkpoint,
    ".mp4": video,
    ".mov": video,
    ".mkv": video,
    ".avi": video,
    ".webm": video,
}
"""The default check of an output's suffix; an npz or JSON output names its kind (:func:`npz`, :func:`json_kind`)."""
