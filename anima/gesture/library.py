"""Baking a motion library: ``anima library build DATA... --out NAME`` (a user's own footage), and the built-in
library (``tools/bake_library.py`` calls :func:`write_from_pairs`, the same function, on a dataset of the
licence-permitted shared videos).

A library holds what ``anima text2face`` and ``anima gesture`` need without a dataset (:mod:`anima.library.builtin`):
the (text, motion) clips' expression weights and head rotation with the detectors' events, the (audio, motion)
windows' matching features, joints and speech features, and the talking face's mouth model. Its inputs are videos
(each captured in this process: face, body, hands and speech, then cut into clips and windows exactly as
``anima dataset build`` cuts them) or dataset folders from ``anima dataset build`` (all their splits: the user's
own data). Every input is checked before any video is captured: a missing path, a file that is not a video, a
video in which no person is seen (a few frames sampled) is refused with one line.

A user's library is theirs: no licence filter; its provenance (``library.json``, and inside the ``.npz``) lists
every source with its sha256, how much motion each gave, and the command that baked it.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima import __version__
from anima.core.contract import BODY_DIM, FACE_DIM, GESTURE_FPS, N_JOINTS, SPEECH_DIM, TEXT_FPS
from anima.dataset.build import VIDEO_EXT, expand_videos, video_payload
from anima.dataset.config import BuildConfig, FilterConfig
from anima.dataset.storage import check_dataset
from anima.dataset.windows import ClipRow, Windows, clip_events, read_clips, read_windows
from anima.errors import InputError
from anima.gesture.database import distinct_seconds, from_windows
from anima.gesture.face import fit_speech_face
from anima.gesture.features import audio_features, pose_features
from anima.io.outdir import OutputFolder, check_out_dir, check_out_file, record_out_file, sha256
from anima.io.owned import npz as npz_check
from anima.io.video import probe_video, sampled_frames
from anima.library import builtin
from anima.track import get

PERSON_FRAMES = 6  # frames sampled per video to see a person before any capture
PERSON_SECONDS = 30.0  # contract: not (... within its first this-many seconds of video)


def _is_dataset(p: Path) -> bool:
    return p.is_dir() and (p / "manifest.json").is_file() and (p / "shards").is_dir()


def collect(inputs: list[str]) -> tuple[list[Path], list[Path]]:
    """``(videos, datasets)`` named by ``inputs`` (files, folders searched recursively for videos, glob patterns,
    dataset folders), each checked: a missing path, an empty folder, a file that is not a readable video.
    :class:`InputError` on the first bad one."""
    videos, datasets = [], []
    for s in inputs:
        p = Path(s)
        if _is_dataset(p):
            check_dataset(p)
            datasets.append(p)
            continue
        if p.is_dir():
            found = expand_videos([s])
            if not found:
                raise InputError(f"{p}: a folder with no video in it ({', '.join(VIDEO_EXT)}) and not a dataset")
            videos += found
            continue
        if any(ch in s for ch in "*?[") and not p.exists():
            found = expand_videos([s])
            if not found:
                raise InputError(f"{s}: the pattern matches no video")
            videos += found
            continue
        if not p.exists():
            raise InputError(f"not found: {p}")
        videos.append(p)
    seen, uniq = set(), []
    for v in videos:
        if v.resolve() not in seen:
            seen.add(v.resolve())
            uniq.append(v)
    for v in uniq:
        probe_video(v)  # a missing, empty or non-video file: one line
    return uniq, datasets


def check_person(video: Path, n: int = PERSON_FRAMES) -> None:
    """Refuse a video in which the tracker's pose model finds nobody in ``n`` frames evenly spaced over its first
    :data:`PERSON_SECONDS` seconds (read in order: seeking is unreliable in old codecs)."""
    import cv2

    seen = 0
    with get().pose(static=True) as pose:
        for f in sampled_frames(video, PERSON_SECONDS, n):
            seen += 1
            if pose(cv2.cvtColor(f, cv2.COLOR_BGR2RGB)) is not None:
                return
    raise InputError(f"no person found in {video} ({seen} frames sampled in its first {PERSON_SECONDS:g} s)")


def _rows_to_pairs(rows: list[dict], wins: list[dict], fps_text: float, fps_win: float) -> tuple[list, Windows]:
    clips = [
        ClipRow(
            r["clip_id"],
            r["video_id"],
            r["split"],
            r["source"],
            float(r["start_s"]),
            np.asarray(r["motion"], np.float32),
            list(r["texts"]),
            clip_events(r["attributes"], "capture", r["clip_id"]),
            r["gender"],
            fps_text,
        )
        for r in rows
    ]
    T = wins[0]["n_frames"] if wins else 0

    def stack(key, dim):
        return np.stack([np.asarray(w[key], np.float32).reshape(T, dim) for w in wins]) if wins else None

    w = Windows(
        stack("speech", SPEECH_DIM) if wins else np.zeros((0, 0, SPEECH_DIM), np.float32),
        stack("body", BODY_DIM) if wins else np.zeros((0, 0, BODY_DIM), np.float32),
        stack("face", FACE_DIM) if wins else np.zeros((0, 0, FACE_DIM), np.float32),
        [x["source"] for x in wins],
        [float(x["start_s"]) for x in wins],
        [x["split"] for x in wins],
        [x["window_id"] for x in wins],
        fps_win,
    )
    return clips, w


def _concat_windows(parts: list[Windows]) -> Windows:
    parts = [p for p in parts if p.n]
    if not parts:
        z = np.zeros((0, 0, SPEECH_DIM)), np.zeros((0, 0, BODY_DIM)), np.zeros((0, 0, FACE_DIM))
        return Windows(*z, [], [], [], [], GESTURE_FPS)
    rates = {round(p.fps, 6) for p in parts}
    lengths = {p.length for p in parts}
    if len(rates) > 1 or len(lengths) > 1:
        raise InputError(f"the inputs' (audio, motion) windows differ in rate {sorted(rates)} or length {lengths}")
    return Windows(
        np.concatenate([p.speech for p in parts]),
        np.concatenate([p.body for p in parts]),
        np.concatenate([p.face for p in parts]),
        sum((p.source for p in parts), []),
        sum((p.start_s for p in parts), []),
        sum((p.split for p in parts), []),
        sum((p.window_id for p in parts), []),
        parts[0].fps,
    )


def write_from_pairs(
    path: Path, clips: list, windows: Windows, name_of, provenance: dict, sidecar: bool = True
) -> tuple[Path, Path | None, dict]:
    """Write a library at ``path`` (``.npz``; with ``sidecar`` its provenance ``.json`` beside it) from (text,
    motion) ``clips`` (:class:`anima.dataset.windows.ClipRow`) and (audio, motion) ``windows``; ``name_of(source)``:
    how a source video is named in it. ``provenance`` gains the amounts. Returns the files and the provenance."""
    db = from_windows(windows, "the inputs") if windows.n and windows.has_body.any() else None
    face_fps = clips[0].fps if clips else TEXT_FPS
    if any(abs(c.fps - face_fps) > 1e-6 for c in clips):
        raise InputError("the inputs' (text, motion) clips are at several frame rates: rebuild them with one anima")
    amounts = {
        "face_clips": len(clips),
        "face_seconds": round(sum(len(c.motion) for c in clips) / face_fps, 1),
        "gesture_windows": int(db.M) if db else 0,
        "gesture_seconds_distinct": round(distinct_seconds(db), 1) if db else 0.0,
    }
    provenance = dict(provenance) | amounts
    if db:
        gesture = {"F": db.F, "P": db.P, "G": db.G, "S": db.S}
    else:  # no window: empty arrays of the features' widths
        f, q = audio_features(np.zeros((1, SPEECH_DIM))), pose_features(np.zeros((1, N_JOINTS, 3)))
        gesture = {"F": np.zeros((0, 0, f.shape[1])), "P": np.zeros((0, 0, q.shape[1])),
                   "G": np.zeros((0, 0, BODY_DIM)), "S": np.zeros((0, 0, SPEECH_DIM))}  # fmt: skip
    npz, meta = builtin.write_library(
        path,
        [c.motion for c in clips],
        [c.events for c in clips],
        [f"{name_of(c.source)}@{c.start_s:.2f}s" for c in clips],
        face_fps,
        gesture,
        [(name_of(s), float(t)) for s, t in db.source] if db else [],
        db.fps if db else GESTURE_FPS,
        fit_speech_face(windows.face) if windows.n else None,
        provenance,
        sidecar=sidecar,
    )
    return npz, meta, provenance


LIBRARY_NPZ = npz_check(*builtin.MEMBERS)  # an existing --out FILE.npz is replaced only when it is a library


def build(
    inputs: list[str],
    out: str | Path,
    max_frames: int | None = None,
    min_clip_s: float = FilterConfig().min_s,
    progress: bool = True,
    command: str | None = None,
) -> dict:
    """``anima library build``: check every input and ``out`` (a folder, or a file ending in ``.npz``), capture
    the videos (one after another in this process, a progress bar over their frames), read the datasets, and
    write the library atomically. Returns its provenance with the files written."""
    if not inputs:
        raise InputError("give at least one video, folder of videos or dataset folder")
    single = Path(out).suffix.lower() == ".npz"
    if single:
        check_out_file(out, inputs=inputs, suffixes=(".npz",), ours=LIBRARY_NPZ, what="a motion library")
    else:
        check_out_dir(out, inputs=inputs)
    videos, datasets = collect(inputs)
    for v in videos:
        check_person(v)
    cfg = BuildConfig(max_frames=max_frames)
    cfg = replace(cfg, filters=replace(cfg.filters, min_s=min(min_clip_s, cfg.filters.max_s)))
    t0 = time.perf_counter()
    clips, parts, sources, notes = [], [], [], []
    if videos:
        frames = [min(probe_video(v).n_frames, max_frames or 10**9) for v in videos]
        with tqdm(total=sum(frames), desc="capture", unit="fr", smoothing=0, disable=not progress) as bar:
            for v, n in zip(videos, frames):
                bar.set_postfix_str(v.name[-40:])
                done = bar.n
                payload = video_payload(str(v), cfg, on_progress=bar.update, split="train")
                bar.update(max(0, done + n - bar.n))  # frames the tracker skipped
                res = payload["result"]
                c, w = _rows_to_pairs(payload["text_motion"], payload["audio_motion"], TEXT_FPS, GESTURE_FPS)
                clips += c
                parts.append(w)
                body = int(w.has_body.sum()) if w.n else 0
                sources.append(
                    {
                        "path": str(v.resolve()),
                        "sha256": sha256(v),
                        "seconds": round(res["duration_s"], 2),
                        "frames_captured": res["frames"],
                        "face_clips": len(c),
                        "gesture_windows": body,
                    }  # fmt: skip
                )
                if not res["has_speech"]:
                    notes.append(f"{v}: no speech (no audio track): its motion serves text2face only")
                elif not body:
                    notes.append(f"{v}: no window with the upper body and hands in view and speech throughout")
    for ds in datasets:
        c, w = read_clips(ds), read_windows(ds)
        clips += c
        parts.append(w)
        sources.append(
            {
                "dataset": str(ds.resolve()),
                "videos": len({x.source for x in c} | set(w.source)),
                "face_clips": len(c),
                "gesture_windows": int(w.has_body.sum()) if w.n else 0,
                "manifest_sha256": sha256(ds / "manifest.json"),
            }  # fmt: skip
        )
    windows = _concat_windows(parts)
    if not clips and not (windows.n and windows.has_body.any()):
        raise InputError(
            "nothing to bake: no face clip of at least "
            f"{cfg.filters.min_s:g} s and no (audio, motion) window with the body in view (--min-len, longer videos)"
        )
    provenance = {
        "kind": "user",
        "what": "motion parameters only: ARKit-named expression weights + head rotation per frame (text2face), "
        "55-joint upper body + hands and 28 speech features per frame (gesture); no pixels, audio or identity",
        "licence": "the user's own: anima applies no licence filter to a library a user bakes (the built-in one "
        "keeps anima.library.sources' table)",
        "videos": len({s.get("path") for s in sources if "path" in s})
        + sum(s.get("videos", 0) for s in sources if "dataset" in s),
        "sources": sources,
        "capture": {"max_frames": max_frames, "min_clip_s": cfg.filters.min_s, "window": cfg.window, "hop": cfg.hop},
        "baked_with": f"anima {__version__} (`anima library build`)",
        "command": command,
        "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }

    def name_of(src: str) -> str:
        return str(Path(src).resolve()) if Path(src).exists() else str(src)

    if single:
        npz, _, prov = write_from_pairs(Path(out), clips, windows, name_of, provenance, sidecar=False)
        record_out_file(npz, "motion library")
        written = [npz]
    else:
        with OutputFolder(out, kind="library", command=command, inputs=inputs) as od:
            npz, meta, prov = write_from_pairs(od.file(builtin.FOLDER_FILE), clips, windows, name_of, provenance)
            od.file(meta.name)
            od.info = {k: prov[k] for k in ("videos", "face_clips", "gesture_windows", "gesture_seconds_distinct")}
            written = [npz, meta]
    return prov | {"notes": notes, "written": [str(p) for p in written], "seconds": round(time.perf_counter() - t0, 1)}
