"""``anima text2face``: a sentence -> a result folder, by the timeline method (the dataset's captured segments,
:mod:`anima.text2face.compose`) or the seed model (:class:`anima.text2face.generate.Generator`). The motion is
written by the one motion writer (``motion.npz``, a tracked-sequence file that ``anima info`` / ``anima export``
read, ``face.mp4``, ``arkit.csv``, ``avatar.glb``, ``info.json``)."""

from __future__ import annotations

import time
import warnings
from pathlib import Path

from anima.core.contract import TEXT_FPS
from anima.dataset.storage import check_dataset
from anima.dataset.windows import read_clips
from anima.errors import InputError
from anima.export.framing import generated_sequence
from anima.export.motion import write_motion_outputs
from anima.io.outdir import OutputFolder
from anima.library import builtin
from anima.text2face.compose import DEFAULT_FRAMES, Library, compose
from anima.text2face.config import PromptConfig
from anima.text2face.encoders import clean_prompt, get_encoder, require_prompt
from anima.text2face.prompt import parse


def run(
    prompt: str,
    out: str | Path,
    cfg: PromptConfig | None = None,
    checkpoint: str | Path | None = None,
    video: bool = True,
    progress: bool = True,
    command: str | None = None,
    db: str | Path | None = None,
    preset: str = "anima",
    library: str | Path | None = None,
    body: str | None = None,
) -> dict:
    """``anima text2face``: a sentence -> a result folder (``motion.npz``, ``arkit.csv``, ``face.glb``,
    ``face.mp4``, ``info.json``; :func:`anima.export.motion.write_motion_outputs`). ``--out`` is checked
    before the model loads. ``library``: a motion library from ``anima library build`` in place of the built-in
    one. ``body``: the character's build (:data:`anima.facemodel.character.BUILDS`; default neutral). Returns the
    run's info (frames, fps, seed, sampling time, warnings, files)."""
    cfg = cfg or PromptConfig()
    seed = cfg.seed
    require_prompt(prompt)
    parse(prompt)  # a prompt the planner refuses (an event 10^12 times) is refused by both methods
    method = cfg.method
    if method == "auto":
        method = "model" if checkpoint else "timeline"
    if method == "timeline":
        if checkpoint:
            raise InputError("--checkpoint is for --method model; the timeline method reads --db")
        if cfg.with_builtin and not db:
            raise InputError("--with-builtin adds the built-in library to --db's clips: give --db too")
        if library and db and not cfg.with_builtin:
            raise InputError("--db replaces the library: give --db or --library (or both with --with-builtin)")
        lib = builtin.resolve(library)  # a bad --library fails before any work
        return _timeline(prompt, out, cfg, db, video, progress, command, preset, lib, body)
    if db or library:
        raise InputError("--db and --library are for the timeline method; --method model reads --checkpoint")
    from anima.text2face.generate import Generator  # lazy: torch

    with OutputFolder(out, kind="text2face", command=command, inputs=[checkpoint]) as od:
        gen = Generator(checkpoint)
        n = gen.check_length(int(round(cfg.seconds * gen.fps)) if cfg.seconds else cfg.length or DEFAULT_FRAMES)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            text = clean_prompt(prompt, gen.encoder)
        t = time.perf_counter()
        motion = gen.generate([text], n, seed)[0]
        info = {
            "prompt": text,
            "frames": n,
            "fps": gen.fps,
            "seed": seed,
            "checkpoint": str(gen.path),
            "kind": gen.kind,
            "method": "model",
            "sampling_s": round(time.perf_counter() - t, 3),
            "warnings": [str(w.message) for w in caught],
        }
        seq = generated_sequence(gen.fps, face=motion, meta={"generated_by": "anima text2face", **info})
        od.info = info
        files = write_motion_outputs(
            seq, od, "motion.npz", render=video, info=info, progress=progress, preset=preset, body=body
        )
    return info | {"written": [str(p) for p in files.values()]}


