"""What the viewer page reads: a small, versioned export of an anima result (schema ``anima.view`` version 1,
docs/artifacts.md), written by :func:`build_view` next to a copy of the page. The page never parses an npz:
everything it shows comes from here.

* ``view-data.js``: ``window.ANIMA_VIEW = {...}``: kind, title, fps, frames, the media files, curves (chosen
  ARKit weights and wrist speeds per frame), timeline marks (capture flags, gesture joins) and ranges (gesture
  controls), notes; for a dataset its clips (descriptions, attributes, expression weights per frame).
* ``avatar-glb.js``: ``window.ANIMA_GLB = "<base64>"``: the result's ``avatar.glb`` (rig + head, or the head
  alone), or the neutral head with its morph targets for a dataset. Script files, not fetched data, so the
  page also works opened from disk (``file://``), where browsers refuse to fetch.
* the videos and ``speech.wav`` beside it, copied (a missing one is a note on the page, the 3D plays alone).

Only regular files inside the result folder are read (a symlink, or a name that leaves the folder, is a note,
never followed); a re-enactment record's video must lie beside the record; the capture's source video is never
looked up against the current folder: a relative recorded path is a file inside the result folder, an absolute
one is taken as recorded only when it is the video the capture tracked (its recorded size, frame count and
codec), and it must be a real, browser-playable video (else the page has no source video, and a note says why).
A copy of a user's file keeps its permission bits.
"""

from __future__ import annotations

import base64
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from anima import __version__
from anima.core.contract import EXPR_NAMES, FACE_DIM, N_EXPR, TEXT_FPS
from anima.core.skeleton import JOINT_NAMES, LEFT_HAND, RIGHT_HAND
from anima.dataset.storage import check_dataset
from anima.dataset.windows import read_clips
from anima.errors import AssetNotFound, InputError, SchemaError
from anima.export.avatar import character_face
from anima.export.formats import export_glb, export_vrma
from anima.export.framing import generated_sequence
from anima.export.retarget import avatar_front, find_humanoid, in_t_pose, load_avatar
from anima.export.retarget import run as retarget
from anima.io.atomic import copy_file, write_text
from anima.io.gltf_read import read_gltf
from anima.io.outdir import MANIFEST, confined, read_manifest
from anima.io.sequence import FLAG_LOW_CONFIDENCE, FLAG_NO_FACE, read_sequence
from anima.io.validate import MAX_FPS, MIN_FPS, input_file, read_json
from anima.io.video import probe_video

SCHEMA = "anima.view"
VERSION = 1
STATIC = Path(__file__).parent / "static"
CURVES = (
    "jawOpen",
    "mouthSmile_L",
    "eyeBlink_L",
    "eyeBlink_R",
    "browInnerUp_L",
    "browDown_L",
    "mouthFrown_L",
    "eyeWide_L",
)
# the videos shown beside the 3D view (the fitted-mesh and avatar renders repeat what the 3D view shows; each
# more video costs the page decoding time)
VIDEO_ROLES = {"overlay.mp4": "fit over the video", "skeleton_overlay.mp4": "skeleton over the video"}
PLAYABLE = {".mp4", ".webm", ".m4v", ".mov"}  # containers a browser plays (with H.264 / VP8 / VP9 / AV1 inside)
SEQUENCES = {"capture": "capture.npz", "text2face": "motion.npz", "gesture": "gesture.npz"}


def viewer_files() -> list[Path]:
    """The page's own files, built by ``./dev setup`` (three.js and the app bundled with esbuild)."""
    files = [STATIC / "index.html", STATIC / "viewer.js"]
    if not all(f.is_file() for f in files):
        raise AssetNotFound(
            f"the viewer is not built ({STATIC / 'viewer.js'} is missing): run ./dev setup (it needs Node.js and npm)"
        )
    return files


def js_global(name: str, value) -> str:
    """A script that sets ``window.NAME`` to ``value`` (as JSON): how the viewer's data files hand it data."""
    return f"window.{name} = {json.dumps(value, separators=(',', ':'))};\n"


def _reenact_records(path: Path) -> list[Path]:
    """The re-enactment records (``OUT.json`` beside ``anima reenact --out OUT.mp4``) that ``path`` names: the
    record of a video or a record itself, or every record in a folder, newest first."""
    if path.is_file():
        cands = [path.with_suffix(".json")]
    else:
        cands = sorted(path.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True)
    found = []
    for r in cands:
        if not r.is_file() or r.stat().st_size > 10_000_000:
            continue
        try:
            d = read_json(r)
        except InputError:
            continue
        if isinstance(d, dict) and d.get("schema") == "anima.reenact_run":
            if d.get("version") != 1:
                raise SchemaError(f"{r}: re-enactment record version {d.get('version')}; this anima reads 1")
            found.append(r)
    return found


