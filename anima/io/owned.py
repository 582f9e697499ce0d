"""Whether an existing file is one anima wrote, checked by its content (never by its name alone): the only
files a single-file output (``--out FILE``) may replace. One check per kind of file anima writes, each reading
a bounded head of the file and running nothing:

* glTF / GLB / VRM / VRM Animation: a binary glTF whose ``asset.generator`` is ``anima``;
* BVH: a hierarchy whose joints are anima's rig under one of its naming presets (``anima.core.rig``);
* ARKit CSV: the Live Link Face header exactly as anima writes it;
* npz: a zip of ``.npy`` members holding the members of the named kind;
* checkpoints: a torch zip (``data.pkl``) of anima's envelope (``anima.io.checkpoint``);
* JSON: a document whose ``schema`` / ``kind`` field is the named one;
* a video: one whose record beside it (``OUT.json``, written by anima with the video) names its sha256.

:data:`BY_SUFFIX` maps an output's suffix to its default check (``anima.io.outdir.check_out_file``).
"""

from __future__ import annotations

import hashlib
import json
import struct
import zipfile
from pathlib import Path

from anima.core import rig
from anima.io.arkit import header
from anima.io.checkpoint import looks_like_checkpoint

_HEAD = 1 << 20  # bytes read of a text file's head
_GLB = 0x46546C67


def _head(path: Path, n: int = _HEAD) -> bytes:
    with open(path, "rb") as fh:
        return fh.read(n)


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


def bvh(path: Path) -> bool:
    """A BVH whose joints are anima's rig, named by one of its presets (``anima.core.rig.PRESETS``)."""
    try:
        text = _head(path).decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    if not text.lstrip().startswith("HIERARCHY") or "MOTION" not in text:
        return False
    names = []
    for line in text[: text.index("MOTION")].splitlines():
        w = line.split()
        if len(w) >= 2 and w[0] in ("ROOT", "JOINT"):
            names.append(" ".join(w[1:]))
    return any(names == rig.preset_names(p) for p in rig.PRESETS)


def arkit_csv(path: Path) -> bool:
    """A Live Link Face CSV with anima's header (``anima.io.arkit``) whose first row starts at anima's timecode
    zero (Live Link Face on a phone writes the time of day)."""
    try:
        lines = _head(path, 1 << 16).decode("utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return False
    return len(lines) >= 2 and lines[0].strip() == ",".join(header()) and lines[1].startswith("00:00:00:00.000,")


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
    ".bvh": bvh,
    ".csv": arkit_csv,
    ".pt": checkpoint,
    ".mp4": video,
    ".mov": video,
    ".mkv": video,
    ".avi": video,
    ".webm": video,
}
"""The default check of an output's suffix; an npz or JSON output names its kind (:func:`npz`, :func:`json_kind`)."""
