"""Exports of a tracked sequence: ARKit Live Link Face CSV, GLB with morph targets, BVH of body and hands."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from anima.core import rig
from anima.core.filters import resample_joints
from anima.core.rotations import matrix_to_euler, matrix_to_quat
from anima.errors import InputError
from anima.facemodel.ict import load_face_model
from anima.io.arkit import write_live_link_csv
from anima.io.bvh import write_bvh
from anima.io.gltf import write_glb
from anima.io.outdir import check_out_file
from anima.io.sequence import TrackedSequence, read_sequence
from anima.io.validate import MAX_FRAMES

FORMATS = ("arkit", "glb", "bvh")


def export_arkit_csv(seq: TrackedSequence, path: str | Path) -> Path:
    """53 ICT weights as the 52 ARKit columns of a Live Link Face CSV, with head yaw, pitch and roll."""
    ypr = matrix_to_euler(seq.rotation_matrices())
    return write_live_link_csv(path, seq.expression, seq.expr_names, seq.fps, ypr)


def export_glb(seq: TrackedSequence, path: str | Path, animate_head: bool = True) -> Path:
    """The fitted face (identity applied) with 53 morph targets, animated by the expression weights and the
    head rotation."""
    skin = load_face_model().skin()
    q = matrix_to_quat(seq.rotation_matrices()) if animate_head else None
    return write_glb(
        path,
        skin.vertices(seq.identity),
        skin.triangles(),
        skin.expr_deltas,
        skin.expr_names,
        seq.expression,
        seq.fps,
        q,
    )


MAX_RESAMPLE = 16  # the BVH export's frames at most 16 x the sequence's (15 -> 240 fps): memory stays bounded


def has_body(seq: TrackedSequence) -> bool:
    """True when some frame has every joint."""
    return seq.body_joints is not None and bool(np.isfinite(seq.body_joints).all(-1).all(-1).any())


def export_bvh(seq: TrackedSequence, path: str | Path, fps: float | None = None) -> Path:
    """Upper body + hands on the canonical rig (``anima.core.rig``: T-pose rest, conventional names, the clip's
    bone lengths with human-size hands), centimetres, optionally resampled to ``fps``."""
    if seq.body_joints is None:
        raise InputError("this sequence has no body (captured with --face-only, or schema v1): nothing to export")
    if not np.isfinite(seq.body_joints).all(-1).any():
        raise InputError("no body joint was tracked in any frame of this sequence: no BVH can be made from it")
    J, rate = seq.body_joints, seq.fps
    if fps and abs(fps - rate) > 1e-6:
        n_out = int(np.ceil(len(J) * fps / rate))
        if n_out > min(MAX_RESAMPLE * len(J) + 1000, MAX_FRAMES):
            raise InputError(
                f"--fps {fps:g}: {n_out:,} frames from {len(J):,} at {rate:g} fps; anima resamples to at most "
                f"{MAX_RESAMPLE}x the frames (and {MAX_FRAMES:,} in all)"
            )
        conf = seq.body_conf if seq.body_conf is not None else np.ones(J.shape[:2])
        J, _, _ = resample_joints(J, conf, np.zeros(J.shape[:2], bool), rate, fps)
        rate = fps
    lengths, _ = rig.measure_lengths(seq.body_joints)
    root, local, _ = rig.rig_rotations(J, lengths)
    leaves = np.array([not (rig.PARENTS_RIG == j).any() for j in range(rig.N_RIG)])
    ends = np.where(leaves[:, None], rig.REST_DIRECTIONS * 0.02, 0.0)  # 2 cm end sites along the last bone
    return write_bvh(path, rig.NAMES, rig.PARENTS_RIG, rig.rest_offsets(lengths), root, local, rate, ends)


def export_file(fmt: str, sequence_path: str | Path, out: str | Path, fps: float | None = None) -> Path:
    """``anima export FORMAT FILE --out OUT``: read a tracked sequence and write one export."""
    check_out_file(out, inputs=[sequence_path])
    seq = read_sequence(sequence_path, landmarks=False)
    if fmt == "bvh":
        return export_bvh(seq, out, fps)
    if fps is not None:
        raise InputError("--fps applies to the BVH export only")
    if not seq.tracked.any():
        raise InputError(f"no frame of {sequence_path} has a face: no {fmt} export can be made from it")
    if fmt == "arkit":
        return export_arkit_csv(seq, out)
    if fmt == "glb":
        return export_glb(seq, out)
    raise InputError(f"unknown export format {fmt!r}: {', '.join(FORMATS)}")
