"""The take of ``anima live --record DIR``: its journal, its reader and its writer. The take is flushed to
``DIR/take/part-NNNNN.npz`` every :data:`CHUNK_S` seconds while it runs (each part written atomically and
listed in anima's folder marker), so a take killed with SIGKILL loses at most the last seconds and leaves a
folder that is still anima's and says what it holds: ``anima live --recover DIR`` writes the result from the
parts (:func:`recover`). A take that ends normally writes its result (:func:`write_take`) and removes the
parts. One writer of parts (:class:`Journal`) and one reader (:func:`read_parts`).

A part's arrays: ``index [n]`` source frame indices, ``t_capture [n]`` seconds since the epoch, ``face [n]``
bool, ``expression [n, 53]``, ``rotation [n, 3]`` (head axis-angle), ``body [n, 55, 3]`` (NaN where unseen
or no body), ``has_body [n]`` bool, ``legs [n, 8, 3]`` (knees, ankles, heels, toes; NaN unseen; parts of an
older anima have none), ``fps`` the source's frame rate.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from anima.capture.config import CaptureConfig
from anima.core.contract import FACE_DIM, LEG_JOINTS, N_EXPR, N_JOINTS
from anima.core.filters import gaussian_smooth
from anima.errors import InputError
from anima.export.framing import generated_sequence
from anima.export.motion import write_motion_outputs
from anima.io.atomic import remove_stale_temps, write_npz
from anima.io.outdir import OutputFolder, check_out_dir, confined, read_marker, sha256
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
    legs: np.ndarray | None = None  # [8, 3] knees, ankles, heels, toes (LEG_JOINTS), pelvis-relative, NaN unseen
    root: np.ndarray | None = None  # [3] the hips where the legs stand them (the stream's, not recorded)
    character: np.ndarray | None = None  # [53] the character's face (LiveCharacterFace; the stream's, not recorded)
    presented: np.ndarray | None = None  # [53] the fit measured from the running rest face (the stream's)

    @property
    def shown(self) -> np.ndarray:
        """The weights the outputs send (Live Link, VMC, ``--avatar``): the character's face, what the page shows;
        without one (no face model yet), the fit measured from the running rest face, else the fit's."""
        if self.character is not None:
            return self.character
        return self.expression if self.presented is None else self.presented


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
        no_legs = np.full((len(LEG_JOINTS), 3), np.nan, np.float32)
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
            legs=np.stack([no_legs if f.legs is None else f.legs for f in fr]).astype(np.float32),
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
    """The frames of an unfinished take (as :class:`LiveFrame` without rig rotations) and
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
                    a["legs"][j] if "legs" in a else None,
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
    if "legs" in h and h["legs"][0] != (k, len(LEG_JOINTS), 3):
        raise InputError(f"{path}: a part of the take whose arrays do not match (legs)")
    check_expansion(path, h, [*_PART_SHAPES, "fps", *(["legs"] if "legs" in h else [])])


def recover(folder: str, command: str | None = None) -> dict:
    """``anima live --recover DIR``: the result folder from the parts of a take that was killed."""
    check_out_dir(folder, "--recover")
    frames, fps = read_parts(folder)
    stats = {"recovered": True, "frames_tracked": len(frames), "source_fps": fps}
    with OutputFolder(folder, kind="capture", command=command) as od:
        return {"record": write_take(frames, fps, od, stats, None)}


def take_sequence(frames: list[LiveFrame], fps: float, cfg: CaptureConfig | None = None):
    """The take on the source's frame grid (frames the loop dropped are interpolated from their neighbours;
    frames before the first face hold its first values), smoothed as ``anima capture`` smooths when it is
    written: the take is whole by then, so the zero-phase filters cost the stream nothing (the live messages
    stay unsmoothed, no look-ahead): expression weights and head rotation (axis-angle) by a Gaussian of
    ``cfg.smooth_sigma`` frames, joints by one of ``cfg.body_sigma``."""
    cfg = cfg or CaptureConfig()
    if not frames:
        raise InputError("the take has no frame: nothing to record")
    last = {f.index: f for f in frames}  # a frame written again (a warm-up frame fitted later): the last one
    frames = [last[k] for k in sorted(last)]
    idx = np.array([f.index for f in frames])
    grid = np.arange(idx[0], idx[-1] + 1)
    face = np.stack([np.concatenate([f.expression, f.rotation]) for f in frames])
    ok = np.array([f.face for f in frames])
    F = np.zeros((len(grid), FACE_DIM), np.float32)
    if ok.any():
        for c in range(FACE_DIM):
            F[:, c] = np.interp(grid, idx[ok], face[ok, c])
        F[:, :N_EXPR] = np.clip(gaussian_smooth(F[:, :N_EXPR], cfg.smooth_sigma), 0, 1)
        F[:, N_EXPR:] = gaussian_smooth(F[:, N_EXPR:], cfg.smooth_sigma)
    body = None
    if any(f.body is not None for f in frames):
        B = np.stack([f.body if f.body is not None else np.full((N_JOINTS, 3), np.nan) for f in frames])
        body = np.full((len(grid), N_JOINTS, 3), np.nan, np.float32)
        for j in range(N_JOINTS):
            seen = np.isfinite(B[:, j]).all(-1)
            if seen.sum() >= 2:
                for c in range(3):
                    body[:, j, c] = np.interp(grid, idx[seen], B[seen, j, c])
        seen = np.isfinite(body).all(-1)
        flat = np.where(seen[..., None], body, 0).reshape(len(grid), -1)
        body = np.where(seen[..., None], gaussian_smooth(flat, cfg.body_sigma).reshape(body.shape), np.nan)
        body = body.astype(np.float32)
    legs = _take_legs(frames, idx, grid, cfg) if body is not None else None
    if not ok.any() and body is None:
        return None
    seq = generated_sequence(fps, face=F if ok.any() else None, body=body, meta={"recorded_by": "anima live"})
    seq.leg_joints = legs
    if legs is not None:
        seq.leg_conf = np.where(np.isfinite(legs).all(-1), 1.0, 0.0).astype(np.float32)
    return seq


def _take_legs(frames: list[LiveFrame], idx: np.ndarray, grid: np.ndarray, cfg: CaptureConfig) -> np.ndarray | None:
    """The take's legs on the frame grid (interpolated where a frame was dropped, smoothed as the body), or None
    when no frame saw them."""
    if not any(f.legs is not None and np.isfinite(f.legs).all(-1).any() for f in frames):
        return None
    Lg = np.stack([f.legs if f.legs is not None else np.full((len(LEG_JOINTS), 3), np.nan) for f in frames])
    out = np.full((len(grid), len(LEG_JOINTS), 3), np.nan, np.float32)
    for j in range(len(LEG_JOINTS)):
        seen = np.isfinite(Lg[:, j]).all(-1)
        if seen.sum() >= 2:
            for c in range(3):
                out[:, j, c] = np.interp(grid, idx[seen], Lg[seen, j, c])
            out[:, j] = gaussian_smooth(out[:, j], cfg.body_sigma)
    return out


def write_take(
    frames: list[LiveFrame], fps: float, od: OutputFolder, stats: dict, journal: Journal | None, body: str | None = None
) -> dict:
    """``--record DIR``: the take as a result folder (``capture.npz``, ``avatar.glb``, ``body.bvh``,
    ``arkit.csv``, ``info.json``; the manifest last, when ``od`` closes), written when the take ends, on the
    character's build ``body`` (``--body``; None: the default); the journal's parts go once the result is
    written."""
    seq = take_sequence(frames, fps)
    if seq is None:
        raise InputError("the take never saw a face or a body: nothing to record")
    info = {"live": {k: v for k, v in stats.items() if k != "rss_mb"}, "frames": seq.n_frames, "fps": fps}
    od.info = info
    files = write_motion_outputs(seq, od, "capture.npz", render=False, info=info, progress=False, body=body)
    if journal is not None:
        journal.discard()
    remove_parts(od.path, part_names(od.path))  # a recovered take's parts: the result now holds them
    return {"folder": str(od.path), "frames": seq.n_frames, "files": sorted(Path(p).name for p in files.values())}
