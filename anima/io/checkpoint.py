"""The one checkpoint format of every trained anima model: one writer (:func:`save_checkpoint`), one reader
(:func:`load_checkpoint`).

A checkpoint is a ``torch.save`` file holding only tensors and plain containers, and it is always read with
``torch.load(..., weights_only=True)``: loading a file never runs code from it (a crafted pickle is refused
with :class:`CheckpointError`). Layout::

    {"format": "anima.checkpoint", "envelope": 1,
     "kind": "text2face" | "gesture_refiner" | "gesture_generator" | "pose_lifter" | ...,
     "version": <the model kind's own version>,
     "meta": "<JSON: config (rebuilds the model), info (command, data fingerprint, losses, ...)>",
     "tensors": {"state": {name: Tensor}, ...}}      # e.g. "optimizer": an optimizer state_dict

The config travels inside the file, so a checkpoint rebuilds its own model. Every error (missing file
aside, which is bad input) is a :class:`CheckpointError`: one line, exit code 4.
"""

from __future__ import annotations

import json
import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from anima.errors import CheckpointError, InputError
from anima.io.atomic import atomic_path

FORMAT = "anima.checkpoint"
ENVELOPE = 1


@dataclass
class Checkpoint:
    kind: str
    version: int
    config: dict
    tensors: dict
    info: dict = field(default_factory=dict)
    path: Path | None = None

    @property
    def state(self) -> dict:
        return self.tensors["state"]


