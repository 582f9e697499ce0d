"""The evaluations' settings (light: no torch, no MediaPipe): one dataclass per evaluation, whose fields are the
options of ``anima eval NAME`` (:mod:`anima.cli.options`; a field's docstring is its help). The registry
(:mod:`anima.eval.registry`) pairs each with its runner."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

HELDOUT_PROMPTS = Path(__file__).parent / "prompts" / "text2face_heldout3.json"
"""The held-out prompt suite (third edition): written and frozen before any method ran on it, run once, by the
final ``anima eval all``; its result is reported whatever it is and never used to change anything. After a
release it joins the development suites and a new one is written (the protocol: docs/text2face.md). The second
edition, ``text2face_heldout.json``, was run three times and is a development suite now."""
HELDOUT_SHA256 = "dfa801432f8f01f0106a314263bd49798120b796ed38f1942c4922148c83dfda"
"""The held-out suite's file hash, written here when it was frozen (2026-12-06)."""
FROZEN_SUITES = {HELDOUT_PROMPTS.name: HELDOUT_SHA256}
"""Prompt suites frozen by their hash (file name -> sha256): the evaluation refuses a file of that name whose
content differs (:func:`anima.eval.text2face.prompts.load_suite`)."""
DEV2_PROMPTS = Path(__file__).parent / "prompts" / "text2face_dev2.json"
"""The second development suite: 40 prompts written after the first suite (its judge failures were seen before
the round that fixed smiles, frowns and shakes, so its scores are development scores)."""


@dataclass
class LandmarksEval:
    per_image: bool = False
    """Include per-image rows."""


@dataclass
class StabilityEval:
    clips: list = field(default_factory=list, metadata={"positional": True, "metavar": "CLIP"})
    """Videos (default: the shared talking clips)."""
    max_frames: int = field(default=300, metadata={"range": (1, None)})
    """Frames per clip."""


@dataclass
class BodyEval:
    clips: list = field(default_factory=list, metadata={"positional": True, "metavar": "PATTERN"})
    """Glob patterns under the data root (default: the gesture sets)."""
    max_frames: int | None = field(default=None, metadata={"range": (1, None)})
    """Frames per clip (default: all)."""


@dataclass
class AnnotationsEval:
    pass


@dataclass
class PoseEval:
    model: str | None = None
    """Lifter checkpoint (default: $ANIMA_HOME/models/pose_lifter.pt)."""
    ablation: str | None = field(default=None, metadata={"metavar": "DIR"})
    """Train (resumable) and evaluate the ablation rows of seed table 3.6 into DIR."""
    ablation_steps: int = field(default=8000, metadata={"range": (1, None)})
    """Training steps of each ablation row."""
    ablation_width: int = field(default=256, metadata={"range": (8, 8192)})
    """Network width of the ablation rows (256 keeps the five trainings to minutes on 2 cores; the seed's 1024
    is the `train pose` default)."""
    ablation_dropout: float = field(default=0.1, metadata={"range": (0.0, 0.99)})
    """Dropout of the ablation rows."""
    cache: str | None = None
    """MediaPipe detection cache (default: $ANIMA_HOME/cache/pose3d)."""


@dataclass
class ReenactEval:
    out: str | None = field(default=None, metadata={"metavar": "DIR"})
    """Folder for plots and side-by-side frames."""