def detect(folder: Path) -> str:
    """The kind of anima result in ``folder``: capture, text2face, gesture, reenact or dataset. A re-enacted
    video (or its ``.json`` record) may be given instead of a folder."""
    if not folder.exists():
        raise InputError(f"no such folder: {folder}")
    if folder.is_file():
        if _reenact_records(folder):
            return "reenact"
        raise InputError(f"{folder}: not a result folder (nor a video made by anima reenact)")
    m = folder / MANIFEST
    if m.is_file():
        data = read_json(m, "manifest")
        if isinstance(data, dict) and data.get("schema") == "anima.dataset":
            check_dataset(folder)
            return "dataset"
        manifest = read_manifest(folder)
        if manifest.get("kind") in SEQUENCES:
            return manifest["kind"]
    if _reenact_records(folder):
        return "reenact"
    for kind, name in SEQUENCES.items():  # an older result (no manifest): its sequence file
        if (folder / name).is_file():
            return kind
    raise InputError(f"{folder} holds no anima result (capture, text2face, gesture, reenact or dataset)")


def _speeds(J: np.ndarray, fps: float) -> dict:
    out = {}
    for name in ("left_wrist", "right_wrist"):
        p = J[:, JOINT_NAMES.index(name)]
        v = np.linalg.norm(np.diff(p, axis=0, prepend=p[:1]), axis=-1) * fps
        out[f"{name}_speed"] = [None if not np.isfinite(x) else round(float(x), 4) for x in v]
    return out


def _inside(folder: Path, name: str, notes: list) -> Path | None:
    """``folder/name`` when it is a regular file inside the folder (not a symlink); a note when something else
    sits there."""
    p = confined(folder, name)
    if p is None and os.path.lexists(folder / name):
        notes.append(f"{name} in {folder} is not a regular file of the folder (a link?): not shown")
    return p


_FINGERPRINT = ("width", "height", "n_frames", "codec")
"""What a capture records of its source video (:class:`anima.io.video.VideoInfo`) and the file at a recorded
absolute path must show again before the page takes it."""


def _source_video(folder: Path, src: str, meta: dict, notes: list) -> Path | None:
    """The capture's source video when the page can show it, never looked up against the current folder: a
    relative recorded path inside the result folder (a regular file, no ``..``, no symlink), an absolute one as
    recorded when it is the video the capture tracked (the same size, frame count and codec as recorded); a
    readable, browser-playable video. Anything else: no source video, a note saying why."""
    none = "no source video:"
    if "\x00" in src:
        notes.append(f"{none} the recorded source is not a file name")
        return None
    if os.path.isabs(src):
        s = Path(src)
        if not s.is_file():
            notes.append(f"{none} the source video {src} is not there")
            return None
    else:
        s = confined(folder, src)
        if s is None:
            notes.append(f"{none} the recorded source {src} is not a file inside {folder} (a relative source is "
                         "looked up in the result folder)")  # fmt: skip
            return None
    if s.suffix.lower() not in PLAYABLE or meta.get("codec") not in ("h264", "vp8", "vp9", "av1"):
        notes.append(f"{none} the source video {s.name} ({meta.get('codec')}) does not play in a browser")
        return None
    try:
        info = probe_video(s)
    except InputError:
        notes.append(f"{none} the source video {src} is not a readable video")
        return None
    if os.path.isabs(src) and any(meta.get(k) != getattr(info, k) for k in _FINGERPRINT):
        notes.append(f"{none} {src} is not the video this capture tracked (its size, frames or codec differ)")
        return None
    if info.codec not in ("h264", "vp8", "vp9", "av1"):
        notes.append(f"{none} the source video {s.name} ({info.codec}) does not play in a browser")
        return None
    return s


