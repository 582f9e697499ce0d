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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anima.core.rotations import matrix_to_euler, rotvec_to_matrix
from anima.core.skeleton import LEFT_HAND, RIGHT_HAND
from anima.errors import InputError, SchemaError
from anima.io.atomic import atomic_path

SCHEMA = "anima.tracked_sequence"
VERSION = 2
FLAG_NO_FACE = 1
FLAG_LOW_CONFIDENCE = 2
ARRAYS = ("identity", "expression", "rotation", "scale", "translation", "fit_error_px", "fit_nme", "flags", "landmarks")
OPTIONAL = ("body_joints", "body_joints_raw", "body_conf", "body_interpolated", "body_image", "speech", "speech_valid")


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
    landmarks: np.ndarray
    expr_names: list[str]
    meta: dict = field(default_factory=dict)
    body_joints: np.ndarray | None = None
    body_joints_raw: np.ndarray | None = None
    body_conf: np.ndarray | None = None
    body_interpolated: np.ndarray | None = None
    body_image: np.ndarray | None = None
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
            "source": self.meta.get("source", {}).get("path"),
        }
        if self.body_joints is not None:
            raw = np.isfinite(self.body_joints_raw).all(-1) if self.body_joints_raw is not None else None
            fin = np.isfinite(self.body_joints).all(-1)
            out["body_tracked_fraction"] = round(float(raw[:, :13].all(1).mean()), 4) if raw is not None else None
            for name, sl in (("left_hand", LEFT_HAND), ("right_hand", RIGHT_HAND)):
                if raw is not None:
                    out[f"{name}_tracked_fraction"] = round(float(raw[:, sl].all(1).mean()), 4)
                out[f"{name}_after_interpolation"] = round(float(fin[:, sl].all(1).mean()), 4)
        out["speech"] = None if self.speech is None else self.meta.get("audio", {})
        if self.speech is None and "audio" in self.meta:
            out["speech"] = self.meta["audio"]
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
    with atomic_path(path, ".tmp.npz") as tmp:
        np.savez_compressed(tmp, meta=np.asarray(json.dumps(meta)), **arrays)
    return Path(path)


def read_sequence(path: str | Path) -> TrackedSequence:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"tracked sequence not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            if "meta" not in z.files:
                raise SchemaError(f"{path} is not an anima tracked sequence (no meta)")
            meta = json.loads(str(z["meta"]))
            arrays = {k: z[k] for k in z.files if k != "meta"}
    except (OSError, ValueError) as e:
        raise InputError(f"cannot read {path}: not a valid .npz ({e})") from None
    if meta.get("schema") != SCHEMA:
        raise SchemaError(f"{path}: schema {meta.get('schema')!r}, expected {SCHEMA!r}")
    if int(meta.get("version", -1)) > VERSION:
        raise SchemaError(
            f"{path}: schema version {meta.get('version')} is newer than this anima (reads <= {VERSION}); upgrade anima"
        )
    missing = [k for k in ARRAYS if k not in arrays]
    if missing:
        raise SchemaError(f"{path}: missing arrays {missing}")
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
        **{k: arrays[k] for k in ARRAYS},
        **opt,
    )
