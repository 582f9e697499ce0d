"""Train / validation / test splits by **source**, independent of where the data sits.

A video's split is decided by its *source group*, never by its file alone or its absolute path:

1. Its **key path**: the path relative to the data root (``anima.io.assets.data_root``) for shared data; for a
   video elsewhere, its folder's name and its file name (``speaker_a/take3.mp4``), so moving or copying a
   folder leaves every split as it was (and renaming it moves none: 4.).
2. Its **source key** (the speaker, actor, recording or talk): the first rule of :data:`SOURCE_RULES` whose
   prefix the key path starts with, applied to the file name; a video no rule names gets
   ``<folder>:<file name less a trailing clip/part/take number>``.
3. **Groups**: videos whose files are byte-identical (sha256), whose middle frames look the same (a 64-bit
   difference hash of the frame, :data:`NEAR` bits apart or fewer), or that share frames after cropping and
   scaling (:func:`face_hashes`: a perceptual hash of a face-centred crop at :data:`FACE_FRAMES` points of
   each video; :data:`FACE_MIN_FRAMES` of one video's crops each within :data:`FACE_NEAR` bits of one of the
   other's) join one group, named by its smallest source key; so a clip copied under two folders, re-encoded
   or re-cropped cannot sit on two sides. Each row says why it was grouped (``grouped_with``).
4. The group's split: a hash of its name against :data:`TEST` and :data:`VAL` (so adding videos never moves
   another video's split). A group of videos wholly outside the data root lands by its content instead
   (:func:`content_key`: the sha256 of its first video by file name), so the same videos under differently
   named folders get the same splits: there names (the folder, a speaker hint, and the file) still decide what
   belongs together, content decides the side. Adding a video to such a group moves it only where the new
   video's file name sorts first.

``table(videos)`` returns all of it per video; ``anima dataset build`` writes it into the manifest
(``split_table``) and each row carries its video's split.
"""

from __future__ import annotations

import hashlib
import re
from contextlib import ExitStack
from pathlib import Path

from anima.io.assets import data_root
from anima.io.outdir import sha256
from anima.io.video import sampled_frames
from anima.track import get

TEST = 0.2  # fraction of source groups on the test side (by hash of the group's name)
VAL = 0.2  # and on the validation side
SALT = "anima-splits-v2"  # the rule's version: changing it (or TEST / VAL) moves splits; the manifest records it
NEAR = 4  # difference-hash bits at most between two middle frames of one recording
FACE_FRAMES = 12  # face-centred crops hashed per video, evenly over its frames
FACE_NEAR = 2  # perceptual-hash bits at most between two crops of one recording
FACE_MIN_FRAMES = 2  # crops of one video that must each find such a crop in the other
"""Chosen on the shared data (102 videos, every pair, crops from each one's first 10 s): the one re-cropped copy
an audit found (``talking-heads-extra/pose_source1.mp4`` and ``videoretalking-examples/examples/face/3.mp4``)
has 2 crops within 1 bit; the copies the source table already declares 0-1 bits (2-12 crops), as do one
CREMA-D actor's sentences (one session, one source already); the nearest crops of two different sources are
7 bits apart."""
FACE_CROP = 1.6  # the crop's side, times the face box's longer side
FACE_SECONDS = 10.0  # the crops come from the video's first seconds (a bounded cost per video)

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
    # one interview (same shot, flag, dress, earrings), re-cropped in VideoReTalking's examples: found by the
    # face crops, declared so a build of any subset gives it one split
    ("talking-heads-extra/pose_source", r"", "recording:pose-source"),
    ("videoretalking-examples/examples/face/3.mp4", r"", "recording:pose-source"),
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


def fingerprint(path: str | Path, detector=None) -> tuple[str, int | None, list[int]]:
    """(sha256 of the file, 64-bit difference hash of its middle frame or None where none decodes, its
    :func:`face_hashes`)."""
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
        return digest, None, []
    g = cv2.resize(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), (9, 8), interpolation=cv2.INTER_AREA).astype(np.int16)
    bits = (g[:, 1:] > g[:, :-1]).ravel()
    return digest, int(sum(int(b) << i for i, b in enumerate(bits))), face_hashes(path, detector)


