"""Train / validation / test splits by **source**, independent of where the data sits.

A video's split is decided by its *source group*, never by its file alone or its absolute path:

1. Its **key path**: the path relative to the data root (``anima.io.assets.data_root``) for shared data; for a
   video elsewhere, its folder's name and its file name (``speaker_a/take3.mp4``), so moving or copying a
   folder leaves every split as it was.
2. Its **source key** (the speaker, actor, recording or talk): the first rule of :data:`SOURCE_RULES` whose
   prefix the key path starts with, applied to the file name; a video no rule names gets
   ``<folder>:<file name less a trailing clip/part/take number>``.
3. **Groups**: videos whose files are byte-identical (sha256) or whose middle frames look the same (a 64-bit
   difference hash of the frame, :data:`NEAR` bits apart or fewer) join one group, named by its smallest
   source key; so a clip copied under two folders, or re-encoded, cannot sit on two sides.
4. The group's split: a hash of its name against :data:`TEST` and :data:`VAL` (so adding videos never moves
   another video's split).

``table(videos)`` returns all of it per video; ``anima dataset build`` writes it into the manifest
(``split_table``) and each row carries its video's split.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from anima.io.assets import data_root
from anima.io.outdir import sha256

TEST = 0.2  # fraction of source groups on the test side (by hash of the group's name)
VAL = 0.2  # and on the validation side
SALT = "anima-splits-v2"  # the rule's version: changing it (or TEST / VAL) moves splits; the manifest records it
NEAR = 4  # difference-hash bits at most between two middle frames of one recording

# (key-path prefix, regular expression on the file name, source key template with {1}.. for its groups).
# Persons seen in more than one corpus get one key (Obama in StyleTalk and EDTalk's test data).
SOURCE_RULES: list[tuple[str, str, str]] = [
    ("emotion-clips/crema-d/", r"^(\d{4})_", "crema-d:actor{1}"),  # CREMA-D: the actor id leads the file name
    ("emotion-clips/eamm-mead/", r"", "mead:eamm"),  # EAMM's MEAD test crops: one actor
    ("gesture-video/pats-crops/", r"^([a-z]+)\d+_gt", "person:{1}"),  # oliver1_gt: John Oliver
    ("gesture-video/tango-interviews/", r"^(speaker\d+)_", "tango:{1}"),
    ("gesture-video/tango-interviews/", r"^([A-Za-z0-9_-]{11})_\d\d-", "tango:youtube-{1}"),
    ("liveportrait-examples/", r"^(.+)$", "liveportrait:{1}"),  # d0, d3 ...: each clip its own recording
    ("pose3d/", r"^(.+)$", "pose3d:{1}"),
    ("talking-heads-extra/uncrop_Obama", r"", "person:obama"),
    ("talking-heads-extra/aniportrait_pose_ref", r"", "person:theresa-may"),  # the frames of May_5s (checked)
    ("talking-heads-extra/expression_source", r"", "styletalk:happyenglish"),  # the happyenglish speaker
    ("talking-heads-extra/RD_Radio", r"^(RD_Radio\d+)_", "hdtf:{1}"),
    ("talking-heads-misc/Real3DPortrait/", r"^May_", "person:theresa-may"),
    ("styletalk-samples/", r"^(?i:obama)_", "person:obama"),
    ("styletalk-samples/", r"^(?i:andrew)_", "person:andrew-ng"),
    ("styletalk-samples/", r"^(?i:feifeili)_", "person:feifei-li"),
    ("styletalk-samples/", r"^(?i:kristinoem)", "person:kristi-noem"),
    ("styletalk-samples/", r"^(?i:reagan)_", "person:reagan"),
    ("styletalk-samples/", r"^(?i:trump)_", "person:trump"),
    ("styletalk-samples/", r"^(.+?)_clip", "styletalk:{1}"),  # furious_talk2_clip5: the furious_talk2 recording
]

_TRAILING = re.compile(r"([_-]?(clip|part|take|seg|segment)?[_-]?\d+)?(_short|_gt)?$", re.I)


def key_path(path: str | Path, root: Path | None = None) -> str:
    """The path a split is keyed on: relative to the data root, else ``<folder>/<file name>``."""
    p = Path(path).resolve()
    root = (root or data_root()).resolve()
    try:
        return p.relative_to(root).as_posix()
    except ValueError:
        return f"{p.parent.name}/{p.name}"


def source_key(rel: str) -> str:
    """The source (speaker, actor, recording, talk) of a key path, by :data:`SOURCE_RULES` or the default."""
    name = rel.rsplit("/", 1)[-1]
    stem = name.rsplit(".", 1)[0]
    for prefix, pattern, template in SOURCE_RULES:
        if rel.startswith(prefix):
            m = re.search(pattern, stem)
            if m:
                return re.sub(r"\{(\d)\}", lambda g: m.group(int(g.group(1))).lower(), template)
    folder = rel.rsplit("/", 2)[-2] if "/" in rel else ""
    base = _TRAILING.sub("", stem) or stem
    return f"{folder}:{base}".lower()


def split_of_group(name: str, test: float | None = None, val: float | None = None) -> str:
    test = TEST if test is None else test
    val = VAL if val is None else val
    h = int(hashlib.sha1(f"{SALT}/{name}".encode()).hexdigest()[:8], 16) / 0xFFFFFFFF
    return "test" if h < test else ("val" if h < test + val else "train")


def split_for(path: str | Path, root: Path | None = None) -> str:
    """One video's split from its source alone (no grouping with others)."""
    return split_of_group(source_key(key_path(path, root)))


