"""The one writer of motion outputs: capture, text2face and gesture all write their result folder here.

:func:`write_motion_outputs` writes, into an :class:`anima.io.outdir.OutputFolder`:

=====================  ==========================================================  =======================
file                   what                                                        when
=====================  ==========================================================  =======================
``<name>.npz``         the tracked sequence (``anima.io.sequence``)                always, written first
``arkit.csv``          Live Link Face CSV (52 ARKit weights + head)                a face in some frame
``face.glb``           ICT face with 53 morph targets, animated                    a face in some frame
``body.bvh``           the body on the character's rig (metres, T-pose rest)       a body joint tracked
``avatar.glb``         the skinned character (body + face), one timeline           always
                       (standing at ease without a body)
``speech.wav``         the speech the motion goes with (offset 0 s)                the source has speech
``overlay.mp4``        the fitted mesh over the source video                       a face and a source
``mesh.mp4``           the fitted mesh alone                                       a face and a source
``face.mp4``           the animated neutral face (generated motion)                a face, no source
``skeleton_overlay``   2D joints over the source video (``.mp4``)                  a body and a source
``avatar.mp4``         the character, front and 3/4 views                          always
``info.json``          what made it (prompt, settings, notes, summary, avatar)     always
=====================  ==========================================================  =======================

Videos carry the source's audio track, else ``audio`` (the speech motion was made from). The sequence is
written first, then the exports and the videos side by side; a failing render loses nothing already computed
(every job runs to its end before the failure is raised), and every file is atomic.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from anima.core.clock import Stopwatch
from anima.core.occlusion import hand_over_face
from anima.export.avatar import OnCharacter, body_of, render_avatar_preview, write_avatar, write_speech
from anima.export.formats import export_arkit_csv, export_bvh, export_glb
from anima.facemodel.character import BUILDS
from anima.facemodel.neutral import MAX_REST, presented
from anima.io.atomic import write_json
from anima.io.outdir import OutputFolder
from anima.io.sequence import TrackedSequence, write_sequence
from anima.render.videos import render_videos


def write_motion_outputs(
    seq: TrackedSequence,
    out: OutputFolder,
    name: str = "capture.npz",
    source_video: str | None = None,
    audio: str | None = None,
    render: bool = True,
    info: dict | None = None,
    progress: bool = True,
    sw: Stopwatch | None = None,
    preset: str = "anima",
    body: str | None = None,
) -> dict[str, Path]:
    """Write the output set of ``seq`` (see the module table); returns ``{role: path}``. The exports (CSV,
    glTF, BVH, speech) are written on a thread beside the videos. ``sw``: a stopwatch given the stages
    ``write`` (the sequence, ``info.json``, and the exports when nothing is rendered) and ``render`` (the
    videos, with the exports beside them). ``body``: the character's build (``--body``,
    :data:`anima.facemodel.character.BUILDS`), recorded in the sequence (``meta["body"]``) so that its exports
    make the same character; None: the sequence's own, else the default."""
    sw = sw or Stopwatch()
    if body is not None:
        if body not in BUILDS:
            raise ValueError(f"unknown body {body!r}; one of {', '.join(BUILDS)}")
        seq.meta["body"] = body
    with sw("write"):
        files = {"sequence": write_sequence(seq, out.file(name))}  # first: everything else is made from it
    speech = _speech_source(seq, source_video, audio)
    face = bool(seq.tracked.any())
    body = body_of(seq) is not None
    exported: dict = {}
    on = OnCharacter(seq)  # the character's motion and face, made once for avatar.glb, body.bvh and avatar.mp4
    jobs = [({}, lambda: exported.update(_write_exports(seq, out, speech, info is not None, preset, on)))]
    if render and source_video is not None:  # one pass over the source: the fit over it, alone, the skeleton over it
        roles = {}
        if face:
            roles |= {"overlay_video": out.file("overlay.mp4"), "mesh_video": out.file("mesh.mp4")}
        if body and seq.body_image is not None:
            roles["skeleton_overlay_video"] = out.file("skeleton_overlay.mp4")
        if roles:
            jobs.append(
                (
                    roles,
                    lambda: render_videos(
                        seq,
                        source_video,
                        roles.get("overlay_video"),
                        roles.get("mesh_video"),
                        progress=progress,
                        audio=audio,
                        skeleton_path=roles.get("skeleton_overlay_video"),
                    ),
                )
            )
    elif render and face:
        fv = out.file("face.mp4")
        jobs.append(({"face_video": fv}, lambda: render_videos(seq, None, None, fv, progress=progress, audio=audio)))
    if render:
        av = out.file("avatar.mp4")
        jobs.append(
            ({"avatar_video": av}, lambda: render_avatar_preview(seq, av, audio=speech, progress=progress, on=on))
        )
    with sw("render" if len(jobs) > 1 else "write"):  # the exports are written beside the videos
        videos = run_renders(jobs)
    files.update(exported.get("files", {}))
    files.update(videos)
    if info is not None:
        with sw("write"):
            info = {**info, **({"avatar": exported["avatar"]} if exported.get("avatar") else {})}
            rest = presented(seq)[1]
            ref = (seq.meta.get("rest_face") or {}).get("from")
            if rest or ref:
                how = "anima.facemodel.neutral: each channel's " + (
                    f"median over the rest clip {ref} (--neutral)"
                    if ref
                    else f"10th percentile over the clip (at most {MAX_REST})"
                )
                info["rest_face"] = {"channels": rest, "how": how + ", taken out of every animation"}
            covered = hand_over_face(seq) & seq.tracked
            if covered.any():
                info["mouth_covered"] = {
                    "frames": int(covered.sum()),
                    "first_s": round(float(np.flatnonzero(covered)[0] / seq.fps), 2),
                    "how": "a hand over the lower face (anima.core.occlusion): the character's mouth eases to its "
                    "rest over 0.25 s and back, as for a lost face (the fit has no evidence there)",
                }
            files["info"] = write_json(out.file("info.json"), {**info, "files": {k: p.name for k, p in files.items()}})
    return files