def _plain(x):
    """JSON-safe copy of ``x``: numpy scalars and arrays become Python numbers and lists, tuples lists."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if hasattr(x, "tolist"):  # numpy scalars/arrays, torch tensors
        return _plain(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    return str(x)


def save_checkpoint(
    path: str | Path, kind: str, version: int, config: dict, tensors: dict, info: dict | None = None
) -> Path:
    """Write atomically. ``tensors``: ``{"state": model.state_dict(), ...}`` (tensors and plain containers
    only); ``config`` and ``info`` are stored as JSON."""
    import torch

    if "state" not in tensors:
        raise ValueError("tensors must hold the model's 'state'")
    obj = {
        "format": FORMAT,
        "envelope": ENVELOPE,
        "kind": kind,
        "version": int(version),
        "meta": json.dumps({"config": _plain(config), "info": _plain(info or {})}),
        "tensors": tensors,
    }
    with atomic_path(path) as tmp:
        torch.save(obj, tmp)
    return Path(path)


def load_checkpoint(
    path: str | Path, kind: str | tuple[str, ...], version: int | tuple[int, ...], train_hint: str = ""
) -> Checkpoint:
    """Read a checkpoint of ``kind`` (one or several) and ``version`` (the versions this anima reads).
    Never executes code from the file. A missing file is :class:`InputError` (exit 2); anything else wrong
    (not a torch file, a pickle with code, another kind, another version) is :class:`CheckpointError`."""
    import torch

    p = Path(path)
    kinds = (kind,) if isinstance(kind, str) else tuple(kind)
    versions = (version,) if isinstance(version, int) else tuple(version)
    hint = f"; {train_hint}" if train_hint else ""
    if not p.is_file():
        raise InputError(f"checkpoint not found: {p}{hint}")
    try:
        obj = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as e:
        why = str(e).strip().splitlines()[0][:120] if str(e).strip() else type(e).__name__
        if "weights_only" in str(e) or "Unsupported global" in str(e) or "Weights only load failed" in str(e):
            why = "it holds Python objects that would run code on loading; refused"
        raise CheckpointError(f"{p}: not a loadable anima checkpoint ({why})") from None
    if isinstance(obj, dict) and obj.get("format") in LEGACY:
        try:
            obj = _from_legacy(obj, p)
        except (KeyError, TypeError) as e:
            raise CheckpointError(f"{p}: malformed {obj.get('format')} checkpoint (no {e})") from None
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise CheckpointError(f"{p}: not an anima checkpoint (format {_fmt(obj)!r}){hint}")
    if obj.get("envelope") != ENVELOPE:
        raise CheckpointError(
            f"{p}: checkpoint envelope {obj.get('envelope')!r}, this anima reads {ENVELOPE}; upgrade anima"
        )
    if obj.get("kind") not in kinds:
        raise CheckpointError(f"{p}: a {obj.get('kind')!r} checkpoint, expected {' or '.join(map(repr, kinds))}")
    if obj.get("version") not in versions:
        raise CheckpointError(
            f"{p}: {obj.get('kind')} checkpoint version {obj.get('version')!r}, this anima reads "
            f"{', '.join(map(str, versions))}{hint}"
        )
    try:
        meta = json.loads(obj["meta"])
        tensors = obj["tensors"]
        if not isinstance(tensors, dict) or not isinstance(tensors.get("state"), dict):
            raise ValueError("no model state")
    except (KeyError, TypeError, ValueError) as e:
        raise CheckpointError(f"{p}: malformed anima checkpoint ({e})") from None
    return Checkpoint(obj["kind"], int(obj["version"]), meta.get("config") or {}, tensors, meta.get("info") or {}, p)


# the per-model envelopes of anima before the one format (all loadable with weights_only=True): kind, and
# how their fields map to (config, tensors, info)
LEGACY = {
    "anima.text2face": None,
    "anima.gesture_refiner": "gesture_refiner",
    "anima.gesture_generator": "gesture_generator",
    "anima.pose_lifter": "pose_lifter",
}


def _from_legacy(obj: dict, p: Path) -> dict:
    """An envelope of version 1 of a model's own format, read into the one format (its kind at version 1)."""
    fmt, v = obj["format"], obj.get("version")
    if v != 1:
        raise CheckpointError(
            f"{p}: a checkpoint of the old format {fmt} version {v!r}, which this anima cannot read; retrain the model"
        )
    if fmt == "anima.text2face":
        config = {
            "model": obj["model_config"],
            "train": obj["train_config"],
            "mean": obj["mean"],
            "std": obj["std"],
            "gram": obj["gram"],
            "step": obj["step"],
        }
        tensors, info, kind = {"state": obj["state"]}, obj.get("info", {}), obj["kind"]
        if obj.get("optim"):
            tensors["optimizer"] = obj["optim"]
    elif fmt == "anima.pose_lifter":
        config, kind = obj["config"], LEGACY[fmt]
        tensors = {"state": obj["state_dict"], **({"optimizer": obj["optimizer"]} if obj.get("optimizer") else {})}
        info = {"step": obj.get("step", 0), "extra": obj.get("extra") or {}}
    else:
        config = {"model": obj["model_config"], "stats": obj["stats"]}
        tensors, info, kind = {"state": obj["state"]}, obj.get("info", {}), LEGACY[fmt]
    return {
        "format": FORMAT,
        "envelope": ENVELOPE,
        "kind": kind,
        "version": 1,
        "meta": json.dumps({"config": _plain(config), "info": _plain(info)}),
        "tensors": tensors,
    }


@contextmanager
def rebuilding(ck: Checkpoint):
    """Around rebuilding a model from ``ck.config``: a config that does not fit (missing or unknown keys,
    wrong types) is a :class:`CheckpointError`, not a crash."""
    try:
        yield
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise CheckpointError(
            f"{ck.path}: its config does not describe a {ck.kind} model ({type(e).__name__}: {str(e)[:100]})"
        ) from None


def load_state(module, ck: Checkpoint, key: str = "state", float32: bool = True) -> None:
    """Load ``ck.tensors[key]`` into ``module``; a state that does not fit the config is a CheckpointError."""
    state = ck.tensors[key]
    if float32:
        state = {
            k: v.float() if hasattr(v, "is_floating_point") and v.is_floating_point() else v for k, v in state.items()
        }
    try:
        module.load_state_dict(state)
    except (RuntimeError, KeyError, TypeError) as e:
        first = str(e).strip().splitlines()[0][:160]
        raise CheckpointError(f"{ck.path}: weights do not match the {ck.kind} model of its config ({first})") from None


def _fmt(obj) -> str:
    return obj.get("format", "?") if isinstance(obj, dict) else type(obj).__name__
