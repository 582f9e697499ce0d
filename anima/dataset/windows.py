"""The one reader of a dataset's training pairs, checking the data contract (``anima.core.contract``) on read.

* :func:`read_windows`: the (audio, motion) windows as stacked arrays with their frame rate, taken from the
  data (the ``fps`` column), never assumed.
* :func:`read_clips`: the (text, motion) clips with their frame rate.

A row whose sizes break the contract, or a mix of frame rates, is a :class:`SchemaError` naming the row.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anima.core.contract import BODY_DIM, FACE_DIM, SPEECH_DIM
from anima.dataset.storage import read_table
from anima.errors import SchemaError
from anima.io.validate import MAX_FPS, MIN_FPS


@dataclass
class Windows:
    """(audio, motion) windows: ``speech [N, T, 28]``, ``body [N, T, 165]`` (all NaN for face-only windows),
    ``face [N, T, 56]``; per window its source video, start (s), split and id."""

    speech: np.ndarray
    body: np.ndarray
    face: np.ndarray
    source: list[str]
    start_s: list[float]
    split: list[str]
    window_id: list[str]
    fps: float

    @property
    def has_body(self) -> np.ndarray:
        return np.isfinite(self.body).all((1, 2))

    @property
    def n(self) -> int:
        return len(self.source)

    @property
    def length(self) -> int:
        return int(self.speech.shape[1]) if self.n else 0

    def select(self, keep) -> Windows:
        keep = np.asarray(keep)
        idx = np.flatnonzero(keep) if keep.dtype == bool else keep
        return Windows(
            self.speech[idx],
            self.body[idx],
            self.face[idx],
            [self.source[i] for i in idx],
            [self.start_s[i] for i in idx],
            [self.split[i] for i in idx],
            [self.window_id[i] for i in idx],
            self.fps,
        )


def _one_rate(fps: list, folder, kind: str) -> float:
    rates = sorted({round(float(f), 6) for f in fps})
    if len(rates) > 1:
        raise SchemaError(f"{folder}: {kind} rows at several frame rates {rates}: rebuild the dataset")
    if rates and not MIN_FPS <= rates[0] <= MAX_FPS:
        raise SchemaError(f"{folder}: {kind} rows with frame rate {rates[0]} (expected {MIN_FPS:g} to {MAX_FPS:g})")
    return rates[0] if rates else 0.0


def _array(values, n: int, dim: int, what: str, row: str) -> np.ndarray:
    a = np.asarray(values, np.float32)
    if a.size != n * dim:
        raise SchemaError(f"{row}: {what} has {a.size} values, expected {n} frames x {dim}")
    return a.reshape(n, dim)


def _list_column(t, name: str, n_frames: np.ndarray, dim: int, ids: list) -> np.ndarray:
    """A list column of ``t`` as one ``[rows, T, dim]`` float32 array, read by Arrow in one pass (no Python
    object per value); every row must hold ``n_frames x dim`` values."""
    import pyarrow.compute as pc  # Arrow loads with the table it reads (read_table), not on import

    col = t[name].combine_chunks() if t.num_rows else None
    if col is None:
        return np.zeros((0, 0, dim), np.float32)
    sizes = pc.list_value_length(col).to_numpy(zero_copy_only=False)
    bad = np.flatnonzero(sizes != n_frames * dim)
    if len(bad):
        i = int(bad[0])
        raise SchemaError(f"{ids[i]}: {name} has {int(sizes[i])} values, expected {int(n_frames[i])} frames x {dim}")
    return np.asarray(col.flatten().to_numpy(zero_copy_only=False), np.float32).reshape(len(sizes), -1, dim)


def read_windows(folder: str | Path, split: str | None = None) -> Windows:
    """All (audio, motion) windows of a dataset (one split, or all), face-only windows included."""
    t = read_table(folder, "audio_motion", split)
    meta = t.select(["window_id", "fps", "n_frames", "source", "start_s", "split"]).to_pydict()
    fps = _one_rate(meta["fps"], folder, "audio_motion")
    lengths = sorted(set(int(n) for n in meta["n_frames"]))
    if len(lengths) > 1:
        raise SchemaError(f"{folder}: (audio, motion) windows of several lengths {lengths}")
    T = lengths[0] if lengths else 0
    n_frames = np.asarray(meta["n_frames"], np.int64)
    ids = meta["window_id"]

    def column(name, d):
        a = _list_column(t, name, n_frames, d, ids)
        return a if len(a) else np.zeros((0, T, d), np.float32)

    return Windows(
        column("speech", SPEECH_DIM),
        column("body", BODY_DIM),
        column("face", FACE_DIM),
        list(meta["source"]),
        [float(s) for s in meta["start_s"]],
        list(meta["split"]),
        list(ids),
        fps,
    )


@dataclass
class ClipRow:
    clip_id: str
    video_id: str
    split: str
    source: str
    start_s: float
    motion: np.ndarray  # [T, 56] raw (expression weights, axis-angle)
    texts: list[str]
    events: list[tuple[str, float, float]]
    gender: str | None
    fps: float
    extra: dict = field(default_factory=dict)


def clip_events(text: str | None, folder: str | Path, row: str) -> list[tuple[str, float, float]]:
    """A clip's ``attributes`` column (JSON: ``[[name, start_s, end_s], ...]`` or ``{"events": [...]}``) as
    events; anything else (not JSON, nested too deeply, another shape) is a :class:`SchemaError`."""
    try:
        ev = json.loads(text) if text else []
        ev = ev.get("events", []) if isinstance(ev, dict) else ev
        return [(str(a), float(s), float(e)) for a, s, e in ev]
    except (ValueError, TypeError, RecursionError) as e:
        why = "nested too deeply" if isinstance(e, RecursionError) else str(e).splitlines()[0][:80]
        raise SchemaError(
            f"{folder}: clip {row}: its attributes are not a list of events ({why}): rebuild it"
        ) from None


def read_clips(folder: str | Path, split: str | None = None) -> list[ClipRow]:
    """The (text, motion) clips of a dataset (one split, or all)."""
    t = read_table(folder, "text_motion", split).to_pydict()
    fps = _one_rate(t["fps"], folder, "text_motion")
    out = []
    for i in range(len(t["clip_id"])):
        n, row = int(t["n_frames"][i]), t["clip_id"][i]
        ev = clip_events(t["attributes"][i], folder, row)
        g = t["gender"][i]
        out.append(
            ClipRow(
                row,
                t["video_id"][i],
                t["split"][i],
                t["source"][i],
                float(t["start_s"][i]),
                _array(t["motion"][i], n, FACE_DIM, "motion", row),
                list(t["texts"][i]),
                ev,
                g if g in ("female", "male") else None,
                fps,
            )
        )
    return out
