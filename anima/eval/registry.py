"""Every evaluation, declared once. ``anima eval NAME`` and ``anima eval all`` are generated from
:data:`EVALUATIONS`: each names its light config (:mod:`anima.eval.config`; the command's options), the module
whose ``run(cfg, progress) -> dict`` computes it and whose ``summary(result) -> list[str]`` gives the markdown
lines of ``eval all`` (and ``text(result) -> str`` the terminal text, where the result is not JSON by default),
a check that refuses bad input before any heavy import, and the rows ``eval all`` runs (name and config each).

To add an evaluation: its config in :mod:`anima.eval.config`, its module under ``anima/eval/`` with ``run`` and
``summary``, and one :class:`Evaluation` here."""

from __future__ import annotations

import dataclasses
import importlib
import shlex
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from anima.dataset.storage import check_dataset
from anima.eval.config import (
    DEV2_PROMPTS,
    HELDOUT_PROMPTS,
    AnnotationsEval,
    BodyEval,
    GestureEval,
    LandmarksEval,
    PoseEval,
    ReenactEval,
    StabilityEval,
    Text2FaceEval,
)
from anima.eval.text2face.prompts import load_suite
from anima.io.assets import shown_path


@dataclass(frozen=True)
class Context:
    """What ``anima eval all`` gives every evaluation: the dataset, the result folder (the pose ablation trains
    in its ``pose_ablation`` folder), the text2face work folder, and whether this is a quick run (a few
    training steps: a check that everything runs)."""

    db: str
    out: Path
    work: Path
    quick: bool


@dataclass(frozen=True)
class Evaluation:
    name: str
    help: str
    description: str
    config: type
    module: str
    rows: Callable[[Context], list[tuple[str, object]]]
    check: Callable[[object], None] = lambda cfg: None
    text: bool = False  # a terminal text unless --json (else the result is JSON either way)
    long: bool = False  # its rows take most of an ``eval all`` (hours on 2 cores): started first with --jobs

    def runner(self):
        """The evaluation's module (imported now: it may load torch or MediaPipe)."""
        return importlib.import_module(self.module)

    def command(self, cfg) -> str:
        """The command line that computes ``cfg`` (what ``eval all`` records for each row)."""
        return command_line(self.name, cfg)


def command_line(name: str, cfg) -> str:
    """``anima eval NAME`` with the options of ``cfg`` that differ from the config's defaults, and ``--json``."""
    default = type(cfg)()
    parts = ["anima", "eval", name]
    for f in dataclasses.fields(cfg):
        v, d = getattr(cfg, f.name), getattr(default, f.name)
        md = f.metadata
        if md.get("positional"):
            parts += [str(x) for x in v] if isinstance(v, list) else [str(v)]
            continue
        if v == d:
            continue
        if isinstance(v, bool):
            parts.append(md.get("flag", ("--no-" if d else "--") + f.name.replace("_", "-")))
            continue
        flag = md.get("flag", "--" + f.name.replace("_", "-"))
        if isinstance(v, (list, tuple)):
            parts += [flag, ",".join(map(str, v)) if md.get("parse") else " ".join(map(str, v))]
        elif v == md.get("const", object()):
            parts.append(flag)
        else:
            parts += [flag, _shown(v)]
    return shlex.join(parts + ["--json"])


def _shown(v) -> str:
    """An option's value as a command line shows it: a file inside the project by its path from the
    project's root (where it is, not where this copy is installed); others as given."""
    s = shown_path(v)
    return str(v) if s.startswith("$") else s


def _check_gesture(cfg: GestureEval) -> None:
    check_dataset(cfg.db)


def _check_text2face(cfg: Text2FaceEval) -> None:
    check_dataset(cfg.dataset)
    if cfg.prompts is not None:
        load_suite(cfg.prompts or None)  # a bad suite fails before any model loads


def _text2face_rows(c: Context) -> list[tuple[str, object]]:
    seeds = 1 if c.quick else 3
    q = dict(reps=2, ablations=False, steps=20) if c.quick else {}
    return [
        ("text2face", Text2FaceEval(dataset=c.db, work=str(c.work), **q)),
        # both judges on every suite: the dataset's detectors and the independent one; the two
        # development suites, then the frozen held-out one (run once per release, here)
        ("text2face_prompts", Text2FaceEval(dataset=c.db, prompts="", seeds=seeds, judge=not c.quick)),
        (
            "text2face_prompts_dev2",
            Text2FaceEval(dataset=c.db, prompts=str(DEV2_PROMPTS), seeds=seeds, judge=not c.quick),
        ),
        (
            "text2face_prompts_heldout",
            Text2FaceEval(dataset=c.db, prompts=str(HELDOUT_PROMPTS), seeds=seeds, judge=not c.quick),
        ),
    ]


