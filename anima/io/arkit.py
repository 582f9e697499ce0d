"""ARKit blendshape CSV in Epic's Live Link Face layout (61 values: 52 blendshapes + head + eyes).

Columns: ``Timecode, BlendShapeCount, EyeBlinkLeft ... TongueOut, HeadYaw, HeadPitch, HeadRoll,
LeftEyeYaw ... RightEyeRoll``; Timecode ``HH:MM:SS:FF.mmm`` (frame number and its fraction).
ICT names map to ARKit by dropping ``_L/_R`` for ``Left/Right``; ICT splits ``browInnerUp`` and
``cheekPuff`` into left/right, which are averaged. ``TongueOut`` and eye rotations are written as 0.

The same table names the character's morph targets in every file anima writes (:data:`ARKIT_NAMES`: Apple's
names, ``eyeBlinkLeft`` ... ``tongueOut``) and makes them from the 53 ICT-named ones (:func:`arkit_sources`).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from anima.io.atomic import write_text

LIVE_LINK_COLUMNS = [
    "EyeBlinkLeft",
    "EyeLookDownLeft",
    "EyeLookInLeft",
    "EyeLookOutLeft",
    "EyeLookUpLeft",
    "EyeSquintLeft",
    "EyeWideLeft",
    "EyeBlinkRight",
    "EyeLookDownRight",
    "EyeLookInRight",
    "EyeLookOutRight",
    "EyeLookUpRight",
    "EyeSquintRight",
    "EyeWideRight",
    "JawForward",
    "JawLeft",
    "JawRight",
    "JawOpen",
    "MouthClose",
    "MouthFunnel",
    "MouthPucker",
    "MouthLeft",
    "MouthRight",
    "MouthSmileLeft",
    "MouthSmileRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "MouthDimpleLeft",
    "MouthDimpleRight",
    "MouthStretchLeft",
    "MouthStretchRight",
    "MouthRollLower",
    "MouthRollUpper",
    "MouthShrugLower",
    "MouthShrugUpper",
    "MouthPressLeft",
    "MouthPressRight",
    "MouthLowerDownLeft",
    "MouthLowerDownRight",
    "MouthUpperUpLeft",
    "MouthUpperUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BrowInnerUp",
    "BrowOuterUpLeft",
    "BrowOuterUpRight",
    "CheekPuff",
    "CheekSquintLeft",
    "CheekSquintRight",
    "NoseSneerLeft",
    "NoseSneerRight",
    "TongueOut",
]
HEAD_COLUMNS = [
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
]


ARKIT_NAMES = [c[0].lower() + c[1:] for c in LIVE_LINK_COLUMNS]
"""Apple's 52 ARKit blendshape names as perfect-sync rigs and engines' importers spell them (lower camelCase, as
``ARFaceAnchor.BlendShapeLocation`` names its constants: ``eyeBlinkLeft``, ``browInnerUp``, ``cheekPuff``,
``tongueOut``), in :data:`LIVE_LINK_COLUMNS` order: the character's morph targets in ``avatar.glb``, the ``.vrm``
and the FBX (``anima.facemodel.character.arkit_morphs``)."""


def header() -> list[str]:
    """The CSV's header row, as anima writes it."""
    return ["Timecode", "BlendShapeCount", *LIVE_LINK_COLUMNS, *HEAD_COLUMNS]


def arkit_name(ict: str) -> str:
    base = ict[:-2] if ict.endswith(("_L", "_R")) else ict
    side = {"_L": "Left", "_R": "Right"}.get(ict[-2:], "")
    return base[0].upper() + base[1:] + side


def arkit_sources(expr_names) -> list[list[int]]:
    """The one table from ICT's expression names to ARKit's 52: per :data:`LIVE_LINK_COLUMNS` column, the indices
    into ``expr_names`` it is made of (``_L/_R`` for ``Left/Right``; ICT's two halves of ``browInnerUp`` and of
    ``cheekPuff`` both go to the one ARKit channel; ``TongueOut``: none). A column's weight is its sources' mean
    (:func:`ict_to_arkit`); a character's morph for it, their deltas summed."""
    col = {n: i for i, n in enumerate(LIVE_LINK_COLUMNS)}
    out: list[list[int]] = [[] for _ in LIVE_LINK_COLUMNS]
    for j, n in enumerate(expr_names):
        a = arkit_name(n)
        if a not in col:
            a = arkit_name(n[:-2]) if n.endswith(("_L", "_R")) else a  # browInnerUp_L -> BrowInnerUp
        if a in col:
            out[col[a]].append(j)
    return out


def ict_to_arkit(expression: np.ndarray, expr_names: list[str]) -> np.ndarray:
    """``[F, 53]`` ICT weights -> ``[F, 52]`` ARKit weights in LIVE_LINK_COLUMNS order (each column its
    :func:`arkit_sources`' mean; 0 where it has none)."""
    acc = np.zeros((expression.shape[0], len(LIVE_LINK_COLUMNS)))
    for c, src in enumerate(arkit_sources(expr_names)):
        for j in src:
            acc[:, c] += expression[:, j]
        acc[:, c] /= max(len(src), 1)
    return acc


def timecode(i: int, fps: float) -> str:
    t = i / fps
    h, rem = divmod(t, 3600)
    m, s = divmod(rem, 60)
    frame = (s - int(s)) * fps
    return (
        f"{int(h):02d}:{int(m):02d}:{int(s):02d}:{int(frame):02d}.{int(round((frame - int(frame)) * 1000)) % 1000:03d}"
    )


def write_live_link_csv(
    path: str | Path, expression: np.ndarray, expr_names: list[str], fps: float, head_ypr: np.ndarray | None = None
) -> Path:
    """Write the CSV. head_ypr ``[F, 3]`` radians (yaw, pitch, roll), or None for zeros. Blendshape weights are
    written clamped to ARKit's [0, 1] (what Live Link and Unreal read)."""
    ark = np.clip(ict_to_arkit(np.asarray(expression), expr_names), 0.0, 1.0)
    F = ark.shape[0]
    head = np.zeros((F, len(HEAD_COLUMNS)))
    if head_ypr is not None:
        head[:, :3] = head_ypr
    fh = io.StringIO(newline="")
    w = csv.writer(fh)
    w.writerow(header())
    n = len(LIVE_LINK_COLUMNS) + len(HEAD_COLUMNS)
    for i in range(F):
        w.writerow([timecode(i, fps), n, *(f"{v:.6f}" for v in ark[i]), *(f"{v:.6f}" for v in head[i])])
    return write_text(path, fh.getvalue())


def read_live_link_csv(path: str | Path) -> tuple[list[str], np.ndarray]:
    """Return (column names after BlendShapeCount, values ``[F, 61]``)."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    return header[2:], np.array([[float(x) for x in r[2:]] for r in rows[1:]])
