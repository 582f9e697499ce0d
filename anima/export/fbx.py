"""``anima export fbx SEQUENCE --out take.fbx``: the character with the take, as binary FBX 7.4 for game engines
and DCC tools (Unity's Mecanim, Unreal, Maya, MotionBuilder, Cascadeur).

The writer is Blender's own FBX exporter, run headless: anima writes its ``avatar.glb`` (the skinned character
in the person's proportions, the 53 face morphs, the rig named by ``--rig``, one timeline) into a temporary
folder, Blender imports it with its glTF importer and exports it (``anima/export/blender/fbx_from_gltf.py``):
the mesh and its skin, the armature, the face morphs as blend shapes, the armature's action and the blend
shapes' weights baked on every frame. Units (the FBX header's ``UnitScaleFactor`` says which, and the importers
read it): ``m`` (default: the unit is the metre, every value in metres, no node scaled; Unity imports it at 1
unit = 1 m, Unreal converts it to its centimetres, Blender takes it 1:1) or ``cm`` (the unit is the centimetre,
values in centimetres through an armature node scaled by 100, as Blender writes it: for Maya, MotionBuilder or
Cascadeur scenes in cm). Axes: Blender's FBX defaults, +Y up and -Z forward. No Blender: exit 3 with the
install line. A face-only result becomes the face on an idle body, and the export says so."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from anima.errors import AnimaError, AssetNotFound
from anima.export.avatar import write_avatar
from anima.io.atomic import copy_file
from anima.io.sequence import TrackedSequence

SCRIPT = Path(__file__).parent / "blender" / "fbx_from_gltf.py"
UNITS = ("m", "cm")
MAGIC = b"Kaydara FBX Binary  \x00"
TIMEOUT_S = 1800


def blender() -> str:
    """The Blender executable, or :class:`AssetNotFound` with the install line (exit 3)."""
    exe = shutil.which("blender")
    if exe is None:
        raise AssetNotFound(
            "anima writes FBX with Blender's exporter and Blender is not installed: sudo apt-get install blender "
            "(Debian/Ubuntu; ./dev setup does it) or get it from blender.org and put `blender` on PATH"
        )
    return exe


def fbx_version(path: str | Path) -> int:
    """The version of a binary FBX file (7400 for 7.4); 0 when it is not one."""
    with open(path, "rb") as fh:
        head = fh.read(27)
    return int.from_bytes(head[23:27], "little") if head[:21] == MAGIC else 0


def export_fbx(seq: TrackedSequence, path: str | Path, preset: str = "anima", units: str = "m") -> dict:
    """Write ``seq`` on the character as binary FBX 7.4 at ``path`` (see the module docstring); returns what it
    holds and the notes to tell the user."""
    if units not in UNITS:
        raise ValueError(f"units {units!r}: one of {UNITS}")
    exe = blender()
    notes = []
    with tempfile.TemporaryDirectory(prefix="anima-fbx-") as tmp:
        glb = Path(tmp) / "avatar.glb"
        info = write_avatar(seq, glb, preset=preset)
        if info.get("body", "").startswith("idle"):
            notes.append("this result has no body (a face-only capture or a text2face take): the FBX has the face "
                         "on an idle, breathing body")  # fmt: skip
        out = Path(tmp) / "take.fbx"
        try:
            r = subprocess.run(
                [exe, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(SCRIPT), "--",
                 str(glb), str(out), units, repr(float(seq.fps))],
                capture_output=True, text=True, timeout=TIMEOUT_S,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            raise AnimaError(f"Blender's FBX export ran past {TIMEOUT_S} s") from None
        if r.returncode != 0 or not out.is_file() or fbx_version(out) < 7400:
            tail = " ".join((r.stderr or r.stdout).split())[-300:]
            raise AnimaError(f"Blender's FBX export failed (exit {r.returncode}): {tail}")
        copy_file(out, path)
    return {"format": "FBX binary", "version": fbx_version(path), "units": units, "frames": seq.n_frames,
            "fps": seq.fps, "rig": preset, "body": info.get("body"), "writer": "Blender's FBX exporter",
            "notes": notes}  # fmt: skip
