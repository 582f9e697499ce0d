"""Generate facial motion from text with a trained checkpoint, and write what a user opens.

``Generator(checkpoint)`` loads a text2face or MDM checkpoint with its text encoder; ``generate(prompts,
length, seed)`` returns raw motion ``[B, T, 56]`` (53 ICT expression weights in [0, 1], head axis-angle).
:func:`write_outputs` writes ``motion.npz`` (a tracked-sequence file, so ``anima info`` / ``anima export``
read it), ``face.mp4`` (the neutral ICT face animated), ``arkit.csv`` (Live Link Face), ``face.glb``
(morph-target animation) and ``info.json``.
"""
from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import torch

from anima.errors import InputError
from anima.text2face.encoders import clean_prompt, get_encoder
from anima.text2face.train import load_checkpoint

FPS = 30.0
SHIPPED = Path(__file__).parent / "checkpoints" / "text2face.pt"


def default_checkpoint() -> Path:
    if not SHIPPED.is_file():
        raise InputError(f"no shipped checkpoint at {SHIPPED}; train one with `anima train text2face`")
    return SHIPPED


class Generator:
    def __init__(self, checkpoint: str | Path | None = None):
        self.path = Path(checkpoint) if checkpoint else default_checkpoint()
        ck = load_checkpoint(self.path)
        self.ck, self.model, self.kind = ck, ck["model"], ck["kind"]
        self.cfg = self.model.cfg
        self.mean = np.asarray(ck["mean"], np.float32)
        self.std = np.asarray(ck["std"], np.float32)
        self.encoder = get_encoder(self.cfg.encoder)

    @property
    def length_range(self) -> tuple[int, int]:
        return self.cfg.min_len, self.cfg.max_len

    def check_length(self, n: int) -> int:
        lo, hi = self.length_range
        if not lo <= n <= hi:
            raise InputError(f"length {n} frames ({n / FPS:.1f} s) is outside the trained range {lo}-{hi} frames "
                             f"({lo / FPS:.1f}-{hi / FPS:.1f} s at 30 fps)")
        return n

    def embed(self, prompts: list[str]) -> np.ndarray:
        return self.encoder.encode([clean_prompt(p, self.encoder) for p in prompts])

    def generate_from_embeddings(self, E: np.ndarray, length: int, seed: int = 0, cached: bool = True) -> np.ndarray:
        self.check_length(length)
        g = torch.Generator().manual_seed(int(seed))
        e = torch.from_numpy(np.asarray(E, np.float32))
        if self.kind == "text2face":
            code = torch.randn(len(e), self.cfg.d_r, generator=g)
            z = self.model.sample(e, code, length, cached=cached)
        else:
            z = self.model.sample(e, length, generator=g)
        return self.denormalise(z.numpy())

    def denormalise(self, z: np.ndarray) -> np.ndarray:
        m = z * self.std + self.mean
        m[..., :53] = np.clip(m[..., :53], 0.0, 1.0)
        return m.astype(np.float32)

    def generate(self, prompts: list[str], length: int = 90, seed: int = 0) -> np.ndarray:
        return self.generate_from_embeddings(self.embed(prompts), length, seed)


@lru_cache(maxsize=1)
def _skin_height() -> tuple[float, float, tuple[str, ...]]:
    """(lowest, highest) y of the neutral skin mesh (cm) and the expression names; computed once (the
    evaluation frames thousands of generated windows)."""
    from anima.facemodel.ict import load_face_model
    fm = load_face_model()
    ys = fm.skin().neutral[:, 1]
    return float(ys.min()), float(ys.max()), tuple(fm.expr_names)


def motion_to_sequence(motion: np.ndarray, fps: float = FPS, size: int = 512, meta: dict | None = None):
    """A tracked-sequence object for generated motion: the neutral identity, framed in a ``size`` square."""
    from anima.io.sequence import TrackedSequence

    lo, hi, names = _skin_height()
    F = len(motion)
    scale = 0.8 * size / (hi - lo)  # pixels per cm: the head fills 80 % of the frame
    cy = (hi + lo) / 2
    return TrackedSequence(
        fps=fps, width=size, height=size, identity=np.zeros(100, np.float32),
        expression=np.ascontiguousarray(motion[:, :53], np.float32),
        rotation=np.ascontiguousarray(motion[:, 53:56], np.float32),
        scale=np.full(F, scale, np.float32),
        translation=np.tile(np.array([size / 2, -size / 2 - cy * scale, 0], np.float32), (F, 1)),
        fit_error_px=np.zeros(F, np.float32), fit_nme=np.zeros(F, np.float32), flags=np.zeros(F, np.uint8),
        landmarks=np.full((F, 478, 3), np.nan, np.float32), expr_names=list(names), meta=meta or {})


def write_outputs(out: str | Path, motion: np.ndarray, prompt: str, info: dict, video: bool = True,
                  progress: bool = True) -> dict:
    from anima.capture.export import export_arkit_csv, export_glb
    from anima.io.sequence import write_sequence
    from anima.render.videos import render_videos

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    seq = motion_to_sequence(motion, meta={"generated_by": "anima text2face", "prompt": prompt, **info})
    files = {"sequence": write_sequence(seq, out / "motion.npz"),
             "arkit_csv": export_arkit_csv(seq, out / "arkit.csv"),
             "glb": export_glb(seq, out / "face.glb")}
    if video:
        render_videos(seq, None, None, out / "face.mp4", progress=progress)
        files["video"] = out / "face.mp4"
    (out / "info.json").write_text(json.dumps({"prompt": prompt, **info,
                                               "files": {k: str(v) for k, v in files.items()}}, indent=2))
    return files
