"""Generated motion as a tracked sequence, so every reader (``anima info``, ``anima export``, the viewer)
takes generated and captured motion alike.

* a generated face (text2face, the gesture generator): the neutral ICT identity, framed in a ``size``-pixel
  square (the head fills 80 % of it), with the expression weights and head rotation per frame;
* generated gestures: the 55-joint skeleton as ``body_joints``; without a face the face arrays are the
  neutral face flagged "no face" in every frame (as for a capture where no face was found).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from anima.core.contract import HEAD_ROT_DIM, N_EXPR, N_FACE_LANDMARKS
from anima.core.skeleton import JOINT_NAMES, PARENTS
from anima.facemodel.ict import load_face_model
from anima.io.sequence import FLAG_NO_FACE, TrackedSequence


@lru_cache(maxsize=1)
def _skin_height() -> tuple[float, float, tuple[str, ...], int]:
    """(lowest, highest) y of the neutral skin mesh (cm), the expression names and the identity size;
    computed once (evaluations frame thousands of generated windows)."""
    fm = load_face_model()
    ys = fm.skin().neutral[:, 1]
    return float(ys.min()), float(ys.max()), tuple(fm.expr_names), int(fm.id_deltas.shape[0])


def generated_sequence(
    fps: float,
    face: np.ndarray | None = None,
    body: np.ndarray | None = None,
    meta: dict | None = None,
    size: int = 512,
) -> TrackedSequence:
    """``face [F, 56]`` (53 expression weights + head axis-angle) and/or ``body [F, 55, 3]`` (metres,
    pelvis-relative) -> a tracked sequence at ``fps``."""
    if face is None and body is None:
        raise ValueError("generated_sequence needs a face or a body")
    lo, hi, names, n_id = _skin_height()
    F = len(face) if face is not None else len(body)
    scale = 0.8 * size / (hi - lo)  # pixels per cm: the head fills 80 % of the frame
    cy = (hi + lo) / 2
    if face is not None:
        expression = np.ascontiguousarray(face[:, :N_EXPR], np.float32)
        rotation = np.ascontiguousarray(face[:, N_EXPR : N_EXPR + HEAD_ROT_DIM], np.float32)
        flags = np.zeros(F, np.uint8)
    else:
        expression = np.zeros((F, N_EXPR), np.float32)
        rotation = np.zeros((F, HEAD_ROT_DIM), np.float32)
        flags = np.full(F, FLAG_NO_FACE, np.uint8)
    meta = dict(meta or {})
    seq = TrackedSequence(
        fps=float(fps),
        width=size,
        height=size,
        identity=np.zeros(n_id, np.float32),
        expression=expression,
        rotation=rotation,
        scale=np.full(F, scale, np.float32),
        translation=np.tile(np.array([size / 2, -size / 2 - cy * scale, 0], np.float32), (F, 1)),
        fit_error_px=np.zeros(F, np.float32) if face is not None else np.full(F, np.nan, np.float32),
        fit_nme=np.zeros(F, np.float32) if face is not None else np.full(F, np.nan, np.float32),
        flags=flags,
        landmarks=np.full((F, N_FACE_LANDMARKS, 3), np.nan, np.float32),
        expr_names=list(names),
        meta=meta,
    )
    if body is not None:
        J = np.asarray(body, np.float32).reshape(F, len(JOINT_NAMES), 3)
        seq.body_joints = J
        seq.body_joints_raw = J.copy()
        seq.body_conf = np.isfinite(J).all(-1).astype(np.float32)
        seq.body_interpolated = np.zeros(J.shape[:2], bool)
        meta.setdefault(
            "skeleton",
            {
                "joints": JOINT_NAMES,
                "parents": PARENTS.tolist(),
                "units": "m",
                "origin": "pelvis",
                "tracker": "generated",
            },
        )
    return seq
