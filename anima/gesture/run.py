"""``anima gesture``: speech -> 3D upper-body + hands gestures, by controllable k-NN search over a dataset's
(audio, motion) windows (optionally refined by the cGAN) or by the §4.4 generator (which also gives the face).
The result is a tracked sequence (``gesture.npz``) written by the one motion writer with its BVH and videos
(the speech muxed in), so ``anima info`` and ``anima export`` read it like a capture.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from anima.audio.features import read_audio, speech_features
from anima.audio.stress import find_stresses
from anima.core.clock import Stopwatch
from anima.core.contract import CHARACTER_FPS
from anima.dataset.windows import read_windows
from anima.errors import InputError
from anima.export.framing import generated_sequence
from anima.export.motion import write_motion_outputs
from anima.gesture.config import GestureConfig
from anima.gesture.control import parse_control, speed_steps, step_masks
from anima.gesture.database import distinct_seconds, from_dataset, from_library
from anima.gesture.face import fit_speech_face, talking_face
from anima.gesture.features import N_STEP, audio_features
from anima.gesture.keywords import keyword_masks, parse_keyword, union
from anima.gesture.knn import search
from anima.gesture.post import finish_knn, joins_of, one_skeleton, to_rate
from anima.gesture.strokes import StrokeTerm, alignment, place_strokes
from anima.io.mapped import cache_key, file_stamp, mapped_arrays
from anima.io.outdir import OutputFolder, check_out_dir
from anima.library import builtin

SEED_SEARCH = GestureConfig(stroke_rank=0.0, stroke_shift=0.0)
"""The seed's search: :class:`GestureConfig` with no strokes placed on the speech's stresses (the command's
defaults place them)."""


def synthesize(
    speech_path: str,
    db,
    cfg: GestureConfig = SEED_SEARCH,
    refiner=None,
    keyword_dbs: dict | None = None,
    sw: Stopwatch | None = None,
) -> tuple[np.ndarray, dict]:
    """k-NN search (and, with ``refiner`` from ``anima.gesture.refine.load_refiner``, the cGAN refinement)
    at the database's frame rate, as ``cfg`` sets it (its ``k``, ``control``, ``init``, ``seed``, ``keyword``,
    ``blend``, ``no_repeat_s``, ``control_ends_only``, ``stroke_rank``, ``stroke_shift``). ``cfg.keyword``
    switches the search to ``keyword_dbs[word]`` (MatchDB) while the word is spoken. ``blend``: inertialized
    joins (:mod:`anima.gesture.post`); the output is always re-posed on the database's one skeleton. Strokes on
    the speech's stresses: :mod:`anima.gesture.strokes` (off in the default, :data:`SEED_SEARCH`). ``sw``: a
    stopwatch given the stages ``speech``, ``search`` and ``post``."""
    controls = [parse_control(c) for c in cfg.control]
    keywords = [parse_keyword(k) for k in cfg.keyword]
    k, init, seed, blend, no_repeat_s = cfg.k, cfg.init, cfg.seed, cfg.blend, cfg.no_repeat_s
    stroke_rank, stroke_shift, control_every_frame = cfg.stroke_rank, cfg.stroke_shift, not cfg.control_ends_only
    sw = sw or Stopwatch()
    fps = db.fps
    with sw("speech"):
        x, feats, notes = _read(speech_path, fps)
        stress = find_stresses(x) if stroke_rank > 0 or stroke_shift > 0 else None
    T = len(feats.features)
    F_in = audio_features(feats.features)
    if init == "mean":
        p0 = db.P.reshape(-1, db.P.shape[-1]).mean(0)
    elif init == "random":
        rng = np.random.default_rng(seed)
        p0 = db.P[rng.integers(db.M), rng.integers(db.P.shape[1])]
    else:
        raise InputError(f"unknown --init {init!r}: mean or random")
    n_steps = -(-T // N_STEP)
    part = None
    if keywords or keyword_dbs:
        db, part, names = union(db, keyword_dbs or {})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        masks, report = step_masks(
            db, controls or [], n_steps, N_STEP / fps, None if part is None else part == 0, control_every_frame
        )
    notes += [str(w.message) for w in caught]
    used = None
    if part is not None:
        masks, used = keyword_masks(db, part, names, keywords or [], n_steps, N_STEP / fps, masks if controls else None)
    if T > db.M * db.P.shape[1]:
        notes.append("the speech is longer than the database: database windows are reused")
    with sw("search"):
        stroke = None
        if stress is not None and stroke_rank > 0:
            stroke = StrokeTerm.of(db.stroke_dist, stress.frames(fps), n_steps, N_STEP, stroke_rank)
        G, picks = search(db, F_in, k, p0, masks, no_repeat_steps=round(no_repeat_s * fps / N_STEP), stroke=stroke)
    with sw("post"):
        raw = speed_steps(controls or [], n_steps, N_STEP / fps)
        J = finish_knn(G, picks, db.bone_lengths, N_STEP, blend=blend, raw_steps=raw)
        if refiner is not None:  # the refiner works on the blended output, and keeps the one skeleton
            J = one_skeleton(refiner.refine(feats.features[: len(J)], J), db.bone_lengths)
        placed = None
        if stress is not None and stroke_shift > 0:  # a speed control's steps keep their timing
            keep = [(i * N_STEP, (i + 1) * N_STEP) for i in sorted(raw)]
            J, placed = place_strokes(J, stress.frames(fps), fps, stroke_shift, keep=keep)
            J = one_skeleton(J, db.bone_lengths)
    joins = joins_of(picks, N_STEP)
    info = {
        "frames": len(G),
        "joins_s": [round(t / fps, 3) for t in joins],
        "distinct_windows": len({m for m, _ in picks}),
        "blended": blend,
        "fps": fps,
        "controls": report,
        "notes": notes,
        "refined": refiner is not None,
        "picks": [(int(m), int(r)) for m, r in picks],
        "speech_features": feats.features[: len(J)],  # (the talking face's input; not written to info.json)
    }
    if used is not None:
        info["database_per_step"] = used
    if stress is not None:
        a = alignment(J, stress.times_s, fps)
        info["strokes"] = {
            "stresses": len(stress.times_s),
            "rank_weight": stroke_rank,
            "max_shift_frames": stroke_shift,
            "moved": placed["moved"] if placed else 0,
            "mean_shift_frames": placed["mean_shift_frames"] if placed else 0.0,
            "stresses_with_a_stroke_within_0.1_s": round(a.get("stresses_hit", float("nan")), 3),
            "strokes_per_s": round(a["strokes_per_s"], 2),
        }
    return J, info


FACE_NOTE = "the jaw on the speech's envelope, the mouth's other channels on the jaw as in the dataset's faces; blinks"


def talking_face_of(db: str, S: np.ndarray, fps: float, seed: int = 0) -> tuple[np.ndarray, str | None]:
    """A talking face ``[T, 56]`` for speech features ``S`` (:mod:`anima.gesture.face`), its mouth model from
    the dataset's captured faces (through a memory-mapped cache keyed on the dataset's manifest); a note when
    the dataset has no captured face."""
    manifest = Path(db) / "manifest.json"
    code = file_stamp(Path(__file__).parent / "face.py")

    def make():
        m = fit_speech_face(read_windows(db).face)
        return m if m is not None else {"none": np.zeros(1)}

    key = cache_key(file_stamp(manifest) if manifest.is_file() else db, code)
    model = mapped_arrays("gesture_face", key, make)
    if "none" in model:
        note = "the dataset has no captured talking face: the mouth follows an adult's default jaw range"
        return talking_face(S, fps, None, seed), note
    return talking_face(S, fps, dict(model), seed), None


MAX_SPEECH_S = 600.0
"""The longest speech ``anima gesture`` takes (10 min, as ``anima text2face``'s longest clip): without videos
that is about 8 s and 0.8 GB; a longer file is refused before the search, after decoding at most this much (its
--help states it)."""
LIBRARY_NO_REPEAT_MAX_S = 20.0
"""With a motion library, the no-repeat span grows to half its distinct seconds, up to this
(:class:`GestureConfig`'s ``no_repeat_s``)."""


def library_no_repeat_s(db, no_repeat_s: float) -> float:
    """The no-repeat span for a motion library's database: ``no_repeat_s``, raised to half the library's distinct
    seconds (variants counted as their source) up to :data:`LIBRARY_NO_REPEAT_MAX_S`; 0 stays 0."""
    if no_repeat_s <= 0:
        return no_repeat_s
    return max(no_repeat_s, min(LIBRARY_NO_REPEAT_MAX_S, distinct_seconds(db) / 2))


OUTPUT_FPS = CHARACTER_FPS
"""The rate of every file ``anima gesture`` writes (the character's, as text2face's): the models work at
15 frames a second (the seed's), and their motion is carried to 30 by a cubic through its frames."""


def read_speech(speech_path: str, fps: float):
    """Speech features at ``fps`` (any audio rate, resampled to 16 kHz mono; at most :data:`MAX_SPEECH_S`), and
    notes for the user."""
    _, feats, notes = _read(speech_path, fps)
    return feats, notes


def _read(speech_path: str, fps: float):
    """``(samples at 16 kHz, features, notes)``: :func:`read_speech` with the samples."""
    x = read_audio(speech_path, max_s=MAX_SPEECH_S)
    feats = speech_features(x, fps)
    if len(feats.features) < N_STEP:
        raise InputError(f"speech is {len(x) / 16000:.2f} s long: at least {N_STEP / fps:.2f} s is needed")
    notes = (
        ["the speech is silent (below -60 dBFS): gestures follow the database's quiet moments"] if feats.silent else []
    )
    return x, feats, notes


def generate(speech_path: str, gen) -> tuple[np.ndarray, np.ndarray, dict]:
    """The §4.4 generator (``anima.gesture.generator.load_generator``): speech -> joints [T, 55, 3] and face
    [T, 56] (53 ICT expression weights + head rotation) at the generator's frame rate, one pass for any
    length."""
    feats, notes = read_speech(speech_path, gen.fps)
    if feats.silent:
        notes = ["the speech is silent (below -60 dBFS): expect a near-rest pose and a closed mouth"]
    J, face = gen.generate(feats.features)
    return J, face, {"frames": len(J), "fps": gen.fps, "notes": notes, "model": gen.cfg.kind}


def run(
    speech: str,
    out: str | Path,
    cfg: GestureConfig,
    db: str | None = None,
    generator: str | None = None,
    refiner: str | None = None,
    render: bool = True,
    command: str | None = None,
    progress: bool = False,
    preset: str = "anima",
    library: str | None = None,
    body: str | None = None,
) -> dict:
    """``anima gesture``: check every input, then search (``db``, or the motion ``library``: ``anima library
    build``'s, default the built-in one) or generate (``generator``) and write the result folder (``body``: the
    character's build, :data:`anima.facemodel.character.BUILDS`; default neutral). Returns the
    run's info (notes, controls, files written, and ``time_s``: seconds per stage, start-up included)."""
    sw = Stopwatch()
    inputs = [speech, db, generator, refiner, library, *(spec.partition("=")[2] for spec in cfg.keyword_db)]
    check_out_dir(out, inputs=inputs)  # a user's folder is refused before anything is read
    if not Path(speech).is_file():
        raise InputError(f"speech file not found: {speech}")
    for spec in cfg.control:  # a bad --control or --keyword is refused before anything is read
        parse_control(spec)
    for spec in cfg.keyword:
        parse_keyword(spec)
    if generator and (cfg.control or refiner or cfg.keyword):
        raise InputError("--control, --refiner and --keyword apply to the k-NN search (--db), not to --generator")
    if generator and db:
        raise InputError("give --db DATASET (k-NN search) or --generator CHECKPOINT, not both")
    if library and (db or generator):
        raise InputError("--library is the k-NN search's database instead of --db's, and not for --generator")
    lib_path = None if db or generator else builtin.resolve(library)  # a bad --library fails before any work
    kw_folders = {}
    for spec in cfg.keyword_db:
        word, sep, folder = spec.partition("=")
        if not sep or not word or not folder:
            raise InputError(f"--keyword-db {spec!r}: expected WORD=DATASET")
        if not Path(folder).exists():
            raise InputError(f"--keyword-db {spec!r}: no dataset at {folder}")
        kw_folders[word.lower()] = folder
    read_audio(speech, sr=8000, max_s=MAX_SPEECH_S)  # a cheap probe: no audio, or too long, before anything loads
    with OutputFolder(out, kind="gesture", command=command, inputs=inputs) as od:
        if generator:
            from anima.gesture.generator import load_generator  # lazy: torch

            with sw("load"):
                gen = load_generator(generator)
            with sw("generate"):
                J, face, info = generate(speech, gen)
        else:
            ref = None
            with sw("load"):
                if refiner:  # checkpoints first: a bad one fails before the database loads
                    from anima.gesture.refine import load_refiner  # lazy: torch

                    ref = load_refiner(refiner)
                match_db = from_dataset(db, None if cfg.all_splits else "train") if db else None
                if match_db is None:
                    match_db = from_library(library, cfg.variants)
                kw_dbs = {w: from_dataset(f, None) for w, f in kw_folders.items()}
            no_repeat = cfg.no_repeat_s
            if not db and no_repeat > 0:  # a small library: keep its stretches apart for longer
                no_repeat = library_no_repeat_s(match_db, no_repeat)
            J, info = synthesize(speech, match_db, replace(cfg, no_repeat_s=no_repeat), ref, kw_dbs, sw)
            with sw("face"):
                S = info.pop("speech_features")
                if db:
                    face, face_note = talking_face_of(db, S, info["fps"], cfg.seed)
                else:
                    face, face_note = talking_face(S, info["fps"], builtin.load(lib_path).speech_face, cfg.seed), None
            info = {k: v for k, v in info.items() if k != "picks"} | {"database_windows": match_db.M}
            info["no_repeat_s"] = round(no_repeat, 2)
            info["database"] = str(db) if db else builtin.summary(lib_path)
            if not db and cfg.variants:
                info["library_variants"] = "mirrored and speed-varied (1/1.15x, 1.15x) copies of its windows"
            info["notes"] = info.get("notes", []) + ([face_note] if face_note else [])
            info["face"] = FACE_NOTE
        info["motion_fps"], info["fps"] = info["fps"], OUTPUT_FPS  # the character's rate, not the models'
        J, face = to_rate(J, info["motion_fps"], OUTPUT_FPS), to_rate(face, info["motion_fps"], OUTPUT_FPS)
        info["frames"] = len(J)
        seq = generated_sequence(
            info["fps"],
            face=face,
            body=J,
            meta={
                "generated_by": "anima gesture",
                "speech": str(speech),
                **{k: v for k, v in info.items() if k != "notes"},
            },
        )
        od.info = info
        files = write_motion_outputs(
            seq, od, "gesture.npz", audio=str(speech), render=render, info=info, progress=progress, sw=sw,
            preset=preset, body=body,
        )  # fmt: skip
    return info | {"written": [str(p) for p in files.values()], "time_s": sw.report()}