@dataclass
class GestureEval:
    db: str = field(default="", metadata={"required": True, "metavar": "DB"})
    """Dataset folder from `anima dataset build`."""
    refiner_folds: int = field(default=3, metadata={"range": (0, 100)})
    """The learned models' cross-validation folds, each speaker's videos in one fold (at most one per speaker:
    leave-one-speaker-out; by video with --speaker; 0 = skip the learned models)."""
    seeds: int = field(default=3, metadata={"range": (1, 100)})
    """Training seeds of every learned model in every fold: its rows are the mean over seeds, with their spread."""
    refiner_steps: int | None = field(default=None, metadata={"range": (1, None)})
    """Generator steps per fold of the refiner (default 600)."""
    refiner_ablation: bool = False
    """Also train the refiner with anima's earlier settings (L1 10, gradient penalty 10, k = 0..4) on the same
    folds: knn_cgan_anima_v1 (about 9 minutes more)."""
    speaker: str | None = None
    """Only this speaker's windows (the seed's subject-specific protocol), e.g. oliver."""
    generator_steps: int | None = field(default=None, metadata={"range": (1, None)})
    """The §4.4 generator and baselines: training steps per fold (default 1000)."""
    sync_steps: int = field(default=300, metadata={"range": (1, None)})
    """Training steps of the sync classifier (table 4.4)."""
    fgd_steps: int = field(default=1500, metadata={"range": (1, None)})
    """Training steps of the FGD feature extractor."""
    blend: bool = True
    """k-NN rows with blended joins and the no-repeat rule (off: --no-blend, the seed's raw concatenation)."""


@dataclass
class Text2FaceEval:
    dataset: str = field(default="", metadata={"positional": True})
    """Dataset folder from `anima dataset build`."""
    work: str = "runs/eval_text2face"
    """Folder for the trained models (reused)."""
    reps: int = field(default=20, metadata={"range": (1, 1000)})
    """Sampling repetitions of every score (95 % intervals over them and over test videos)."""
    steps: int | None = field(default=None, metadata={"range": (1, None)})
    """Training steps of every model (default: table 7.1's learned models each get the count of --step-grid with
    the lowest MAE on the validation videos, the ablation rows ours')."""
    step_grid: tuple | None = field(default=None, metadata={"parse": "step_grid", "metavar": "N,N,..."})
    """The step counts tried on the validation videos (default 250,500,1000,2000); one training per model reaches
    the largest and keeps a snapshot at each."""
    ablations: bool = True
    """The ablation rows too (--no-ablations: only the model and the baselines)."""
    seed_preset: bool = False
    """Also train the seed-size model (13.6 M parameters)."""
    checkpoint: str | None = None
    """Score this checkpoint as 'ours' instead of training it."""
    prompts: str | None = field(default=None, metadata={"const": "", "metavar": "FILE"})
    """Instead of the tables: the prompt suite (default: the 114 prompts shipped in
    anima/eval/prompts/text2face.json; beside it text2face_dev2.json and text2face_heldout.json, 40 more each for
    development, and text2face_heldout3.json, the frozen held-out suite) scored for the
    timeline method, the seed model (the shipped checkpoint or --checkpoint) and retrieval with the dataset's
    detectors: per-event recall and false alarms, order, count and side accuracy, emotion checks, distinct
    motions (about 1 min on 2 cores)."""
    seeds: int = field(default=3, metadata={"range": (1, 100)})
    """With --prompts: seeds per prompt."""
    judge: bool = False
    """With --prompts: also score every method's seed-0 motion with the independent judge (rendered, tracked
    with MediaPipe, events from landmark geometry: anima/eval/text2face/judge.py; about 2 s a prompt and method), and
    list where the two judges disagree."""


@dataclass
class AllEval:
    db: str = field(default="", metadata={"required": True, "metavar": "DB"})
    """Dataset folder from `anima dataset build` (gesture, text2face)."""
    out: str = field(default="", metadata={"required": True, "metavar": "DIR"})
    """Result folder."""
    work: str | None = None
    """Trained models of the run: text2face's and the pose ablation's lifters (reused when there; default
    OUT/text2face_work)."""
    only: list = field(default_factory=list, metadata={"nargs": "+", "metavar": "NAME"})
    """Only these evaluations (rows)."""
    quick: bool = False
    """Learned models with a few steps: checks that everything runs, not results."""
    jobs: int = field(default=1, metadata={"range": (1, 64)})
    """Rows run side by side in this many processes, the machine's cores shared between them (each row's torch
    threads: cores // jobs); 1: one after another, every core to each row."""
    resume: bool = False
    """Keep the rows that a stopped run into OUT finished ("ok") on the same clean commit, shared data, dataset,
    --jobs and --quick, and run only the others (results.json lists the kept rows under "resumed")."""