def fingerprint(path: str | Path) -> tuple[str, int | None]:
    """(sha256 of the file, 64-bit difference hash of its middle frame or None where none decodes)."""
    import cv2
    import numpy as np

    digest = sha256(path)
    cap = cv2.VideoCapture(str(path))
    try:
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        frame = None
        for _ in range(max(1, min(n // 2, 150)) + 1):  # read, not seek: seeking is unreliable in old codecs
            ok, f = cap.read()
            if not ok:
                break
            frame = f
    finally:
        cap.release()
    if frame is None:
        return digest, None
    g = cv2.resize(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), (9, 8), interpolation=cv2.INTER_AREA).astype(np.int16)
    bits = (g[:, 1:] > g[:, :-1]).ravel()
    return digest, int(sum(int(b) << i for i, b in enumerate(bits)))


def table(videos: list[str | Path], root: Path | None = None, fingerprints: dict | None = None) -> dict[str, dict]:
    """Per video (its resolved path as a string): ``{"key_path", "source", "group", "split"}``.
    ``fingerprints``: precomputed :func:`fingerprint` results by path (else computed here)."""
    paths = [str(Path(v).resolve()) for v in videos]
    keys = {p: key_path(p, root) for p in paths}
    source = {p: source_key(keys[p]) for p in paths}
    parent = {s: s for s in source.values()}

    def find(s):
        while parent[s] != s:
            parent[s] = parent[parent[s]]
            s = parent[s]
        return s

    def union(a, b):
        a, b = find(a), find(b)
        if a != b:
            parent[max(a, b)] = min(a, b)

    fps = {}
    for p in paths:
        if fingerprints is not None and p in fingerprints:
            fps[p] = fingerprints[p]
        elif Path(p).is_file():
            try:
                fps[p] = fingerprint(p)
            except OSError:
                pass
    seen_sha: dict[str, str] = {}
    hashes: list[tuple[int, str]] = []
    for p, (sha, dh) in fps.items():
        if sha in seen_sha:
            union(source[p], seen_sha[sha])
        seen_sha.setdefault(sha, source[p])
        if dh is not None:
            for other, s in hashes:
                if bin(other ^ dh).count("1") <= NEAR:
                    union(source[p], s)
            hashes.append((dh, source[p]))
    out = {}
    for p in paths:
        g = find(source[p])
        out[p] = {"key_path": keys[p], "source": source[p], "group": g, "split": split_of_group(g)}
    return out


def rule() -> dict:
    """What a manifest records of the rule its splits came from."""
    return {"salt": SALT, "test": TEST, "val": VAL, "near_bits": NEAR, "module": __name__}
