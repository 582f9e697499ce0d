"""The take journal of ``anima live --record DIR``: the take is flushed to ``DIR/take/part-NNNNN.npz`` every
:data:`CHUNK_S` seconds while it runs (each part written atomically and listed in anima's folder marker), so
a take killed with SIGKILL loses at most the last seconds and leaves a folder that is still anima's and says
what it holds: ``anima live --recover DIR`` writes the result from the parts. A take that ends normally writes
its result and removes the parts. One writer (:class:`Journal`) and one reader (:func:`read_parts`).

A part's arrays: ``index [n]`` source frame indices, ``t_capture [n]`` seconds since the epoch, ``face [n]``
bool, ``expression [n, 53]``, ``rotation [n, 3]`` (head axis-angle), ``body [n, 55, 3]`` (NaN where unseen
or no body), ``has_body [n]`` bool, ``fps`` the source's frame rate.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from anima.core.contract import N_EXPR, N_JOINTS
from anima.errors import InputError
from anima.io.atomic import remove_stale_temps, write_npz
from anima.io.outdir import OutputFolder, confined, read_marker, sha256
from anima.io.validate import MAX_FRAMES, check_expansion, frame_rate, npz_headers

TAKE = "take"
CHUNK_S = 2.0
"""Seconds between flushes: what a SIGKILL can lose at most (plus the write of one part)."""
_PART = re.compile(r"^take/part-(\d{5})\.npz$")


@dataclass
class LiveFrame:
    """One tracked frame of ``anima live``."""

    index: int
    t_capture: float  # time.time() of the frame's arrival, seconds
    face: bool
    expression: np.ndarray  # [53] (0 without a face)
    rotation: np.ndarray  # [3] head axis-angle
    body: np.ndarray | None  # [55, 3] metres, pelvis-relative, NaN unseen
    local: np.ndarray | None  # [65, 3, 3] the rig's local rotations (None when read back from a part)


class Journal:
    """Buffer a take's frames and flush them to ``od``'s ``take/`` folder every ``chunk_s`` seconds."""

    def __init__(self, od: OutputFolder, fps: float, chunk_s: float = CHUNK_S, clock=time.monotonic):
        self.od, self.fps, self.chunk_s, self.clock = od, fps, chunk_s, clock
        self.buffer: list = []
        self.parts: dict[str, str] = {}
        self.last = clock()

    def add(self, frame) -> None:
        self.buffer.append(replace(frame, local=None))  # the rig's rotations are not part of the take
        if self.clock() - self.last >= self.chunk_s:
            self.flush()

    def flush(self) -> None:
        self.last = self.clock()
        if not self.buffer:
            return
        fr, self.buffer = self.buffer, []
        name = f"{TAKE}/part-{len(self.parts) + 1:05d}.npz"
        path = self.od.path / name
        path.parent.mkdir(exist_ok=True)
        none = np.full((N_JOINTS, 3), np.nan, np.float32)
        write_npz(
            path,
            compressed=False,
            index=np.array([f.index for f in fr], np.int64),
            t_capture=np.array([f.t_capture for f in fr], np.float64),
            face=np.array([f.face for f in fr], bool),
            expression=np.stack([f.expression for f in fr]).astype(np.float32),
            rotation=np.stack([f.rotation for f in fr]).astype(np.float32),
            body=np.stack([none if f.body is None else f.body for f in fr]).astype(np.float32),
            has_body=np.array([f.body is not None for f in fr], bool),
            fps=np.float64(self.fps),
        )
        self.parts[name] = sha256(path)
        self.od.journal(self.parts)

    def discard(self) -> None:
        """The take's result is written: the parts go."""
        remove_parts(self.od.path, list(self.parts))
        self.parts = {}
        self.od.journal({})


def remove_parts(folder: Path, names: list[str]) -> None:
    """Remove a take's parts (and a part's temporary file that a kill left), then the empty ``take/``."""
    for name in names:
        p = confined(folder, name)
        if p is not None:
            p.unlink(missing_ok=True)
    if (folder / TAKE).is_dir() and not (folder / TAKE).is_symlink():
        remove_stale_temps(folder / TAKE)
        try:
            (folder / TAKE).rmdir()
        except OSError:  # something else is in there: left alone
            pass


def part_names(folder: str | Path) -> list[str]:
    """The parts of an unfinished take in ``folder`` that anima's marker lists, in order."""
    marker = read_marker(Path(folder)) if Path(folder).is_dir() else None
    names = [n for n in (marker or {}).get("files", {}) if _PART.match(n)]
    return sorted(names, key=lambda n: int(_PART.match(n).group(1)))


def read_parts(folder: str | Path) -> tuple[list, float]:
    """The frames of an unfinished take (as :class:`anima.view.live.LiveFrame` without rig rotations) and
    the source's frame rate. A part that is missing, altered or unreadable is an :class:`InputError`."""
    folder = Path(folder)
    names = part_names(folder)
    if not names:
        raise InputError(f"{folder}: no unfinished take of `anima live --record` here")
    listed = read_marker(folder)["files"]
    frames, fps = [], None
    for n in names:
        p = confined(folder, n)
        if p is None or not p.is_file() or sha256(p) != listed[n]:
            raise InputError(f"{folder}/{n}: a part of the take is missing or was changed")
        check_part(p, MAX_FRAMES - len(frames))
        try:
            with np.load(p, allow_pickle=False) as z:
                a = {k: z[k] for k in z.files}
            k = len(a["index"])
            if a["expression"].shape != (k, N_EXPR) or a["body"].shape != (k, N_JOINTS, 3):
                raise ValueError("array shapes")
        except (OSError, ValueError, KeyError) as e:
            raise InputError(f"{folder}/{n}: unreadable part of the take ({e})") from None
        fps = frame_rate(a["fps"], f"{folder}/{n}")
        for j in range(k):
            frames.append(
                LiveFrame(
                    int(a["index"][j]),
                    float(a["t_capture"][j]),
                    bool(a["face"][j]),
                    a["expression"][j],
                    a["rotation"][j],
                    a["body"][j] if a["has_body"][j] else None,
                    None,
                )
            )
    return frames, fps


_PART_SHAPES = {
    "index": (), "t_capture": (), "face": (), "expression": (N_EXPR,), "rotation": (3,), "body": (N_JOINTS, 3),
    "has_body": (),
}  # fmt: skip


def check_part(path: Path, room: int) -> None:
    """Refuse a part whose arrays are not the journal's (names, shapes, one frame count of at most ``room``), or
    would take far more memory than the file holds, from its headers, before anything is read."""
    h = npz_headers(path)
    missing = sorted(set(_PART_SHAPES) - set(h)) + ([] if "fps" in h else ["fps"])
    if missing:
        raise InputError(f"{path}: not a part of an anima take (no {', '.join(missing)})")
    k = h["index"][0][0] if len(h["index"][0]) == 1 else -1
    bad = [n for n, tail in _PART_SHAPES.items() if h[n][0] != (k, *tail)] + (["fps"] if h["fps"][0] != () else [])
    if k < 0 or bad:
        raise InputError(f"{path}: a part of the take whose arrays do not match ({', '.join(bad) or 'index'})")
    if k > room:
        raise InputError(f"{path}: the take would exceed {MAX_FRAMES:,} frames")
    check_expansion(path, h, [*_PART_SHAPES, "fps"])