def _sequence_view(folder: Path, kind: str, out: Path, notes: list, wrote: list) -> dict:
    seq_path = confined(folder, SEQUENCES[kind])
    if seq_path is None:
        raise InputError(f"{folder}: {SEQUENCES[kind]} is not a regular file of the folder")
    seq = read_sequence(seq_path)
    info = {}
    if _inside(folder, "info.json", notes):
        info = read_json(folder / "info.json", "info.json")
        if not isinstance(info, dict):
            raise SchemaError(f"{folder / 'info.json'}: not a JSON object")
    F = seq.n_frames
    shown = character_face(seq) if seq.tracked.any() else None  # the weights every export carries
    curves = {n: [round(float(x), 4) for x in shown[:, EXPR_NAMES.index(n)]] for n in CURVES if shown is not None}
    marks, ranges = [], []
    if kind == "capture":
        for f in np.flatnonzero(seq.flags & FLAG_NO_FACE):
            marks.append({"frame": int(f), "kind": "no_face", "label": "face lost"})
        for f in np.flatnonzero(seq.flags & FLAG_LOW_CONFIDENCE):
            marks.append({"frame": int(f), "kind": "low_confidence", "label": "low confidence"})
        if seq.body_interpolated is not None:
            for side, sl in (("left", LEFT_HAND), ("right", RIGHT_HAND)):
                for f in np.flatnonzero(seq.body_interpolated[:, sl].any(1)):
                    marks.append({"frame": int(f), "kind": "interpolated", "label": f"{side} hand interpolated"})
    if kind == "gesture":
        for t in info.get("joins_s", []):
            marks.append({"frame": int(round(t * seq.fps)), "kind": "join", "label": "window join"})
        for c in info.get("controls", []):
            a, b = c.get("start_s", 0.0), c.get("end_s", F / seq.fps)
            b = F / seq.fps if b is None or b == float("inf") else b
            ranges.append(
                {
                    "start": int(round(a * seq.fps)),
                    "end": int(min(F, round(b * seq.fps))),
                    "label": c.get("control", "control"),
                }
            )
    joints = {}
    if seq.body_joints is not None and np.isfinite(seq.body_joints).any():
        curves.update(_speeds(seq.body_joints, seq.fps))
        joints = {"names": ["Head", "LeftHand", "RightHand", "Spine"]}  # shown from avatar.glb's bones
    videos = []
    source = seq.meta.get("source")
    src = source.get("path") if isinstance(source, dict) else None
    src = src if isinstance(src, str) and src else None
    if kind == "capture" and src:
        s = _source_video(folder, src, source, notes)
        if s is not None:
            name = f"source{s.suffix.lower()}"
            wrote.append(copy_file(s, out / name, keep_mode=True))
            videos.append({"file": name, "role": "source video"})
    for name, role in VIDEO_ROLES.items():
        p = _inside(folder, name, notes)
        if p is not None:
            wrote.append(copy_file(p, out / name))
            videos.append({"file": name, "role": role})
    if kind == "capture" and not (folder / "overlay.mp4").is_file():
        notes.append("no overlay video beside the capture (captured with --no-render?): the 3D plays alone")
    audio = None
    p = _inside(folder, "speech.wav", notes)
    if p is not None:
        wrote.append(copy_file(p, out / "speech.wav"))
        audio = "speech.wav"
    glb = _inside(folder, "avatar.glb", notes)
    if glb is None:
        with tempfile.TemporaryDirectory(prefix="anima-view-") as tmp:
            head = export_glb(seq, Path(tmp) / "head.glb")
            glb_bytes = Path(head).read_bytes()
        notes.append("no avatar.glb in the folder (an older result): the head alone, made from the sequence")
    else:
        glb_bytes = glb.read_bytes()
    wrote.append(write_text(out / "avatar-glb.js", js_global("ANIMA_GLB", base64.b64encode(glb_bytes).decode())))
    title = {
        "capture": f"capture of {Path(src).name if src else folder.name}",
        "text2face": f"text to face: “{info.get('prompt', seq.meta.get('prompt', ''))}”",
        "gesture": f"gestures for {Path(str(seq.meta.get('speech', ''))).name}",
    }[kind]
    return {
        "kind": kind,
        "title": title,
        "fps": seq.fps,
        "frames": F,
        "videos": videos,
        "audio": audio,
        "prompt": info.get("prompt"),
        "curves": curves,
        "marks": marks,
        "ranges": ranges,
        "joints": joints,
        "summary": {k: v for k, v in info.items() if isinstance(v, (int, float, str)) and k != "prompt"},
    }


