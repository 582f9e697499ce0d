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

What a file may cost is bounded by the file before anything is built from it: the zip members may not declare
more than :data:`EXPANSION` x the file's size; every tensor must own the bytes it shows (no stride-0 or
overlapping views that a copy would blow up to gigabytes); the model's weights must be finite and within
:data:`MAX_WEIGHT`; and :func:`rebuild` builds the model of a config on PyTorch's ``meta`` device first, refusing
a config whose model would be far larger than the weights the file carries (``d_m = 1e7`` in a 4 MB file).
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
EXPANSION = 4  # torch.save stores tensors uncompressed: a real file's members add up to about its size
MAX_WEIGHT = 1e6  # no trained weight of an anima model comes near this (a NaN or 1e38 is damage or an attack)


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
    _check_zip(p)
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
        meta = json.loads(obj["meta"], parse_constant=_no_constant)
        tensors = obj["tensors"]
        if not isinstance(tensors, dict) or not isinstance(tensors.get("state"), dict):
            raise ValueError("no model state")
        if not isinstance(meta, dict) or not isinstance(meta.get("config") or {}, dict):
            raise ValueError("its meta is not a JSON object")
    except (KeyError, TypeError, ValueError, RecursionError) as e:
        raise CheckpointError(f"{p}: malformed anima checkpoint ({str(e)[:120]})") from None
    _check_tensors(p, tensors)
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


def _no_constant(name: str):
    raise ValueError(f"{name} in the config")


def looks_like_checkpoint(p: Path) -> bool:
    """Whether ``p`` is a torch checkpoint file (a zip holding ``data.pkl``), without loading it: what an
    output path must be before anima replaces it."""
    import zipfile

    try:
        with zipfile.ZipFile(p) as z:
            return any(n.endswith("/data.pkl") or n == "data.pkl" for n in z.namelist())
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        return False


def _check_zip(p: Path) -> None:
    """A torch file is a zip: refuse one whose members declare far more bytes than the file holds."""
    import zipfile

    size = p.stat().st_size
    try:
        with zipfile.ZipFile(p) as z:
            declared = sum(i.file_size for i in z.infolist())
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        return  # not a zip (an old-style torch file, or garbage): torch.load decides, with weights_only
    if declared > EXPANSION * size + 1_000_000:
        raise CheckpointError(
            f"{p}: its members declare {declared / 2**20:.0f} MB in a {size / 2**20:.1f} MB file (damaged or crafted)"
        )


def _tensors(x, prefix=""):
    import torch

    if isinstance(x, torch.Tensor):
        yield prefix, x
    elif isinstance(x, dict):
        for k, v in x.items():
            yield from _tensors(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            yield from _tensors(v, f"{prefix}[{i}]")


def _check_tensors(p: Path, tensors: dict) -> None:
    """Every tensor owns the bytes it shows (no stride-0 or overlapping view: a copy of one would take
    gigabytes the file never held), and the model's weights are finite and of a trained model's size."""
    import torch

    for name, t in _tensors(tensors):
        if t.layout != torch.strided or t.is_quantized:
            raise CheckpointError(f"{p}: tensor {name} has a layout anima does not write ({t.layout})")
        if t.numel() and (
            any(s < 1 and n > 1 for s, n in zip(t.stride(), t.shape))
            or t.untyped_storage().nbytes() < t.numel() * t.element_size()
        ):
            raise CheckpointError(f"{p}: tensor {name} is a view larger than the data it holds (crafted)")
    for name, t in _tensors(tensors["state"]):
        if t.is_floating_point() and t.numel():
            if not bool(torch.isfinite(t).all()):
                raise CheckpointError(f"{p}: weight {name} holds NaN or infinite values (a damaged model)")
            if float(t.abs().max()) > MAX_WEIGHT:
                raise CheckpointError(f"{p}: weight {name} reaches {float(t.abs().max()):.3g} (not a trained model)")


def rebuild(ck: Checkpoint, make):
    """``make()`` the model of ``ck.config`` (inside :func:`rebuilding`), after building it once on PyTorch's
    ``meta`` device (no memory) to check that its size fits the weights the file carries."""
    import torch

    with rebuilding(ck):
        try:
            with torch.device("meta"):
                probe = make()
            need = sum(t.numel() for t in probe.state_dict().values())
        except (RuntimeError, NotImplementedError):  # a model that computes on its tensors while it is built
            need = 0
        have = sum(t.numel() for _, t in _tensors(ck.state))
        if need > 2 * have + 1_000_000:
            raise CheckpointError(
                f"{ck.path}: its config describes a model of {need:,} values but the file holds {have:,} (crafted)"
            )
        return make()


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
