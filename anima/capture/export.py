"""Exports of a tracked face sequence: ARKit Live Link Face CSV and GLB with morph targets."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from anima.core.rotations import matrix_to_euler, matrix_to_quat
from anima.facemodel.ict import load_face_model
from anima.io.arkit import write_live_link_csv
from anima.io.gltf import write_glb
from anima.io.sequence import TrackedSequence


def head_rotation_in_model(seq: TrackedSequence):
    """Head rotation relative to looking straight into the camera, ``[F, 3, 3]``."""
    return seq.rotation_matrices()


def export_arkit_csv(seq: TrackedSequence, path: str | Path) -> Path:
    ypr = matrix_to_euler(head_rotation_in_model(seq))
    return write_live_link_csv(path, seq.expression, seq.expr_names, seq.fps, ypr)


def export_glb(seq: TrackedSequence, path: str | Path, animate_head: bool = True) -> Path:
    skin = load_face_model().skin()
    q = matrix_to_quat(head_rotation_in_model(seq)) if animate_head else None
    return write_glb(path, skin.vertices(seq.identity), skin.triangles(), skin.expr_deltas, skin.expr_names,
                     seq.expression, seq.fps, q)


def export_bvh(seq: TrackedSequence, path: str | Path, fps: float | None = None) -> Path:
    """Upper body + hands as BVH (cm, fixed median bone lengths), optionally resampled to ``fps``."""
    from anima.capture.body import resample
    from anima.core.skeleton import JOINT_NAMES, PARENTS
    from anima.errors import InputError
    from anima.io.bvh import write_bvh

    if seq.body_joints is None:
        raise InputError("this capture has no body (captured with --face-only or schema v1): nothing to export")
    J, rate = seq.body_joints, seq.fps
    if fps and abs(fps - rate) > 1e-6:
        conf = seq.body_conf if seq.body_conf is not None else np.ones(J.shape[:2])
        J, _, _ = resample(J, conf, np.zeros(J.shape[:2], bool), rate, fps)
        rate = fps
    return write_bvh(path, J, JOINT_NAMES, PARENTS, rate)
