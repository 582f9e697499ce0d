"""The training config of the text -> face models. Light (no torch), so the command line builds its options
from it."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class TrainConfig:
    kind: str = field(default="text2face", metadata={"choices": ("text2face", "mdm", "smf")})
    """text2face: cVQVAE + FaceFormer decoder (seed 000); mdm, smf: the MDM- and StableMoFusion-style
    diffusion baselines."""
    preset: str = field(default="seed", metadata={"choices": ("seed", "small")})
    """seed: the hyper-parameters of seed 000 §7.1; small: d_m 256, d_t 32 (the shipped model)."""
    model: dict = field(default_factory=dict)  # overrides of the model config
    scheme: str = field(default="teacher", metadata={"choices": ("teacher", "autoregressive")})
    """Teacher forcing, or FaceFormer's autoregressive scheme (the table 7.2 ablation)."""
    steps: int = field(default=2000, metadata={"range": (1, 10_000_000)})
    """Training steps."""
    batch: int = field(default=8, metadata={"range": (1, 4096)})
    """Crops per step."""
    lr: float = field(default=1e-4, metadata={"range": (1e-9, 1.0)})
    """Adam learning rate."""
    w_rot: float = 1.0
    per_clip: int = 30
    min_len: int = 30
    max_len: int = 300
    seed: int = 0
    """Random seed."""
    ckpt_every: int = 250
    restart_every: int = 50  # dead-code restart of the cVQVAE codebook (0: never; the seed does not say)
    fresh_codes: bool = False  # draw the random code anew each step instead of fixing it per sample (§6.1)
    tf_drop: float = field(default=0.9, metadata={"range": (0.0, 0.999)})
    """Share of teacher-forced input frames replaced by the zero start frame. Not in the seed: with plain
    teacher forcing the decoder learns to copy the previous frame (30 fps face motion is smooth), ignores
    the text, and the sampled motion is the same for every prompt (docs/text2face.md). 0 = the seed."""
    tf_noise: float = 0.0  # Gaussian noise (z units) on teacher-forced inputs against exposure bias
    encoder: str = field(default="minilm", metadata={"choices": ("minilm", "clip")})
    """Frozen text encoder (clip needs open_clip and its weights)."""
    threads: int = 0  # 0: torch's default


@dataclass
class PromptConfig:
    """What ``anima text2face PROMPT`` generates."""

    length: int | None = field(default=None, metadata={"range": (1, 100_000)})
    """Frames at 30 fps; default: the timeline method makes the clip as long as the prompt's events need (at
    least 90 = 3 s), the model 90; a length too short for the events is refused; the timeline method makes at
    most 18000 (10 min, asked or implied by the events), the model its trained range."""
    seconds: float | None = field(default=None, metadata={"range": (0.01, 3600.0)})
    """Length in seconds (overrides --length; the timeline method: at most 600)."""
    seed: int = 0
    """Random seed: other seeds give other motions."""
    method: str = field(default="auto", metadata={"choices": ("auto", "timeline", "model")})
    """timeline: the prompt's events (smile, blink, nod, emotions, gaze, ... with "then", counts, "slightly",
    "without") made from captured segments: the built-in motion library's, or --db's (docs/text2face.md);
    model: the seed's cVQ-VAE + FaceFormer checkpoint; auto: the model when --checkpoint is given, else
    timeline."""
    with_builtin: bool = False
    """With --db: the built-in library's clips as well as the dataset's (default: --db replaces them)."""
