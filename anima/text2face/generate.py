"""Generate facial motion from text with a trained checkpoint, and write what a user opens.

``Generator(checkpoint)`` loads a text2face or MDM checkpoint with its text encoder; ``generate(prompts,
length, seed)`` returns raw motion ``[B, T, 56]`` (53 ICT expression weights in [0, 1], head axis-angle).
:func:`text_to_folder` is ``anima text2face``: the motion written by the one motion writer (``motion.npz``, a
tracked-sequence file that ``anima info`` / ``anima export`` read, ``face.mp4``, ``arkit.csv``, ``face.glb``,
``info.json``).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np
import torch

from anima.core.contract import N_EXPR, TEXT_FPS
from anima.dataset.storage import check_dataset
from anima.errors import InputError
from anima.export.framing import generated_sequence
from anima.export.motion import write_motion_outputs
from anima.io.outdir import OutputFolder
from anima.text2face.compose import Library, compose
from anima.text2face.config import PromptConfig
from anima.text2face.encoders import clean_prompt, get_encoder, require_prompt
from anima.text2face.prompt import parse
from anima.text2face.train import load_checkpoint

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
        self.fps = ck["fps"]
        self.cfg = self.model.cfg
        self.mean = np.asarray(ck["mean"], np.float32)
        self.std = np.asarray(ck["std"], np.float32)

    @property
    def encoder(self):
        """The frozen text encoder of the checkpoint (loaded on first use: it takes seconds)."""
        return get_encoder(self.cfg.encoder)

    @property
    def length_range(self) -> tuple[int, int]:
        return self.cfg.min_len, self.cfg.max_len

    def check_length(self, n: int) -> int:
        lo, hi = self.length_range
        if not lo <= n <= hi:
            raise InputError(
                f"length {n} frames ({n / self.fps:.1f} s) is outside the trained range {lo}-{hi} "
                f"frames ({lo / self.fps:.1f}-{hi / self.fps:.1f} s at {self.fps:g} fps)"
            )
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
        m[..., :N_EXPR] = np.clip(m[..., :N_EXPR], 0.0, 1.0)
        return m.astype(np.float32)

    def generate(self, prompts: list[str], length: int = 90, seed: int = 0) -> np.ndarray:
        return self.generate_from_embeddings(self.embed(prompts), length, seed)


def text_to_folder(
    prompt: str,
    out: str | Path,
    cfg: PromptConfig | None = None,
    checkpoint: str | Path | None = None,
    video: bool = True,
    progress: bool = True,
    command: str | None = None,
    db: str | Path | None = None,
    preset: str = "anima",
) -> dict:
    """``anima text2face``: a sentence -> a result folder (``motion.npz``, ``arkit.csv``, ``face.glb``,
    ``face.mp4``, ``info.json``; :func:`anima.export.motion.write_motion_outputs`). ``--out`` is checked
    before the model loads. Returns the run's info (frames, fps, seed, sampling time, warnings, files)."""
    cfg = cfg or PromptConfig()
    seed = cfg.seed
    require_prompt(prompt)
    parse(prompt)  # a prompt the planner refuses (an event 10^12 times) is refused by both methods
    method = cfg.method
    if method == "auto":
        method = "timeline" if db else "model"
    if method == "timeline":
        if not db:
            raise InputError("--method timeline needs --db (a dataset folder from `anima dataset build`)")
        if checkpoint:
            raise InputError("--checkpoint is for --method model; the timeline method reads --db")
        return _timeline_to_folder(prompt, out, cfg, db, video, progress, command, preset)
    with OutputFolder(out, kind="text2face", command=command) as od:
        gen = Generator(checkpoint)
        n = gen.check_length(int(round(cfg.seconds * gen.fps)) if cfg.seconds else cfg.length)
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
        files = write_motion_outputs(seq, od, "motion.npz", render=video, info=info, progress=progress, preset=preset)
    return info | {"written": [str(p) for p in files.values()]}


def _timeline_to_folder(
    prompt, out, cfg: PromptConfig, db, video: bool, progress: bool, command, preset: str = "anima"
) -> dict:
    """The timeline method (:mod:`anima.text2face.compose`): the prompt's events from the dataset's captured
    segments. ``info.json`` records how the prompt was read, what was not understood, and where every event's
    motion comes from."""
    check_dataset(db)
    fps = TEXT_FPS
    n = int(round(cfg.seconds * fps)) if cfg.seconds else cfg.length
    with OutputFolder(out, kind="text2face", command=command) as od:
        lib = Library.from_dataset(db, splits=("train", "val", "test"))  # the user's own clips, all of them
        t = time.perf_counter()
        plan = parse(prompt)
        if not plan.events and plan.unknown:  # words the lexicon lacks: try the sentence encoder
            plan = parse(prompt, get_encoder("minilm"))
        motion, record = compose(plan, lib, n, cfg.seed)
        info = {
            "prompt": plan.text,
            "frames": n,
            "fps": fps,
            "seed": cfg.seed,
            "method": "timeline",
            "dataset": str(db),
            "understood": [
                {k: v for k, v in vars(e).items() if k != "words"} | {"from_words": e.words} for e in plan.events
            ],
            "paraphrased": plan.paraphrased,
            "not_understood": list(dict.fromkeys(plan.unknown)),
            "sampling_s": round(time.perf_counter() - t, 3),
            "timeline": record,
            "warnings": plan.notes + ([] if record["all_found"] else ["not every event reads back with the detectors"]),
        }
        seq = generated_sequence(fps, face=motion, meta={"generated_by": "anima text2face --method timeline"})
        od.info = info
        files = write_motion_outputs(seq, od, "motion.npz", render=video, info=info, progress=progress, preset=preset)
    return info | {"written": [str(p) for p in files.values()]}