def face_hashes(path: str | Path, detector=None, n: int = FACE_FRAMES) -> list[int]:
    """64-bit perceptual hashes (OpenCV's pHash) of the largest face's crop (:data:`FACE_CROP` times its box,
    32 x 32 grey) at ``n`` evenly spaced frames of the video's first :data:`FACE_SECONDS` (those where
    the tracker's face detector finds one: :meth:`anima.track.Tracker.face_boxes`), read in order (seeking costs
    more than decoding here). ``detector``: an opened face detector to reuse (else one is opened and closed
    here)."""
    import cv2

    if detector is None:
        with get().face_boxes() as det:
            return face_hashes(path, det, n)
    out = []
    for f in sampled_frames(path, FACE_SECONDS, n):
        h, w = f.shape[:2]
        found = detector(cv2.cvtColor(f, cv2.COLOR_BGR2RGB))
        if not found:
            continue
        b = max(found, key=lambda r: r.width)
        cx, cy = (b.xmin + b.width / 2) * w, (b.ymin + b.height / 2) * h
        side = FACE_CROP * max(b.width * w, b.height * h)
        x0, y0 = int(max(0, cx - side / 2)), int(max(0, cy - side / 2))
        crop = f[y0 : int(min(h, cy + side / 2)), x0 : int(min(w, cx + side / 2))]
        if crop.size:
            g = cv2.resize(cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY), (32, 32), interpolation=cv2.INTER_AREA)
            out.append(int.from_bytes(cv2.img_hash.pHash(g)[0].tobytes(), "little"))
    return out


def same_recording(a: list[int], b: list[int]) -> bool:
    """Whether two videos' :func:`face_hashes` say they share frames (see :data:`FACE_MIN_FRAMES`)."""
    if not a or not b:
        return False
    near = [[bin(x ^ y).count("1") <= FACE_NEAR for y in b] for x in a]
    return min(sum(map(any, near)), sum(map(any, zip(*near)))) >= FACE_MIN_FRAMES


def content_key(paths: list[str], fingerprints: dict) -> str | None:
    """What decides the side of a group of videos outside the data root: the sha256 of its first video by file
    name (then by sha256), the folder left out; None where none of them was read."""
    read = sorted((Path(p).name, fingerprints[p][0]) for p in paths if p in fingerprints)
    return f"content:{read[0][1]}" if read else None


def table(videos: list[str | Path], root: Path | None = None, fingerprints: dict | None = None) -> dict[str, dict]:
    """Per video (its resolved path as a string): ``{"key_path", "source", "group", "split", "grouped_with"}``
    (``grouped_with``: the other sources it was found to share content with, and how).
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

    why: dict[str, dict[str, str]] = {}

    def union(a, b, how):
        if a != b:
            why.setdefault(a, {}).setdefault(b, how)
            why.setdefault(b, {}).setdefault(a, how)
        a, b = find(a), find(b)
        if a != b:
            parent[max(a, b)] = min(a, b)

    fps = {}
    with ExitStack() as stack:
        det = None
        for p in paths:
            if fingerprints is not None and p in fingerprints:
                fps[p] = fingerprints[p]
            elif Path(p).is_file():
                if det is None:
                    det = stack.enter_context(get().face_boxes())
                try:
                    fps[p] = fingerprint(p, det)
                except OSError:
                    pass
    seen_sha: dict[str, str] = {}
    hashes: list[tuple[int, str]] = []
    faces: list[tuple[list[int], str]] = []
    for p, (sha, dh, *rest) in fps.items():
        if sha in seen_sha:
            union(source[p], seen_sha[sha], "the same file")
        seen_sha.setdefault(sha, source[p])
        if dh is not None:
            for other, s in hashes:
                if bin(other ^ dh).count("1") <= NEAR:
                    union(source[p], s, "the same middle frame")
            hashes.append((dh, source[p]))
        fh = rest[0] if rest else []
        for other, s in faces:
            if same_recording(fh, other):
                union(source[p], s, "the same face crops (re-cropped or scaled)")
        faces.append((fh, source[p]))
    base = (root or data_root()).resolve()
    members: dict[str, list[str]] = {}
    for p in paths:
        members.setdefault(find(source[p]), []).append(p)
    side = {}
    for g, ps in members.items():
        outside = all(not Path(p).is_relative_to(base) for p in ps)
        content = content_key(ps, fps) if outside else None
        # videos outside the data root: their names group them, their content decides the side (a folder renamed
        # or a copy under another folder keeps its split); the shared data keeps the rule by its source names
        side[g] = split_of_group(content or g)
    out = {}
    for p in paths:
        g = find(source[p])
        out[p] = {"key_path": keys[p], "source": source[p], "group": g, "split": side[g],
                  "grouped_with": dict(sorted(why.get(source[p], {}).items()))}  # fmt: skip
    return out


def rule() -> dict:
    """What a manifest records of the rule its splits came from."""
    return {"salt": SALT, "test": TEST, "val": VAL, "near_bits": NEAR, "face_frames": FACE_FRAMES,
            "face_near_bits": FACE_NEAR, "face_min_frames": FACE_MIN_FRAMES,
            "outside_the_data_root": "grouped by names, the side by content: the sha256 of the group's first video "
            "by file name", "module": __name__}  # fmt: skip
