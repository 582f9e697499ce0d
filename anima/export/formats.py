"""Exports of a tracked sequence: ARKit Live Link Face CSV, GLB with morph targets, BVH of body and hands."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anima.core import rig
from anima.core.character import Motion, Skeleton
from anima.core.contract import EXPR_NAMES
from anima.core.rotations import matrix_to_euler, matrix_to_quat
from anima.errors import InputError
from anima.export.avatar import OnCharacter, character_face, character_motion, write_avatar
from anima.export.fbx import blender, export_fbx
from anima.export.vrm import arkit_weights, vrm_expressions
from anima.facemodel.character import BUILDS
from anima.facemodel.ict import load_face_model
from anima.io.arkit import write_live_link_csv
from anima.io.bvh import write_bvh
from anima.io.gltf import write_glb, write_vrma
from anima.io.outdir import check_out_file, record_out_file
from anima.io.sequence import TrackedSequence, read_sequence
from anima.io.validate import MAX_FRAMES


def export_arkit_csv(seq: TrackedSequence, path: str | Path) -> Path:
    """The character's face (:func:`anima.export.avatar.character_face`: what ``avatar.glb`` shows) as the 52 ARKit
    columns of a Live Link Face CSV, with head yaw, pitch and roll."""
    ypr = matrix_to_euler(seq.rotation_matrices())
    return write_live_link_csv(path, character_face(seq), list(EXPR_NAMES), seq.fps, ypr)


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
        character_face(seq)[:, [list(EXPR_NAMES).index(n) for n in skin.expr_names]],
        seq.fps,
        q,
    )


MAX_RESAMPLE = 16  # the BVH export's frames at most 16 x the sequence's (15 -> 240 fps): memory stays bounded


def export_bvh(
    seq: TrackedSequence, path: str | Path, fps: float | None = None, preset: str = "anima", on=None
) -> Path:
    """The body on the character's rig (``anima.core.rig``: Mixamo's hierarchy, the character's T-pose rest in
    the person's proportions, joints named by ``preset``; legs standing unless tracked), metres, optionally
    resampled to ``fps`` (the rotations interpolated along the shortest arc). ``on``: the sequence's
    :class:`anima.export.avatar.OnCharacter` when other writers share it."""
    if seq.body_joints is None:
        raise InputError("this sequence has no body (captured with --face-only, or schema v1): nothing to export")
    if not np.isfinite(seq.body_joints).all(-1).any():
        raise InputError("no body joint was tracked in any frame of this sequence: no BVH can be made from it")
    n, rate = seq.n_frames, seq.fps
    if fps and abs(fps - rate) > 1e-6:
        n_out = int(np.ceil(n * fps / rate))
        if n_out > min(MAX_RESAMPLE * n + 1000, MAX_FRAMES):
            raise InputError(
                f"--fps {fps:g}: {n_out:,} frames from {n:,} at {rate:g} fps; anima resamples to at most "
                f"{MAX_RESAMPLE}x the frames (and {MAX_FRAMES:,} in all)"
            )
    m = (on or OnCharacter(seq)).motion()
    root, local = m["root"], m["local"]
    if fps and abs(fps - rate) > 1e-6:
        root, local = resample_motion(root, local, rate, fps)
        rate = fps
    return write_bvh(path, rig.preset_names(preset), rig.PARENTS_RIG, rig.rest_offsets(m["rest"]), root, local, rate)


def export_vrma(seq: TrackedSequence, path: str | Path) -> Path:
    """VRM Animation (``.vrma``): the body on the character's rig (idle where the sequence has none; VRM bone
    names, T-pose rest) and the face as VRM expression presets (``anima.export.vrm.VRM_PRESETS``)."""
    m = character_motion(seq)
    vrm = rig.CONVENTIONS["vrm"]
    humanoid = {vrm[n]: j for j, n in enumerate(rig.NAMES) if vrm[n]}
    expr = vrm_expressions(arkit_weights(character_face(seq), list(EXPR_NAMES)))
    extras = {"anima": {"fps": seq.fps, "frames": seq.n_frames, "unit": "metre", "body": m["report"]["body"],
                        "expressions": "anima.export.vrm.VRM_PRESETS"}}  # fmt: skip
    skeleton = Skeleton(rig.preset_names("vrm"), rig.PARENTS_RIG, m["rest"])
    return write_vrma(path, skeleton, Motion(m["root"], matrix_to_quat(m["local"]), seq.fps), humanoid, expr, extras)


def resample_motion(root: np.ndarray, local: np.ndarray, fps: float, new_fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Root positions ``[F, 3]`` (linear) and local rotations ``[F, J, 3, 3]`` (shortest arc) at ``new_fps``."""
    F = len(root)
    t = np.arange(int(np.floor((F - 1) * new_fps / fps + 1e-6)) + 1) * fps / new_fps
    i0 = np.minimum(np.floor(t).astype(int), F - 1)
    i1 = np.minimum(i0 + 1, F - 1)
    a = t - i0
    R = root[i0] * (1 - a)[:, None] + root[i1] * a[:, None]
    L = rig.slerp_rot(local[i0], local[i1], np.repeat(a[:, None], local.shape[1], 1))
    return R, L