def _dataset_view(folder: Path, out: Path, notes: list, wrote: list, max_clips: int = 200) -> dict:
    clips = read_clips(folder)
    if not clips:
        raise InputError(f"{folder}: the dataset has no (text, motion) clips to show")
    if len(clips) > max_clips:
        notes.append(f"{len(clips)} clips: the first {max_clips} are shown")
    names = list(generated_sequence(TEXT_FPS, face=np.zeros((1, FACE_DIM), np.float32)).expr_names)
    rows = []
    for c in clips[:max_clips]:
        rows.append(
            {
                "id": c.clip_id,
                "split": c.split,
                "source": Path(c.source).name,
                "start_s": c.start_s,
                "fps": c.fps,
                "frames": len(c.motion),
                "texts": c.texts[:3],
                "events": [[n, round(s, 2), round(e, 2)] for n, s, e in c.events],
                "weights": base64.b64encode(np.ascontiguousarray(c.motion[:, :N_EXPR], np.float32).tobytes()).decode(),
                "rotation": base64.b64encode(np.ascontiguousarray(c.motion[:, N_EXPR:], np.float32).tobytes()).decode(),
            }
        )
    with tempfile.TemporaryDirectory(prefix="anima-view-") as tmp:
        head = export_glb(
            generated_sequence(TEXT_FPS, face=np.zeros((1, FACE_DIM), np.float32)),
            Path(tmp) / "head.glb",
            animate_head=False,
        )
        glb_bytes = Path(head).read_bytes()
    wrote.append(write_text(out / "avatar-glb.js", js_global("ANIMA_GLB", base64.b64encode(glb_bytes).decode())))
    return {
        "kind": "dataset",
        "title": f"dataset {folder.name}: {len(clips)} clips",
        "fps": clips[0].fps,
        "frames": len(clips[0].motion),
        "videos": [],
        "audio": None,
        "curves": {},
        "marks": [],
        "ranges": [],
        "joints": {},
        "expr_names": names,
        "clips": rows,
    }


def _record_fields(rec, where: Path) -> tuple[dict, str, str]:
    """The fields of a re-enactment record the page needs, checked: (result, actor name, target name)."""
    result = rec.get("result") if isinstance(rec, dict) else None
    targets = rec.get("targets") if isinstance(rec, dict) else None
    ok = (
        isinstance(result, dict)
        and isinstance(result.get("fps"), (int, float))
        and not isinstance(result.get("fps"), bool)
        and MIN_FPS <= result["fps"] <= MAX_FPS
        and isinstance(result.get("frames"), int)
        and 0 <= result["frames"] <= 10_000_000
        and isinstance(rec.get("actor"), str)
        and isinstance(targets, list)
        and targets
        and isinstance(targets[0], str)
    )
    if not ok:
        raise SchemaError(f"{where}: a re-enactment record without its result (fps, frames, actor, targets)")
    return result, Path(rec["actor"]).name, Path(targets[0]).name


def _reenact_view(path: Path, out: Path, notes: list, wrote: list) -> dict:
    records = _reenact_records(path)
    if len(records) > 1:
        notes.append(f"{len(records)} re-enactments in {path}: showing the newest, {records[0].stem}")
    rec = read_json(records[0])
    result, actor, target = _record_fields(rec, records[0])
    # the video lies beside its record: a path elsewhere (moved, or crafted to point outside) is not followed
    here = records[0].parent
    named = result.get("output")
    video = None
    if isinstance(named, str) and named and "\x00" not in named:
        video = confined(here, Path(named).name) if Path(named).resolve().parent == here.resolve() else None
    if video is None:
        video = confined(here, records[0].with_suffix(".mp4").name)
    videos = []
    if video is not None:
        name = f"reenact{video.suffix.lower()}" if video.suffix.lower() in PLAYABLE else "reenact.mp4"
        wrote.append(copy_file(video, out / name, keep_mode=True))
        role = "re-enactment" + (" (actor | output)" if rec.get("side_by_side") else "")
        videos.append({"file": name, "role": role})
    else:
        notes.append(f"the re-enactment video {named} is not beside its record {records[0].name}")
    title = f"re-enactment: {actor} on {target}"
    return {
        "kind": "reenact",
        "title": title,
        "fps": result["fps"],
        "frames": result["frames"],
        "videos": videos,
        "audio": None,
        "curves": {},
        "marks": [],
        "ranges": [],
        "joints": {},
        "no3d": True,
        "summary": {k: v for k, v in result.items() if isinstance(v, (int, float, str))},
    }


