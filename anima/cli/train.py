"""``anima train pose | text2face | gesture``."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from anima.cli.common import JsonQuiet, add_args, command_line, emit, group
from anima.cli.options import add_options, config_from_args
from anima.dataset.storage import check_dataset
from anima.gesture.config import GestureTrainConfig
from anima.io.outdir import check_out_dir, check_out_file
from anima.pose3d.config import TrainConfig as PoseTrainConfig
from anima.pose3d.config import default_cache, default_checkpoint
from anima.text2face.config import TrainConfig as FaceTrainConfig
from anima.text2face.ship import check_ship, ship

POSE_OPTIONS = ["steps", "batch", "seed", "wild", "projection", "latent_2d", "bone"]
FACE_OPTIONS = ["kind", "preset", "scheme", "steps", "batch", "lr", "seed", "encoder", "tf_drop"]


GESTURE_OPTIONS = ["model", "steps", "seed", "all_splits"]


@dataclass
class PoseRun:
    out: str | None = field(default=None, metadata={"metavar": "OUT"})
    """checkpoint"""


@dataclass
class PoseRunMore:
    width: int = field(default=1024, metadata={"range": (8, 8192), "metavar": "WIDTH"})
    """f_3D width (seed: 1024)"""
    no_resume: bool = False
    """start over even if --out exists"""
    cache: str | None = field(default=None, metadata={"metavar": "CACHE"})
    """MediaPipe detection cache"""


@dataclass
class FaceRun:
    dataset: str = field(default="", metadata={"positional": True, "metavar": "dataset"})
    """dataset folder"""
    out: str = field(default="runs/text2face", metadata={"metavar": "OUT"})
    """run folder (checkpoint.pt is written there)"""


@dataclass
class FaceRunMore:
    codebook: int | None = field(default=None, metadata={"range": (2, 65_536), "metavar": "CODEBOOK"})
    """N_emb (codebook entries)"""
    emb_dim: int | None = field(default=None, metadata={"range": (2, 8192), "metavar": "EMB_DIM"})
    """D_emb (codebook entry size)"""
    style: bool = False
    """ablation: add a random style vector to the decoder input"""
    ship: str | None = field(default=None, metadata={"metavar": "PATH"})
    """also write a compact (float16, no optimizer) copy and its manifest (command, data fingerprint, held-out
    metrics) to PATH"""


@dataclass
class GestureRun:
    db: str = field(default="", metadata={"required": True, "metavar": "DB"})
    """dataset folder from `anima dataset build`"""
    out: str = field(default="", metadata={"required": True, "metavar": "OUT"})
    """checkpoint path (.pt)"""


def register(sub) -> None:
    trsub = group(sub, "train", "train models", "train_command", "MODEL")
    tp = trsub.add_parser(
        "pose",
        help="the weakly supervised 2D->3D body pose lifter (seed 004 ch. 3)",
        description="Train the lifter on Human3.6M S1,S5,S6,S7,S8 mocap projected through the real "
        "cameras (3D labels) and MediaPipe 2D detections on the in-the-wild videos of the data "
        "folder (2D labels only), with the losses of seed 004 eqs. 3.3-3.8. Resumable: rerun the "
        "same command after an interruption. Never trains on S9/S11. The checkpoint carries its "
        "config; Human3.6M terms forbid redistributing it.",
    )
    add_args(tp, PoseRun, help_extra={"out": f"(default: {default_checkpoint()})"})
    add_options(tp, PoseTrainConfig, POSE_OPTIONS)
    add_args(tp, PoseRunMore, JsonQuiet, help_extra={"cache": f"(default: {default_cache()})"})
    tp.set_defaults(func=cmd_pose)

    tt = trsub.add_parser(
        "text2face",
        help="text -> facial motion: the seed 000 model or the MDM baseline",
        description="Train on the (text, motion) clips of a dataset from `anima dataset build`: "
        "random crops re-described by the timeline grammar, the vertex-offset loss through the ICT "
        "face model, teacher forcing (seed 000 ch. 6-7). Resumable: rerun the same command. "
        "The checkpoint carries its config and normalisation.",
    )
    add_args(tt, FaceRun)
    add_options(tt, FaceTrainConfig, FACE_OPTIONS)
    add_args(tt, FaceRunMore, JsonQuiet)
    tt.set_defaults(func=cmd_text2face)

    tg = trsub.add_parser(
        "gesture",
        help="the cGAN refiner of k-NN gestures (§5.3.3) or the §4.4 generator",
        description="--model refiner (default): synthesises every training window's speech with "
        "the k-NN search over the other videos (the seed's k: 1 for half, 2..15 for the rest), then "
        "trains a 1D U-Net generator against a WGAN-GP critic on (speech, gesture) pairs (5 critic "
        "steps per generator step, the seed's weights: L1 to the k-NN output 0.1, adversarial 1, "
        "gradient penalty 100; parent-relative joints); use it with `anima gesture --refiner`. "
        "--model generator: the §4.4 speech-to-gesture U-Net (face, body and hand decoders) with "
        "its audio+pose discriminator; regression: the same without the adversarial term; lstm: "
        "the LSTM baseline; velocity_adversarial: the Ginosar et al. (2019) baseline (a motion-"
        "difference discriminator without speech); moglow: a MoGlow-style normalising flow (Henter et al. "
        "2020), trained by likelihood on the windows with a body. Use those with `anima gesture --generator`.",
    )
    add_args(tg, GestureRun)
    add_options(tg, GestureTrainConfig, GESTURE_OPTIONS)
    add_args(tg, JsonQuiet)
    tg.set_defaults(func=cmd_gesture)


def cmd_pose(a) -> int:
    from anima.pose3d.train import summary_json, train  # lazy: torch

    base = PoseTrainConfig()
    cfg = config_from_args(PoseTrainConfig, a, POSE_OPTIONS, model={**base.model, "width": a.width})
    out = Path(a.out) if a.out else default_checkpoint()
    _, info = train(
        cfg, out, Path(a.cache) if a.cache else default_cache(), progress=not a.quiet, resume=not a.no_resume
    )
    print(summary_json(info) if a.json else f"wrote {out} ({info['seconds']:.0f} s, {cfg.steps} steps)")
    return 0


def cmd_text2face(a) -> int:
    check_out_dir(a.out, inputs=[a.dataset])  # a user's folder is refused first
    if a.ship:
        check_ship(a.ship, inputs=[a.dataset])  # before the training it would come after
    check_dataset(a.dataset)  # before torch loads
    from anima.eval.text2face.run import quick_metrics  # lazy: torch
    from anima.text2face.train import train  # lazy: torch

    model = {
        k: v for k, v in (("N_emb", a.codebook), ("D_emb", a.emb_dim), ("style", a.style or None)) if v is not None
    }
    cfg = config_from_args(FaceTrainConfig, a, FACE_OPTIONS, model=model)
    r = train(a.dataset, a.out, cfg, progress=not a.quiet, command=command_line(a))
    losses = r["info"]["losses"][-50:]
    msg = {
        "checkpoint": str(r["path"]),
        "steps": cfg.steps,
        "wall_s": round(r["info"]["wall_s"], 1),
        "final_loss": float(sum(losses) / max(1, len(losses))),
    }
    if a.ship:
        msg["shipped"] = [str(p) for p in ship(r["path"], a.ship, lambda p: quick_metrics(a.dataset, p))]
    return emit(msg, a.json)


def cmd_gesture(a) -> int:
    check_out_file(a.out, inputs=[a.db], suffixes=(".pt",), what="a checkpoint")  # refused first
    check_dataset(a.db)  # before torch loads
    from anima.gesture.train import train_from_dataset  # lazy: torch

    cfg = config_from_args(GestureTrainConfig, a, GESTURE_OPTIONS)
    msg = train_from_dataset(a.db, a.out, cfg, progress=not a.quiet, command=command_line(a))
    return emit(
        msg, a.json, lambda m: "\n".join(f"{k}: {json.dumps(v) if isinstance(v, dict) else v}" for k, v in m.items())
    )