@dataclass(frozen=True)
class ExportFormat:
    """One format of ``anima export``: the file names it writes, whether it needs a tracked face, its writer
    ``write(seq, path, options) -> notes``, and a line for ``--help``."""

    suffixes: tuple[str, ...]
    needs_face: bool
    write: Callable[[TrackedSequence, Path, dict], list[str]]
    help: str


def _notes(write):
    def run(seq, path, o):
        write(seq, path, o)
        return []

    return run


EXPORTS: dict[str, ExportFormat] = {
    "arkit": ExportFormat((".csv",), True, _notes(lambda s, p, o: export_arkit_csv(s, p)),
                          "the 52 ARKit channels and the head as a Live Link Face CSV"),
    "glb": ExportFormat((".glb",), True, _notes(lambda s, p, o: export_glb(s, p)),
                        "the fitted face with its 53 morph targets, animated"),
    "avatar": ExportFormat((".glb", ".vrm"), False, _notes(lambda s, p, o: write_avatar(s, p, preset=o["preset"])),
                           "the animated character, body and face on one timeline (.vrm: a VRM 1.0)"),
    "bvh": ExportFormat((".bvh",), False, _notes(lambda s, p, o: export_bvh(s, p, o["fps"], o["preset"])),
                        "the character's skeleton (metres, T-pose rest)"),
    "vrma": ExportFormat((".vrma",), False, _notes(lambda s, p, o: export_vrma(s, p)),
                         "a VRM Animation: plays on any VRM (the face as VRM expression presets)"),
    "fbx": ExportFormat((".fbx",), False, lambda s, p, o: export_fbx(s, p, o["preset"], o["units"])["notes"],
                        "the character with the take as binary FBX 7.4 for Unity, Unreal, Maya (Blender's exporter)"),
}  # fmt: skip
"""``anima export FORMAT``: every format, by name (the command line lists them from here)."""
FORMATS = tuple(EXPORTS)
ON_CHARACTER = ("avatar", "bvh", "vrma", "fbx")
"""The exports made on the character (its build, ``--body``, shapes them)."""


def export_file(fmt: str, sequence_path: str | Path, out: str | Path, **options) -> Path:
    """:func:`export`'s file."""
    return export(fmt, sequence_path, out, **options)[0]


def export(
    fmt: str, sequence_path: str | Path, out: str | Path, fps: float | None = None, preset: str = "anima",
    units: str = "m", body: str | None = None,
) -> tuple[Path, list[str]]:  # fmt: skip
    """``anima export FORMAT FILE --out OUT``: read a tracked sequence and write one export (``preset``: the
    joint names of a BVH, an avatar or an FBX; ``units``: an FBX's; ``body``: the character's build
    (:data:`anima.facemodel.character.BUILDS`), default the one the sequence was made with). Returns the file and
    notes for the user."""
    if fmt not in EXPORTS:
        raise InputError(f"unknown export format {fmt!r}: {', '.join(FORMATS)}")
    spec = EXPORTS[fmt]
    check_out_file(out, inputs=[sequence_path], suffixes=spec.suffixes)
    if fps is not None and fmt != "bvh":
        raise InputError("--fps applies to the BVH export only")
    if body is not None and fmt not in ON_CHARACTER:
        raise InputError(f"--body applies to the character's exports only ({', '.join(ON_CHARACTER)})")
    if body is not None and body not in BUILDS:
        raise InputError(f"unknown body {body!r}: {', '.join(BUILDS)}")
    if fmt == "fbx":
        blender()  # no writer: exit 3 with the install line, before the sequence is read
    seq = read_sequence(sequence_path)  # the landmarks too: the face the character shows
    if body is not None:
        seq.meta["body"] = body
    if spec.needs_face and not seq.tracked.any():
        raise InputError(f"no frame of {sequence_path} has a face: no {fmt} export can be made from it")
    notes = spec.write(seq, Path(out), {"fps": fps, "preset": preset, "units": units})
    record_out_file(out, f"anima export {fmt}")
    return Path(out), notes