def _write_exports(seq, out, speech: str | None, describe: bool, preset: str = "anima", on=None) -> dict:
    """The files made from the sequence, no videos: ``{"files": {role: path}, "avatar": what avatar.glb
    holds (when ``describe``)}``; ``on``: the sequence's :class:`OnCharacter`, shared with ``avatar.mp4``."""
    on = on or OnCharacter(seq)
    files = {}
    face = bool(seq.tracked.any())
    body = body_of(seq) is not None
    if face:
        files["arkit_csv"] = export_arkit_csv(seq, out.file("arkit.csv"))
        files["glb"] = export_glb(seq, out.file("face.glb"))
    if body:
        files["bvh"] = export_bvh(seq, out.file("body.bvh"), preset=preset, on=on)
    if speech is not None:
        files["speech"] = write_speech(speech, out.file("speech.wav"))
    avatar = write_avatar(seq, out.file("avatar.glb"), speech="speech.wav" if speech else None, preset=preset, on=on)
    files["avatar"] = out.path / "avatar.glb"
    return {"files": files, "avatar": avatar if describe else None}


def run_renders(jobs: list) -> dict[str, Path]:
    """Run the render calls of ``jobs`` ``[(roles, call)]`` in a thread pool: the rasterizer, OpenCV and the
    ffmpeg pipes release the GIL and each encoder is its own process, so the videos render side by side
    instead of one after another. Every job runs to its end; the first failure is raised afterwards (each
    video is atomic, so a failed one leaves nothing behind). One BLAS thread meanwhile. Returns the roles of
    the jobs that finished."""
    with threadpool_limits(1, user_api="blas"):  # small matrices: BLAS threads would only spin against the jobs
        if len(jobs) <= 1:
            for _, call in jobs:
                call()
            return {k: Path(v) for roles, _ in jobs for k, v in roles.items()}
        with ThreadPoolExecutor(max_workers=min(len(jobs), max(2, os.cpu_count() or 1))) as pool:
            futures = [(roles, pool.submit(call)) for roles, call in jobs]
            errors = [f.exception() for _, f in futures]
    for e in errors:
        if e is not None:
            raise e
    return {k: Path(v) for roles, _ in futures for k, v in roles.items()}


def _speech_source(seq: TrackedSequence, source_video: str | None, audio: str | None) -> str | None:
    """The file whose audio the motion goes with: ``audio`` (given speech), else the source video when the
    capture found speech in it."""
    if audio is not None:
        return audio if seq.meta.get("audio", {}).get("present", True) else None
    if source_video is not None and seq.meta.get("audio", {}).get("present"):
        return source_video
    return None
