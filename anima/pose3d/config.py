"""Configs of the 2D->3D lifter and its training, and where its files live. Light: no torch, so the command
line can build its options from them."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path

from anima.io.assets import user_dir
from anima.pose3d.joints import K


@dataclass
class LifterConfig:
    joints: int = K
    width: int = 1024
    latent: int = 128
    dropout: float = 0.25
    pose_scale: float = 1000.0  # network units -> mm

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class TrainConfig:
    steps: int = field(default=6000, metadata={"range": (1, 10_000_000)})
    """Training steps."""
    batch: int = field(default=256, metadata={"range": (2, 65_536)})
    """Human3.6M samples per step."""
    batch_wild: int = 128
    lr: float = 1e-3
    lr_decay: float = 0.1  # total exponential decay over the run
    seed: int = 0
    """Random seed."""
    every: int = 1  # keep every n-th mocap pose
    w_3d: float = 10.0
    w_heat: float = 0.1
    w_2d: float = 10.0
    w_bone: float = 10.0
    w_bone_2d: float = 100.0
    latent_2d: bool = True
    """The explicit 2D latent loss L_2Dheatmap on h_2D (eq. 3.3; off: --no-latent-2d)."""
    projection: bool = True
    """The 3D-to-2D projection loss L_2Dpose (eq. 3.7; off: --no-projection)."""
    bone: bool = True
    """The bone losses (eqs. 3.5-3.6; off: --no-bone)."""
    wild: bool = True
    """2D-only in-the-wild data (off: --no-wild)."""
    noise_max: float = 0.06  # per-sample noise level (torso units), uniform in [0, noise_max]
    drop_joint: float = 0.05
    drop_legs: float = 0.15
    model: dict = field(default_factory=lambda: LifterConfig().to_dict())


def default_checkpoint() -> Path:
    """Where ``anima train pose`` writes and ``anima capture --body-3d lifter`` reads by default (a user
    folder: a model trained on Human3.6M may not be redistributed, so none ships with anima)."""
    return user_dir("models", "pose_lifter.pt")


def default_cache() -> Path:
    return user_dir("cache", "pose3d")
