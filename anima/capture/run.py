"""``anima capture``: a video -> a result folder (the tracked sequence and everything people look at and use),
through the one motion writer (:func:`anima.export.motion.write_motion_outputs`)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from anima.audio.features import read_audio
from anima.capture.config import CaptureConfig
from anima.capture.pipeline import Timings, capture_video
from anima.core.clock import Stopwatch
from anima.core.ground import runs
from anima.core.world import LOST_S, lost_runs
from anima.errors import InputError
from anima.export.avatar import body_of, legs_of
from anima.export.motion import write_motion_outputs
from anima.facemodel.neutral import MAX_NEUTRAL, is_captured, not_neutral, reference_rest
from anima.io.outdir import OutputFolder
from anima.io.sequence import read_sequence
from anima.io.validate import input_file
from anima.io.video import probe_video
from anima.pose3d.config import default_checkpoint
from anima.track import get

MIN_REST_S = 0.5
"""A ``--neutral`` clip needs a face on at least this long."""


def check_capture_inputs(
    cfg: CaptureConfig, video: str, audio: str | None = None, audio_optional: bool = False, neutral: str | None = None
) -> None:
    """Fail before tracking on what would fail after it: an unreadable video, ``--audio`` (unless
    ``audio_optional``) or ``--neutral`` clip, a lifter run without a body, a bad checkpoint, an unknown or
    uninstalled tracker."""
    probe_video(input_file(video, "video"))
    get(cfg.tracker).check()
    if neutral is not None:
        _neutral_source(neutral)
    if audio is not None and not audio_optional:
        try:
            read_audio(input_file(audio, "--audio file"), sr=8000)
        except InputError as e:
            raise InputError(f"--audio: {e} (pass --audio-optional to capture the motion without it)") from None
    if cfg.body_3d == "lifter" and cfg.face_only:
        raise InputError("--body-3d lifter needs the body: drop --face-only")
    if cfg.body_3d == "lifter":
        from anima.pose3d.train import load_checkpoint  # lazy: torch

        load_checkpoint(Path(cfg.pose_model) if cfg.pose_model else default_checkpoint())


def _neutral_source(path: str):
    """``--neutral``'s clip checked (a readable video) or read (a captured sequence file): the sequence, or None
    for a video."""
    p = input_file(path, "--neutral clip")
    if p.suffix.lower() == ".npz":
        seq = read_sequence(p, landmarks=False)
        if not is_captured(seq.meta):
            raise InputError(f"--neutral: {p} is a generated sequence; give a clip (or capture.npz) of the person")
        return seq
    try:
        probe_video(p)
    except InputError as e:
        raise InputError(f"--neutral: {e}") from None
    return None


def neutral_reference(path: str, cfg: CaptureConfig, progress: bool = True) -> dict[str, float]:
    """The person's rest face from ``path``, a clip (captured here with ``cfg``'s trackers, no files written)
    or a ``capture.npz`` of them at rest: :func:`anima.facemodel.neutral.reference_rest`. A clip with under
    :data:`MIN_REST_S` of face is refused."""
    seq = _neutral_source(path)
    if seq is None:
        seq = capture_video(path, cfg, progress=progress)
    if seq.tracked.sum() < MIN_REST_S * seq.fps:
        raise InputError(f"--neutral: no face in {path} (a face on {int(seq.tracked.sum())} frames; it needs "
                         f"{MIN_REST_S:g} s)")  # fmt: skip
    rest = reference_rest(seq.expression, list(seq.expr_names), seq.tracked)
    strong = not_neutral(rest)
    if strong:
        shown = ", ".join(f"{n} {v:.2f}" for n, v in strong[:3])
        raise InputError(f"--neutral: {path} is not a face at rest ({shown}; a rest stays under {MAX_NEUTRAL:g}): give "
                         "a take of the person relaxed")  # fmt: skip
    return rest


def lost_warnings(seq) -> list[str]:
    """The face, a hand or a leg the clip loses for more than a second, said with its frames (the character
    holds it and blends it back: ``anima.core.world.lost_runs``; the face eases to its rest and back)."""
    out = [f"face not seen for {(b - a) / seq.fps:.1f} s (frames {a}-{b - 1}): the character's face rests, then "
           "blends back" for a, b in runs(~seq.tracked) if seq.tracked.any() and b - a > LOST_S * seq.fps]  # fmt: skip
    body = body_of(seq)
    if body is None:
        return out
    lost = lost_runs(body, legs_of(seq), seq.fps)
    return out + [f"{r['part']} not seen for {r['seconds']:.1f} s (frames {r['frames'][0]}-{r['frames'][1]}): the "
                  "character holds it, then blends it back" for r in lost]  # fmt: skip


def run(
    video: str,
    out: str | Path,
    cfg: CaptureConfig | None = None,
    audio: str | None = None,
    render: bool = True,
    progress: bool = True,
    command: str | None = None,
    audio_optional: bool = False,
    preset: str = "anima",
    neutral: str | None = None,
    body: str | None = None,
) -> dict:
    """Capture ``video`` into ``out``; returns the sequence summary with the capture speed, the total time,
    the files written and the warnings. ``neutral``: a clip (or ``capture.npz``) of the same person at rest,
    whose face is taken as the rest (:func:`neutral_reference`) instead of the clip's own estimate. ``body``: the
    character's build (:data:`anima.facemodel.character.BUILDS`; default neutral)."""
    cfg = cfg or CaptureConfig()
    od = OutputFolder(out, kind="capture", command=command, inputs=[video, audio, cfg.pose_model, neutral])
    check_capture_inputs(cfg, video, audio, audio_optional, neutral)
    rest = None if neutral is None else neutral_reference(neutral, cfg, progress)
    sw = Stopwatch()
    with od:
        tm = Timings()
        t0 = time.perf_counter()
        with sw("capture"):
            seq = capture_video(video, cfg, audio=audio, progress=progress, timings=tm)
        if isinstance(seq.meta.get("source"), dict):  # absolute: `anima view` finds it from any folder
            seq.meta["source"]["path"] = os.path.abspath(video)
        if rest is not None:
            seq.meta["rest_face"] = {"channels": rest, "from": str(neutral)}
        seq.meta["posture"] = cfg.posture
        s = seq.summary()
        s["capture_fps"] = round(tm.frames / max(tm.decode_track_s + tm.fit_s, 1e-9), 1)
        s["warnings"] = seq.meta.get("source", {}).get("warnings", []) + lost_warnings(seq)
        od.info = s
        files = write_motion_outputs(
            seq,
            od,
            "capture.npz",
            source_video=video,
            audio=audio,
            render=render,
            info=s,
            progress=progress,
            sw=sw,
            preset=preset,
            body=body,
        )
    return s | {
        "total_s": round(time.perf_counter() - t0, 2),
        "time_s": sw.report(),
        "outputs": [str(p) for p in files.values()],
    }
