"""The tracked-sequence artifact: one writer (:func:`write_sequence`), one reader (:func:`read_sequence`).

File: a NumPy ``.npz`` (no pickles) holding the arrays below plus ``meta``, a JSON string.
Schema ``anima.tracked_sequence`` version 2 (docs/artifacts.md has the same table):

=================  ===============  ===========================================================
array              shape, dtype     meaning
=================  ===============  ===========================================================
identity           (100,) f4        ICT identity coefficients, one per clip
expression         (F, 53) f4       ICT expression weights in [0, 1], names in meta.expr_names
rotation           (F, 3) f4        head rotation, model-to-camera, axis-angle (radians)
scale              (F,) f4          weak-perspective camera scale, pixels per cm
translation        (F, 3) f4        camera-space translation in pixels (u = X, v = -Y)
fit_error_px       (F,) f4          mean 2D distance fitted vs tracked landmarks (pixels)
fit_nme            (F,) f4          fit_error_px / sqrt(w*h of the tracked landmarks' bbox)
flags              (F,) u1          bit 1: no face (values interpolated from neighbours),
                                    bit 2: low confidence (large fit error or tiny face)
landmarks          (F, 478, 3) f4   raw MediaPipe landmarks (normalised x, y, z), NaN if no face
body_joints        (F, 55, 3) f4    cleaned skeleton (anima.core.skeleton), metres, pelvis-relative,
                                    NaN where missing after cleaning                      [v2, optional]
body_joints_raw    (F, 55, 3) f4    the same before cleaning                              [v2, optional]
body_conf          (F, 55) f4       per-joint confidence (pose visibility; hands 1/0)     [v2, optional]
body_interpolated  (F, 55) u1       1 where a short drop-out was filled by interpolation   [v2, optional]
body_image         (F, 55, 2) f4    raw pixel positions of the joints (2D evidence)       [v2, optional]
leg_joints         (F, 8, 3) f4     knees, ankles, heels, toes (contract LEG_JOINTS), metres,
                                    pelvis-relative, cleaned, NaN where not seen           [v2, optional]
leg_conf           (F, 8) f4        their confidence (pose visibility)                    [v2, optional]
leg_image          (F, 8, 2) f4     raw pixel positions of the leg joints (2D evidence)   [v2, optional]
camera_step        (F, 3) f4        the background's shift in the picture since the previous
                                    frame (pixels x, y; a panning or tilting camera) and the
                                    log of its scale (a zoom), 0 for a still camera       [v2, optional]
speech             (F, 28) f4       13 MFCC + log energy + first derivatives per frame    [v2, optional]
speech_valid       (F,) u1          1 where the frame's time lies inside the audio        [v2, optional]
=================  ===============  ===========================================================

Version 1 files (face only) still load: the v2 arrays are then None. meta.audio says why speech is absent
("no audio track", "unreadable: ...") and whether it is silent.

``meta``: schema, version, fps, n_frames, width, height, expr_names, camera ("weak_perspective"),
units, smoothing, tracker and face-model versions, source (path, codec, duration, size, warnings).
Readers of a newer or unknown version fail with a clear :class:`SchemaError`.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anima.core.contract import LEG_JOINTS, N_JOINTS
from anima.core.rotations import matrix_to_euler, rotvec_to_matrix
from anima.core.skeleton import LEFT_HAND, RIGHT_HAND
from anima.errors import InputError, SchemaError
from anima.io.atomic import write_npz
from anima.io.validate import (
    MAX_FRAMES,
    MAX_JSON_BYTES,
    check_expansion,
    frame_rate,
    input_file,
    npz_headers,
    parse_json,
)

SCHEMA = "anima.tracked_sequence"
VERSION = 2
FLAG_NO_FACE = 1
FLAG_LOW_CONFIDENCE = 2
ARRAYS = ("identity", "expression", "rotation", "scale", "translation", "fit_error_px", "fit_nme", "flags", "landmarks")
OPTIONAL = (
    "body_joints", "body_joints_raw", "body_conf", "body_interpolated", "body_image", "leg_joints", "leg_conf",
    "leg_image", "camera_step", "speech", "speech_valid",
)  # fmt: skip


@dataclass
class TrackedSequence:
    fps: float
    width: int
    height: int
    identity: np.ndarray
    expression: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray
    translation: np.ndarray
    fit_error_px: np.ndarray
    fit_nme: np.ndarray
    flags: np.ndarray
    landmarks: np.ndarray | None  # None when read with landmarks=False
    expr_names: list[str]
    meta: dict = field(default_factory=dict)
    body_joints: np.ndarray | None = None
    body_joints_raw: np.ndarray | None = None
    body_conf: np.ndarray | None = None
    body_interpolated: np.ndarray | None = None
    body_image: np.ndarray | None = None
    leg_joints: np.ndarray | None = None
    leg_conf: np.ndarray | None = None
    leg_image: np.ndarray | None = None
    camera_step: np.ndarray | None = None
    speech: np.ndarray | None = None
    speech_valid: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return int(self.expression.shape[0])

    @property
    def tracked(self) -> np.ndarray:
        return (self.flags & FLAG_NO_FACE) == 0

    def rotation_matrices(self) -> np.ndarray:
        return rotvec_to_matrix(self.rotation)

    def head_euler(self) -> np.ndarray:
        """(yaw, pitch, roll) radians ``[F, 3]``, ARKit order (see anima.core)."""
        return matrix_to_euler(self.rotation_matrices())

    def body_summary(self) -> dict:
        return _body_summary(self)

    def summary(self) -> dict:
        tr = self.tracked
        ok = tr & np.isfinite(self.fit_error_px)
        out = {
            "frames": self.n_frames,
            "fps": self.fps,
            "duration_s": round(self.n_frames / self.fps, 3) if self.fps else None,
            "size": [self.width, self.height],
            "tracked_fraction": round(float(tr.mean()) if self.n_frames else 0.0, 4),
            "low_confidence_frames": int(((self.flags & FLAG_LOW_CONFIDENCE) > 0).sum()),
            "mean_fit_error_px": round(float(self.fit_error_px[ok].mean()), 3) if ok.any() else None,
            "mean_fit_nme": round(float(self.fit_nme[ok].mean()), 5) if ok.any() else None,
            "schema": f"{SCHEMA}/{self.meta.get('version', VERSION)}",
            "source": (self.meta.get("source") or {}).get("path"),
        }
        if self.body_joints is not None:
            out.update(self.body_summary())
        out["speech"] = None if self.speech is None else self.meta.get("audio", {})
        if self.speech is None and "audio" in self.meta:
            out["speech"] = self.meta["audio"]
        return out


JOINT_GROUPS = {
    "hips": [1, 2],
    "torso_head": [3, 4, 5, 6],
    "arms": [7, 8, 9, 10, 11, 12],
    "left_hand": list(range(LEFT_HAND.start, LEFT_HAND.stop)),
    "right_hand": list(range(RIGHT_HAND.start, RIGHT_HAND.stop)),
}


def _body_summary(seq: TrackedSequence) -> dict:
    """Tracked fractions **after the confidence filter** of capture (a joint counts where it was detected with
    at least the cleaning's ``min_conf``), per joint group; ``body_tracked_fraction`` is the upper body the
    gestures use (torso, head and arms; the hips, often out of view, are their own group)."""
    raw = seq.body_joints_raw if seq.body_joints_raw is not None else seq.body_joints
    conf = seq.body_conf if seq.body_conf is not None else np.isfinite(raw).all(-1).astype(np.float32)
    min_conf = float(seq.meta.get("skeleton", {}).get("cleaning", {}).get("min_conf", 0.5))
    kept = np.isfinite(raw).all(-1) & (conf >= min_conf)
    kept[:, 0] |= np.isfinite(raw[:, 0]).all(-1)  # the pelvis is the origin by construction
    fin = np.isfinite(seq.body_joints).all(-1)
    groups = {g: round(float(kept[:, j].all(1).mean()), 4) for g, j in JOINT_GROUPS.items()}
    out = {"body_tracked_fraction": round(float(kept[:, 3:13].all(1).mean()), 4), "joint_groups_tracked": groups}
    for name, sl in (("left_hand", LEFT_HAND), ("right_hand", RIGHT_HAND)):
        out[f"{name}_tracked_fraction"] = groups[name]
        out[f"{name}_after_interpolation"] = round(float(fin[:, sl].all(1).mean()), 4)
    # the same rule as the writer's (anima.export.motion): a BVH whenever some body joint was tracked (the rig
    # holds or stands in for what was not seen)
    out["bvh"] = "written" if fin.any() else "not written: no body joint was tracked"
    return out


def write_sequence(seq: TrackedSequence, path: str | Path) -> Path:
    """Write atomically (temp file + rename), so an interrupted run never leaves a corrupt artifact."""
    meta = dict(seq.meta)
    meta.update(
        schema=SCHEMA,
        version=VERSION,
        fps=float(seq.fps),
        n_frames=seq.n_frames,
        width=int(seq.width),
        height=int(seq.height),
        expr_names=list(seq.expr_names),
        camera="weak_perspective",
        units={"model": "cm", "image": "px", "time": "s", "angles": "rad"},
    )
    arrays = {k: np.asarray(getattr(seq, k)) for k in ARRAYS}
    arrays.update({k: np.asarray(getattr(seq, k)) for k in OPTIONAL if getattr(seq, k) is not None})
    for k in arrays:
        if arrays[k].dtype.kind == "f":
            arrays[k] = arrays[k].astype(np.float32)
        elif arrays[k].dtype.kind == "b":
            arrays[k] = arrays[k].astype(np.uint8)
    arrays["flags"] = arrays["flags"].astype(np.uint8)
    write_npz(path, meta=np.asarray(json.dumps(meta)), **arrays)
    return Path(path)


# per-frame arrays: trailing shape (None: any size, checked against another array) and whether every value
# must be finite (NaN allowed where the artifact documents "missing")
_FRAME_ARRAYS = {
    "expression": ((None,), True),
    "rotation": ((3,), True),
    "scale": ((), True),
    "translation": ((3,), True),
    "fit_error_px": ((), False),
    "fit_nme": ((), False),
    "flags": ((), True),
    "landmarks": ((None, 3), False),
    "body_joints": ((None, 3), False),
    "body_joints_raw": ((None, 3), False),
    "body_conf": ((None,), False),
    "body_interpolated": ((None,), True),
    "body_image": ((None, 2), False),
    "leg_joints": ((len(LEG_JOINTS), 3), False),
    "leg_conf": ((len(LEG_JOINTS),), False),
    "leg_image": ((len(LEG_JOINTS), 2), False),
    "camera_step": ((3,), True),
    "speech": ((None,), False),
    "speech_valid": ((), True),
}


def _meta_of(path: Path, raw) -> dict:
    meta = parse_json(str(raw[()]), f"{path} (meta)")
    if not isinstance(meta, dict):
        raise SchemaError(f"{path}: meta is not a JSON object")
    return meta


def read_sequence(path: str | Path, landmarks: bool = True) -> TrackedSequence:
    """Read and validate a tracked sequence (see the module docstring). Every problem is one clear error:
    :class:`InputError` (missing, not an npz, damaged, inconsistent) or :class:`SchemaError` (another schema, a
    newer version). ``landmarks=False`` skips the raw landmarks (``None``), which summaries do
    not need (they are most of the file's memory)."""
    path = input_file(path, "tracked sequence")
    headers = npz_headers(path)
    if "meta" not in headers:
        raise SchemaError(f"{path} is not an anima tracked sequence (no meta)")
    if headers["meta"][0] != () or headers["meta"][1].kind != "U" or headers["meta"][1].itemsize > MAX_JSON_BYTES:
        raise SchemaError(f"{path}: meta is not a JSON string")
    wanted = [k for k in headers if k != "meta" and (landmarks or k != "landmarks")]
    check_expansion(path, headers, wanted)
    missing = [k for k in ARRAYS if k not in headers]
    if missing:
        raise SchemaError(f"{path}: missing arrays {missing}")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = _meta_of(path, z["meta"])
            _check_meta(path, meta)
            _check_shapes(path, meta, headers)
            arrays = {k: z[k] for k in wanted}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(f"cannot read {path}: damaged .npz ({str(e).splitlines()[0][:120]})") from None
    _check_values(path, arrays)
    opt = {k: arrays.get(k) for k in OPTIONAL}
    for k in ("body_interpolated", "speech_valid"):
        if opt[k] is not None:
            opt[k] = opt[k].astype(bool)
    return TrackedSequence(
        fps=float(meta["fps"]),
        width=int(meta["width"]),
        height=int(meta["height"]),
        expr_names=list(meta["expr_names"]),
        meta=meta,
        **{k: arrays.get(k) for k in ARRAYS},
        **opt,
    )


def _check_meta(path: Path, meta: dict) -> None:
    if meta.get("schema") != SCHEMA:
        raise SchemaError(f"{path}: schema {meta.get('schema')!r}, expected {SCHEMA!r}")
    try:
        version = int(meta.get("version", -1))
    except (TypeError, ValueError):
        raise SchemaError(f"{path}: schema version {meta.get('version')!r} is not a number") from None
    if version > VERSION:
        raise SchemaError(
            f"{path}: schema version {version} is newer than this anima (reads <= {VERSION}); upgrade anima"
        )
    frame_rate(meta.get("fps"), str(path))
    n = meta.get("n_frames")
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_FRAMES:
        raise InputError(f"{path}: n_frames is {n!r}: expected 1 to {MAX_FRAMES} frames")
    for k in ("width", "height"):
        if not isinstance(meta.get(k), int) or not 1 <= meta[k] <= 100_000:
            raise InputError(f"{path}: {k} is {meta.get(k)!r}: expected a positive integer")
    names = meta.get("expr_names")
    if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
        raise InputError(f"{path}: expr_names is not a list of names")
    for k in ("source", "audio", "skeleton", "tracker", "face_model", "config"):  # the nested records readers use
        if k in meta and meta[k] is not None and not isinstance(meta[k], dict):
            raise SchemaError(f"{path}: meta {k!r} is not a JSON object")
    src = meta.get("source") or {}
    if not isinstance(src.get("path", ""), str):
        raise SchemaError(f"{path}: meta source path is not text")
    cleaning = (meta.get("skeleton") or {}).get("cleaning", {})
    if not isinstance(cleaning, dict) or not isinstance(cleaning.get("min_conf", 0.5), (int, float)):
        raise SchemaError(f"{path}: meta skeleton cleaning is not a table of numbers")


def _check_shapes(path: Path, meta: dict, headers: dict) -> None:
    """Shapes and dtypes of every member, from the headers (before loading; skipped members too)."""
    F = meta["n_frames"]
    shapes = {k: sh for k, (sh, _) in headers.items() if k != "meta"}
    for k, (shape, dtype) in headers.items():
        if k == "meta":
            continue
        if dtype.kind not in "biuf":
            raise SchemaError(f"{path}: array {k!r} has dtype {dtype}, expected numbers")
        if k in _FRAME_ARRAYS:
            tail = _FRAME_ARRAYS[k][0]
            bad_tail = any(t not in (None, d) for t, d in zip(tail, shape[1:]))
            if len(shape) != 1 + len(tail) or shape[0] != F or bad_tail:
                raise InputError(f"{path}: {k} has shape {shape}, expected {F} frames (n_frames) x {tail}")
    if shapes["expression"][1] != len(meta["expr_names"]):
        n = len(meta["expr_names"])
        raise InputError(f"{path}: {shapes['expression'][1]} expression weights but {n} expr_names")
    if len(shapes["identity"]) != 1:
        raise InputError(f"{path}: identity must be a vector")
    if "body_joints" in shapes and shapes["body_joints"][1] != N_JOINTS:
        raise InputError(f"{path}: body_joints has {shapes['body_joints'][1]} joints, expected {N_JOINTS}")
    for k in ("body_joints_raw", "body_conf", "body_interpolated", "body_image"):
        if k in shapes and shapes[k][1] != N_JOINTS:
            raise InputError(f"{path}: {k} has {shapes[k][1]} joints, expected {N_JOINTS}")


# the largest magnitude a value of a real sequence can have (metres for joints and translation, radians,
# weights, pixels): a 1e30 is damage or an attack, and would reach every export as garbage
_MAX_VALUE = {"body_joints": 1e3, "body_joints_raw": 1e3, "leg_joints": 1e3, "expression": 1e2, "rotation": 1e2}
_MAX_ANY = 1e7


def _check_values(path: Path, arrays: dict) -> None:
    for k, a in arrays.items():
        if k in _FRAME_ARRAYS and _FRAME_ARRAYS[k][1] and a.dtype.kind == "f" and not np.isfinite(a).all():
            raise InputError(f"{path}: {k} holds NaN or infinite values")
        if a.dtype.kind == "f" and a.size:
            top = np.nanmax(np.abs(np.where(np.isfinite(a), a, 0)))
            if top > _MAX_VALUE.get(k, _MAX_ANY):
                raise InputError(f"{path}: {k} reaches {top:.3g}, beyond any real sequence (damaged)")
    if not np.isfinite(arrays["identity"]).all():
        raise InputError(f"{path}: identity holds NaN or infinite values")
