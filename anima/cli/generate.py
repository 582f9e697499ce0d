"""``anima text2face`` (a sentence -> facial motion) and ``anima gesture`` (speech -> gestures)."""

from __future__ import annotations

from dataclasses import dataclass, field

from anima.cli.common import Body, Json, Rig, add_args, command_line, emit, notes, time_split
from anima.cli.options import add_options, config_from_args
from anima.core.events import EMOTIONS, VOCABULARY
from anima.gesture import run as gesture
from anima.gesture.config import GestureConfig
from anima.text2face import run as text2face
from anima.text2face.config import PromptConfig

PROMPT_OPTIONS = ["length", "seconds", "seed", "method", "with_builtin"]
GESTURE_OPTIONS = [
    "k",
    "init",
    "seed",
    "all_splits",
    "control",
    "control_ends_only",
    "keyword",
    "keyword_db",
    "no_repeat_s",
    "stroke_rank",
    "stroke_shift",
    "variants",
    "blend",
]

# the actions a prompt may name (anima.core.events), for --help
ACTIONS = [n for n, e in VOCABULARY.items() if e.parsed and e.phrases and n not in EMOTIONS and not e.unplaced]


@dataclass
class PromptIn:
    prompt: str = field(default="", metadata={"positional": True, "metavar": "prompt"})
    """e.g. "a woman smiles, then blinks"; at most 2,000 characters and 100 events"""
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """output folder"""


@dataclass
class PromptMore:
    checkpoint: str | None = field(default=None, metadata={"metavar": "CHECKPOINT"})
    """a checkpoint from `anima train text2face` (--method model)"""
    db: str | None = field(default=None, metadata={"metavar": "DB"})
    """dataset folder from `anima dataset build`: the timeline method's captured motion, instead of the built-in
    library's (with --with-builtin, as well)"""
    library: str | None = field(default=None, metadata={"metavar": "LIBRARY"})
    """a motion library from `anima library build` (its folder or .npz): its clips instead of the built-in
    library's (with --db --with-builtin: beside the dataset's)"""
    no_video: bool = False
    """skip the MP4 render"""


@dataclass
class SpeechIn:
    speech: str = field(default="", metadata={"positional": True, "metavar": "speech"})
    """speech audio (WAV/MP3/FLAC or a video's audio; resampled to 16 kHz), at most 10 min"""
    db: str | None = field(default=None, metadata={"metavar": "DB"})
    """dataset folder from `anima dataset build` (k-NN search); default: the built-in motion library"""
    library: str | None = field(default=None, metadata={"metavar": "LIBRARY"})
    """a motion library from `anima library build` (its folder or .npz): its windows instead of the built-in
    library's"""
    generator: str | None = field(default=None, metadata={"metavar": "GENERATOR"})
    """instead of the search: a section 4.4 generator checkpoint from `anima train gesture --model generator`"""
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """output folder"""


@dataclass
class SpeechMore:
    refiner: str | None = field(default=None, metadata={"metavar": "REFINER"})
    """cGAN refiner checkpoint from `anima train gesture`"""
    no_render: bool = False
    """skip the videos"""


def register(sub) -> None:
    tf = sub.add_parser(
        "text2face",
        help="generate facial motion from a sentence",
        description="Seed 000: a sentence -> 3D facial motion (ICT expression weights + head "
        "rotation, 30 fps). Writes into --out: motion.npz (a tracked sequence: `anima info`, "
        "`anima export`), face.mp4, arkit.csv (Live Link Face), face.glb, info.json and "
        "manifest.json. By default the timeline method: the prompt is read as events ("
        f"{', '.join(ACTIONS)}, and the emotions {', '.join(EMOTIONS)}; 'then', 'while', 'twice', "
        "'slightly', 'left eye', 'without') made from "
        "captured motion: the built-in library (no dataset needed) or --db's; info.json says how the "
        "prompt was read and what was not understood. --method model (or --checkpoint): the seed "
        "model (the shipped checkpoint unless --checkpoint is given).",
    )
    add_args(tf, PromptIn)
    add_options(tf, PromptConfig, PROMPT_OPTIONS)
    add_args(tf, PromptMore, Rig, Body, Json)
    tf.set_defaults(func=cmd_text2face)

    ge = sub.add_parser(
        "gesture",
        help="speech to 3D upper-body + hand gestures (controllable k-NN search)",
        description="Seed 004 Algorithm 1: every 8 frames (15 fps), the database windows of the "
        "dataset's (audio, motion) pairs (--db), of a motion library (--library, from `anima library build`) or of "
        "the built-in library are pre-selected by pose continuity and ranked by audio "
        "(cosine) + pose rank, + a stroke rank where the speech has stressed syllables; the k-th best continues "
        "the motion, which is then re-timed by up to 2 frames so its strokes meet the stresses. Controls "
        "restrict the search "
        "without retraining, in time ranges. With --generator, the §4.4 generator instead (it also "
        "gives the face). Writes into --out: gesture.npz (a tracked sequence), body.bvh, "
        "avatar.glb (the rig), speech.wav, avatar.mp4 (with the speech), with the generator also "
        "arkit.csv, face.glb, face.mp4; info.json and manifest.json. --json adds the time per stage.",
    )
    add_args(ge, SpeechIn)
    add_options(ge, GestureConfig, GESTURE_OPTIONS)
    add_args(ge, SpeechMore, Rig, Body, Json)
    ge.set_defaults(func=cmd_gesture)


def cmd_text2face(a) -> int:

    info = text2face.run(
        a.prompt,
        a.out,
        config_from_args(PromptConfig, a, PROMPT_OPTIONS),
        a.checkpoint,
        video=not a.no_video,
        progress=not a.json,
        command=command_line(a),
        db=a.db,
        preset=a.rig,
        library=a.library,
        body=a.body,
    )
    notes(info["warnings"], "warning")
    return emit(
        info, a.json, lambda i: f"{i['frames']} frames in {i['sampling_s']:.2f} s; wrote " + ", ".join(i["written"])
    )


def cmd_gesture(a) -> int:
    info = gesture.run(
        a.speech,
        a.out,
        config_from_args(GestureConfig, a, GESTURE_OPTIONS),
        db=a.db,
        generator=a.generator,
        refiner=a.refiner,
        render=not a.no_render,
        command=command_line(a),
        progress=not a.json,
        preset=a.rig,
        library=a.library,
        body=a.body,
    )
    notes(info["notes"])
    return emit(info, a.json, lambda i: "wrote " + ", ".join(i["written"]) + "\n  time: " + time_split(i["time_s"]))
