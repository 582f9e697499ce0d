"""The animated avatar: the canonical rig (``anima.core.rig``) with the ICT head on its head joint, in one glTF
file (``avatar.glb``), the speech beside it (``speech.wav``), and a preview video of both (``avatar.mp4``).

* The rig's bone lengths come from the sequence (``measure_lengths``: medians, symmetric, hands of human
  size); a sequence without any body (a face-only capture, text2face) gets the head alone.
* The head mesh is the sequence's fitted identity (the neutral face for generated motion), metres, placed
  with its ear midpoint on the ``Head`` joint; its 53 morph targets carry the expression weights.
* Where the sequence has a face, the head joint turns with the face fit's head rotation (more precise than the
  skeleton's ear and nose points); elsewhere it follows the skeleton.
* ``speech.wav``: the speech the motion goes with (the video's audio track, ``--audio``, or the gesture
  command's speech), 16-bit PCM; its offset from the motion's frame 0 (0 s) is written into ``avatar.glb``
  (``asset.extras.anima``) and ``info.json``.
"""

from __future__ import annotations

import subprocess
from functools import lru_cache
from pathlib import Path

import numpy as np

from anima.core import rig
from anima.core.rotations import matrix_to_quat, rotvec_to_matrix
from anima.errors import InputError
from anima.export.formats import export_glb, has_body
from anima.facemodel.ict import load_face_model
from anima.io.atomic import atomic_path
from anima.io.gltf import write_avatar_glb
from anima.io.sequence import TrackedSequence
from anima.io.video import FFMPEG
from anima.render.avatar import render_avatar_video

CM_TO_M = 0.01


@lru_cache(maxsize=1)
def _head_geometry() -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str], np.ndarray]:
    """(neutral skin cm, triangles, expression deltas cm, names, ear midpoint cm) of the ICT skin mesh."""
    fm = load_face_model()
    skin = fm.skin()
    ear = (skin.neutral[skin.landmarks68[0]] + skin.neutral[skin.landmarks68[16]]) / 2
    ear = np.array([0.0, ear[1], ear[2]])  # on the midline
    return skin.neutral, skin.triangles(), skin.expr_deltas, list(skin.expr_names), ear


def rig_motion(seq: TrackedSequence) -> dict:
    """The sequence's body on the rig: bone lengths (with the measurement report), root positions, local
    rotations ``[F, 66, 3, 3]`` (the head joint following the face fit where there is a face) and posed
    positions. Needs some body joints (raises InputError otherwise)."""
    if seq.body_joints is None or not np.isfinite(seq.body_joints).all(-1).any():
        raise InputError("this sequence has no body: no rig can be posed from it")
    lengths, report = rig.measure_lengths(seq.body_joints)
    root, L, P = rig.rig_rotations(seq.body_joints, lengths)
    if report["defaulted_bones"]:
        report["warning"] = (
            f"{len(report['defaulted_bones'])} bones never seen in the clip take a default "
            "adult's length: " + ", ".join(report["defaulted_bones"][:6])
        )
    if seq.tracked.any():  # the head turns with the face fit: G_head = R_face, so L_head = G_neck^T R_face
        G = np.tile(np.eye(3), (len(L), rig.N_RIG, 1, 1))
        for j in range(rig.N_RIG):
            p = rig.PARENTS_RIG[j]
            G[:, j] = L[:, j] if p < 0 else G[:, p] @ L[:, j]
        neck = G[:, rig.PARENTS_RIG[rig.HEAD]]
        L[:, rig.HEAD] = neck.transpose(0, 2, 1) @ rotvec_to_matrix(seq.rotation.astype(np.float64))
    return {"lengths": lengths, "report": report, "root": root, "local": L, "positions": P}


def _head_vertices(seq: TrackedSequence, at: np.ndarray) -> np.ndarray:
    neutral, _, _, _, ear = _head_geometry()
    skin = load_face_model().skin()
    v = skin.vertices(seq.identity) if np.any(seq.identity) else neutral
    return (np.asarray(v, np.float64) - ear) * CM_TO_M + at


def write_avatar(seq: TrackedSequence, path: str | Path, speech: str | None = None) -> dict:
    """``avatar.glb`` for ``seq`` (see the module docstring); returns what it holds."""
    extras = {"anima": {"speech": "speech.wav" if speech else None, "speech_offset_s": 0.0, "fps": seq.fps}}
    if not has_body(seq) and (seq.body_joints is None or not np.isfinite(seq.body_joints).any()):
        export_glb(seq, path)  # the head alone (a face-only capture, text2face)
        return {"kind": "head", "joints": 0, **extras["anima"]}
    m = rig_motion(seq)
    _, tris, deltas, names, _ = _head_geometry()
    head_at = rig.rest_positions(m["lengths"])[rig.HEAD]
    extras["anima"]["rig"] = {
        "joints": rig.N_RIG,
        "hand_length_m": m["report"]["hand_length_m"],
        "conventions": "docs/rig.md",
    }
    write_avatar_glb(
        path,
        rig.NAMES,
        rig.PARENTS_RIG,
        rig.rest_offsets(m["lengths"]),
        m["root"],
        matrix_to_quat(m["local"]),
        rig.HEAD,
        _head_vertices(seq, head_at),
        tris,
        np.asarray(deltas) * CM_TO_M,
        names,
        seq.expression,
        seq.fps,
        extras,
    )
    out = {"kind": "rig+head", "joints": rig.N_RIG, **extras["anima"], **m["report"]}
    return out


def write_speech(source: str, path: str | Path) -> Path:
    """The audio track of ``source`` as 16-bit PCM WAV (mono, 48 kHz), atomically."""
    with atomic_path(path) as tmp:
        r = subprocess.run(
            [
                FFMPEG,
                "-hide_banner",
                "-nostdin",
                "-v",
                "error",
                "-y",
                "-i",
                str(source),
                "-vn",
                "-ac",
                "1",
                "-ar",
                "48000",
                "-c:a",
                "pcm_s16le",
                str(tmp),
            ],
            capture_output=True,
            timeout=600,
        )
        if r.returncode != 0:
            raise InputError(
                f"cannot write the speech of {source} to WAV: "
                f"{r.stderr.decode(errors='replace').strip().splitlines()[-1:] or ['ffmpeg failed']}"
            )
    return Path(path)


def render_avatar_preview(
    seq: TrackedSequence, path: str | Path, audio: str | None = None, progress: bool = False
) -> Path:
    """``avatar.mp4``: the rig and the head, front and 3/4 views, with the speech."""
    m = rig_motion(seq)
    _, tris, deltas, _, ear = _head_geometry()
    skin = load_face_model().skin()
    base = skin.vertices(seq.identity) if np.any(seq.identity) else skin.neutral
    G = np.tile(np.eye(3), (len(m["local"]), rig.N_RIG, 1, 1))
    for j in range(rig.N_RIG):
        p = rig.PARENTS_RIG[j]
        G[:, j] = m["local"][:, j] if p < 0 else G[:, p] @ m["local"][:, j]
    render_avatar_video(
        path,
        seq.fps,
        m["positions"],
        rig.PARENTS_RIG,
        rig.HEAD,
        G[:, rig.HEAD],
        (base - ear) * CM_TO_M,
        np.asarray(deltas) * CM_TO_M,
        seq.expression,
        tris,
        audio=audio,
        progress=progress,
    )
    return Path(path)