def check_avatar(avatar: str | Path | None, kind: str, motion: str = "auto") -> None:
    """Refuse, before any work, an ``--avatar`` that is not a .vrm/.glb file or a result it cannot play on
    (a dataset, a re-enactment)."""
    if avatar is None:
        if motion != "auto":
            raise InputError("--motion says how the result reaches --avatar: give --avatar")
        return
    if motion not in MOTIONS:
        raise InputError(f"--motion {motion}: one of {', '.join(MOTIONS)}")
    p = input_file(avatar, "avatar")
    if p.suffix.lower() not in (".vrm", ".glb"):
        raise InputError(f"--avatar {p}: expected a .vrm (VRM 1.0) or a .glb (skinned glTF binary)")
    if kind not in SEQUENCES:
        raise InputError(f"--avatar plays a capture, gesture or text2face result on the avatar; {kind} has no motion")
    load_avatar(p)  # read and checked in full (a humanoid, a usable rest) before the page is made


MOTIONS = ("auto", "vrma", "retarget")


def _avatar_view(folder: Path, kind: str, avatar: Path, out: Path, notes: list, wrote: list, how: str) -> dict:
    """The user's avatar on the page. ``how``: "vrma" sends a VRM as it is with the result as a VRM Animation
    (``ANIMA_VRMA``: three-vrm plays it, relative to the VRM's rest, which VRM 1.0 requires to be a T-pose);
    "retarget" sends the avatar with the motion retargeted onto its own rest (``anima.export.retarget``: any
    rest pose); "auto": vrma for a VRM in a T-pose, else retarget."""
    seq_path = folder / SEQUENCES[kind]
    g = read_gltf(avatar)
    if how == "vrma" and g.vrm is None:
        raise InputError(f"--motion vrma plays on a VRM; {avatar} is a plain glTF (use --motion retarget)")
    hum = find_humanoid(g)
    if how == "auto":
        how = "vrma" if g.vrm is not None and in_t_pose(g, hum) else "retarget"
    with tempfile.TemporaryDirectory(prefix="anima-view-") as tmp:
        if how == "vrma":
            vrma = Path(export_vrma(read_sequence(seq_path), Path(tmp) / "take.vrma")).read_bytes()
            glb_bytes = avatar.read_bytes()
            info = {"avatar": avatar.name, "as": "VRM with a VRM Animation (three-vrm)", "vrm": True}
        else:
            out_file = Path(tmp) / ("avatar.vrm" if g.vrm is not None else "avatar.glb")
            r = retarget(seq_path, avatar, out_file)
            glb_bytes, vrma = out_file.read_bytes(), None
            how = f"retargeted onto its rest ({r['convention']})"
            info = {"avatar": avatar.name, "as": how, "vrm": g.vrm is not None}
            notes.append(f"face on {avatar.name}: {r['face']['via']}, {len(r['face']['found_a_home'])} channels")
    wrote.append(write_text(out / "avatar-glb.js", js_global("ANIMA_GLB", base64.b64encode(glb_bytes).decode())
                            + js_global("ANIMA_VRMA", base64.b64encode(vrma).decode() if vrma else None)))  # fmt: skip
    info["front"] = avatar_front(g, hum)  # where the face close-up's camera stands
    return info


def build_view(folder: str | Path, out: str | Path, avatar: str | Path | None = None, motion: str = "auto") -> dict:
    """Write the page for the result in ``folder`` into ``out`` (created); returns the page's data, with
    ``written``: the names of the files written into ``out`` (nothing else there is touched). ``avatar``: a
    user's .vrm / .glb the result plays on instead of anima's character (``motion``: see :func:`_avatar_view`)."""
    folder, out = Path(folder), Path(out)
    kind = detect(folder)
    files = viewer_files()
    out.mkdir(parents=True, exist_ok=True)
    notes: list[str] = []
    wrote: list[Path] = []
    if kind == "dataset":
        data = _dataset_view(folder, out, notes, wrote)
    elif kind == "reenact":
        data = _reenact_view(folder, out, notes, wrote)
        wrote.append(write_text(out / "avatar-glb.js", js_global("ANIMA_GLB", None)))
    else:
        data = _sequence_view(folder, kind, out, notes, wrote)
        if avatar is not None:
            data["avatar"] = _avatar_view(folder, kind, Path(avatar), out, notes, wrote, motion)
            wrote = list(dict.fromkeys(wrote))
    data.update(schema=SCHEMA, version=VERSION, anima_version=__version__, notes=notes, source=str(folder))
    wrote.append(write_text(out / "view-data.js", js_global("ANIMA_VIEW", data)))
    for f in files:
        wrote.append(copy_file(f, out / f.name))
    data["written"] = sorted({Path(p).name for p in wrote})
    return data