MAX_TIMELINE_FRAMES = 18_000
"""The timeline method's longest clip (10 min at the text rate): --length/--seconds and the length a prompt's
events imply alike (``anima text2face --help`` states it)."""


def _library(db, with_builtin: bool, lib: Path = builtin.LIBRARY) -> Library:
    """The timeline method's clips: ``--db``'s (all its splits: the user's own clips), the motion library's
    (``lib``: the built-in one, or ``--library``'s) when there is no ``--db`` or ``--with-builtin`` asks for
    both."""
    motions, events, sources = [], [], []
    if db:
        clips = read_clips(db)
        if clips and abs(clips[0].fps - TEXT_FPS) > 1e-6:
            raise InputError(f"{db}: clips at {clips[0].fps} fps; the timeline method works at {TEXT_FPS}")
        motions += [c.motion for c in clips]
        events += [c.events for c in clips]
        sources += [c.clip_id for c in clips]
    if not db or with_builtin:
        b = builtin.load(lib)
        if abs(b.face_fps - TEXT_FPS) > 1e-6 and b.face_motion:
            raise InputError(f"{lib}: clips at {b.face_fps} fps; the timeline method works at {TEXT_FPS}")
        motions += b.face_motion
        events += b.face_events
        sources += [f"{'built-in' if lib == builtin.LIBRARY else 'library'}:{c}" for c in b.face_clip]
    return Library.from_clips(motions, events, sources, TEXT_FPS)


def _timeline(
    prompt, out, cfg: PromptConfig, db, video: bool, progress: bool, command, preset: str = "anima",
    lib: Path = builtin.LIBRARY, body: str | None = None,
) -> dict:  # fmt: skip
    """The timeline method (:mod:`anima.text2face.compose`): the prompt's events from the dataset's captured
    segments. ``info.json`` records how the prompt was read, what was not understood, and where every event's
    motion comes from."""
    if db:
        check_dataset(db)
    fps = TEXT_FPS
    n = int(round(cfg.seconds * fps)) if cfg.seconds else cfg.length
    if n is not None and n > MAX_TIMELINE_FRAMES:
        raise InputError(
            f"{n} frames asked: the timeline method makes at most {MAX_TIMELINE_FRAMES} "
            f"({MAX_TIMELINE_FRAMES / fps / 60:.0f} min)"
        )
    with OutputFolder(
        out, kind="text2face", command=command, inputs=[db, None if lib == builtin.LIBRARY else lib]
    ) as od:
        clips = _library(db, cfg.with_builtin, lib)
        t = time.perf_counter()
        plan = parse(prompt)
        if not plan.events and plan.unknown:  # words the lexicon lacks: try the sentence encoder
            plan = parse(prompt, get_encoder("minilm"))
        motion, record = compose(plan, clips, n, cfg.seed, max_frames=MAX_TIMELINE_FRAMES)
        info = {
            "prompt": plan.text,
            "frames": len(motion),
            "fps": fps,
            "seed": cfg.seed,
            "method": "timeline",
            "dataset": str(db) if db else None,
            "library": ("--db and " if db else "") + builtin.summary(lib) if (not db or cfg.with_builtin) else str(db),
            "understood": [
                {k: v for k, v in vars(e).items() if k != "words"} | {"from_words": e.words} for e in plan.events
            ],
            "excluded": plan.excluded,
            "paraphrased": plan.paraphrased,
            "not_understood": list(dict.fromkeys(plan.unknown)),
            "sampling_s": round(time.perf_counter() - t, 3),
            "timeline": record,
            "warnings": plan.notes + ([] if record["all_found"] else ["not every event reads back with the detectors"]),
        }
        seq = generated_sequence(fps, face=motion, meta={"generated_by": "anima text2face --method timeline"})
        od.info = info
        files = write_motion_outputs(
            seq, od, "motion.npz", render=video, info=info, progress=progress, preset=preset, body=body
        )
    return info | {"written": [str(p) for p in files.values()]}
