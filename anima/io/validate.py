"""One validation layer for what users hand to anima: files are checked (size, encoding, structure, declared
array sizes) *before* they are loaded, so a crafted or damaged file is one clear :class:`InputError` or
:class:`SchemaError` and never a traceback, a silent wrong result, or memory out of proportion to the file.

Limits (documented in docs/artifacts.md):

* JSON inputs (annotations, manifests): at most ``MAX_JSON_BYTES``, UTF-8, no NaN/Infinity, nesting at most
  ``MAX_JSON_DEPTH``.
* ``.npz`` inputs: only numeric arrays (no pickled objects); the arrays a reader loads may declare at most
  ``EXPANSION`` x the file's size + ``EXPANSION_FLOOR`` bytes (a real file's arrays decompress to a few times
  its size; a "zip bomb" declares gigabytes in kilobytes).
* sequences: at most ``MAX_FRAMES`` frames.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from anima.errors import InputError, SchemaError

MAX_JSON_BYTES = 64 * 1024 * 1024
MAX_JSON_DEPTH = 64
MAX_FRAMES = 1_000_000  # 9 h at 30 fps
EXPANSION = 64
EXPANSION_FLOOR = 16 * 1024 * 1024


def input_file(path: str | os.PathLike, what: str = "file") -> Path:
    """An existing, non-empty regular file, else a one-line :class:`InputError`."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{what} not found: {p}")
    if p.is_dir():
        raise InputError(f"expected a {what}, got a folder: {p}")
    if p.stat().st_size == 0:
        raise InputError(f"{what} is empty: {p}")
    return p


def json_depth(x, limit: int, level: int = 0) -> int:
    """How deep parsed JSON ``x`` nests (dicts and lists), counted no further than just past ``limit``."""
    if level > limit:
        return level
    if isinstance(x, dict):
        return max([json_depth(v, limit, level + 1) for v in x.values()], default=level + 1)
    if isinstance(x, list):
        return max([json_depth(v, limit, level + 1) for v in x], default=level + 1)
    return level


def _no_constant(name: str):
    raise ValueError(f"{name} is not allowed")


def parse_json(text: str | bytes, where: str, max_depth: int = MAX_JSON_DEPTH):
    """Strict JSON: UTF-8, no NaN/Infinity, bounded nesting; errors name ``where``."""
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as e:
            raise InputError(f"{where}: not UTF-8 text (byte {e.start})") from None
    try:
        obj = json.loads(text, parse_constant=_no_constant)
    except RecursionError:
        raise InputError(f"{where}: JSON nested too deeply") from None
    except ValueError as e:
        raise InputError(f"{where}: not valid JSON ({str(e).splitlines()[0][:120]})") from None
    if json_depth(obj, max_depth) > max_depth:
        raise InputError(f"{where}: JSON nested deeper than {max_depth} levels")
    return obj


def read_json(path: str | os.PathLike, what: str = "JSON file", max_bytes: int = MAX_JSON_BYTES):
    p = input_file(path, what)
    if p.stat().st_size > max_bytes:
        raise InputError(f"{what} {p} is {p.stat().st_size / 2**20:.0f} MB: at most {max_bytes / 2**20:.0f} MB")
    return parse_json(p.read_bytes(), str(p))


def npz_headers(path: Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """``{name: (shape, dtype)}`` of every array of an ``.npz``, read from the headers without decompressing the
    data. Object (pickled) arrays and malformed members are refused."""
    out = {}
    try:
        with zipfile.ZipFile(path) as z:
            for info in z.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                with z.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    shape, _, dtype = np.lib.format._read_array_header(fh, version)
                if dtype.hasobject:
                    raise SchemaError(f"{path}: array {info.filename[:-4]!r} holds Python objects; refused")
                out[info.filename[:-4]] = (tuple(int(s) for s in shape), dtype)
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError) as e:
        raise InputError(f"cannot read {path}: not a valid .npz ({str(e).splitlines()[0][:120]})") from None
    return out


def check_expansion(path: Path, headers: dict, names) -> None:
    """Refuse an ``.npz`` whose arrays ``names`` would take far more memory than the file's size suggests."""
    total = sum(int(np.prod(headers[n][0], dtype=np.int64)) * headers[n][1].itemsize for n in names if n in headers)
    limit = EXPANSION * path.stat().st_size + EXPANSION_FLOOR
    if total > limit:
        raise InputError(
            f"{path}: its arrays declare {total / 2**20:.0f} MB in a {path.stat().st_size / 2**20:.1f} MB "
            "file (damaged, or not made by anima)"
        )


MIN_FPS, MAX_FPS = 1.0, 1000.0


def frame_rate(x, where: str) -> float:
    """A frame rate read from a file: a finite number (an int, a float or a numpy number; never a bool or a
    string) from :data:`MIN_FPS` to :data:`MAX_FPS`, else an :class:`InputError` naming ``where``."""
    if isinstance(x, np.ndarray) and x.shape == ():
        x = x.item()
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise InputError(f"{where}: fps is {x!r}, not a number")
    v = float(x)
    if not math.isfinite(v) or not MIN_FPS <= v <= MAX_FPS:
        raise InputError(f"{where}: fps {x!r} is not a frame rate ({MIN_FPS:g} to {MAX_FPS:g})")
    return v


def finite_number(x, what: str, low: float | None = None, high: float | None = None) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise InputError(f"{what} is {x!r}, not a number") from None
    if not math.isfinite(v) or (low is not None and v < low) or (high is not None and v > high):
        raise InputError(f"{what} is {x!r}: expected a finite number in [{low}, {high}]")
    return v