EVALUATIONS = (
    Evaluation(
        "landmarks",
        "68-point NME on the AFLW2000-3D samples",
        "68-point NME (3DDFA_V2 protocol) of raw MediaPipe and of the fitted model.",
        LandmarksEval,
        "anima.eval.landmarks",
        lambda c: [("landmarks", LandmarksEval())],
        text=True,
    ),
    Evaluation(
        "stability",
        "landmark jitter of the smoothed fit vs raw MediaPipe",
        "Mean landmark acceleration (normalised by inter-ocular distance) of raw MediaPipe and of the smoothed "
        "fit, and the fit's landmark error with and without smoothing, on talking clips.",
        StabilityEval,
        "anima.eval.stability",
        lambda c: [("stability", StabilityEval())],
        text=True,
    ),
    Evaluation(
        "body",
        "body/hand tracking and cleaning report on the gesture clips",
        "Per clip: body and hand tracked %, after interpolation, bone-length CV before/after cleaning; hand "
        "detector on hand-images/. Default clips: pats-crops, tango-interviews, LatentSync.",
        BodyEval,
        "anima.eval.body",
        lambda c: [("body", BodyEval())],
        text=True,
    ),
    Evaluation(
        "annotations",
        "attribute detectors vs labels made by watching frames",
        "Precision and recall per attribute (event and frame level) of the automatic attribute detectors on the "
        "labelled clips in anima/eval/labels/attributes/.",
        AnnotationsEval,
        "anima.eval.annotations",
        lambda c: [("annotations", AnnotationsEval())],
        text=True,
    ),
    Evaluation(
        "pose",
        "3D body pose: lifter vs MediaPipe on Human3.6M S9 images, HumanEva; ablation",
        "MPJPE, 3D PCK@150 mm and AUC under the unscaled, globally scaled and Procrustes protocols (seed 004 "
        "§3.4.1) for the lifter checkpoint and for MediaPipe's own world landmarks on the real S9 images; "
        "HumanEva-I validation from ground-truth 2D; with --ablation DIR, trains (resumable) and evaluates the "
        "rows of seed table 3.6.",
        PoseEval,
        "anima.eval.pose.run",
        lambda c: [  # the ablation's lifters are trained in the run (no lifter ships: Human3.6M's terms)
            ("pose", PoseEval(ablation=str(c.out / "pose_ablation"), ablation_steps=20 if c.quick else 8000))
        ],
    ),
    Evaluation(
        "reenact",
        "self-re-enactment metrics (seed 001 §4.2) on the Obama clips and d11",
        "SSIM, LPIPS, lip NME, tOF, tLP on the face box; the base loss with the true vertex colours; SSIM "
        "against n; method 1 vs 2; n-best L2 curves with and without the actor->target expression mapping. "
        "--out DIR also writes plots and side-by-side frames.",
        ReenactEval,
        "anima.eval.reenact.run",
        lambda c: [("reenact", ReenactEval(out=str(c.out / "reenact")))],
    ),
    Evaluation(
        "gesture",
        "gestures from speech: control adherence, L1, FGD, lip error, jerk, beats",
        "On the dataset's (audio, motion) windows (seed 004 ch. 4-5): k-NN leave-one-speaker-out with control "
        "adherence as table 5.3; k-NN + cGAN, the §4.4 generator, direct regression and the LSTM baseline "
        "cross-validated by speaker (each speaker's videos held out together, settings chosen on inner "
        "validation speakers), each trained with --seeds training seeds (mean and spread over seeds); L1 to the "
        "captured motion, FGD, lip keypoint error (table 4.3), diversity, jerk, beat consistency; the sync "
        "classifier (table 4.4); lip sync on FaceGood's recordings; minutes per speaker. With --speaker: that "
        "speaker's windows only, held out by video.",
        GestureEval,
        "anima.eval.gesture.run",
        lambda c: [
            (
                "gesture",
                GestureEval(db=c.db, refiner_steps=10, generator_steps=10, sync_steps=10, seeds=1)
                if c.quick
                else GestureEval(db=c.db),
            )
        ],
        check=_check_gesture,
        long=True,
    ),
    Evaluation(
        "text2face",
        "text -> face: tables 7.1-7.3, attribute recall, R-precision",
        "Trains (or reuses, in --work) the seed 000 model, its ablations and the MDM- and StableMoFusion-style "
        "baselines on the dataset's training videos (training steps chosen on the validation videos) and "
        "scores them with the retrieval and mean baselines on 90-frame windows of the held-out videos: "
        "MAE/RMSE of mouth and eye vertices (mm), Diversity, each over --reps repetitions with 95% confidence "
        "intervals; attribute recall with the dataset's detectors; R-precision with a contrastive text-motion "
        "evaluator. With --prompts: the prompt suite instead.",
        Text2FaceEval,
        "anima.eval.text2face.run",
        _text2face_rows,
        check=_check_text2face,
        long=True,
    ),
)
BY_NAME = {e.name: e for e in EVALUATIONS}


def rows(c: Context) -> list[tuple[Evaluation, str, object]]:
    """Every row of ``anima eval all``: (evaluation, row name, config), in the registry's order."""
    return [(e, name, cfg) for e in EVALUATIONS for name, cfg in e.rows(c)]
