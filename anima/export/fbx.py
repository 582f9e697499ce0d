"""``anima export fbx SEQUENCE --out take.fbx``: the character with the take, as binary FBX 7.4 for game engines
and DCC tools (Unity's Mecanim, Unreal, Maya, MotionBuilder, Cascadeur).

The writer is Blender's own FBX exporter, run headless: anima writes its ``avatar.glb`` (the skinned character in
the person's proportions, the face morphs under ARKit's 52 names, the rig named by ``--rig``, one timeline) into a
temporary folder, Blender imports it with its glTF importer and exports it
(``anima/export/blender/fbx_from_gltf.py``): the mesh and its skin, the armature, the face morphs as blend shapes,
the armature's action and the blend shapes' weights baked on every frame. Units (the FBX header's
``UnitScaleFactor`` says which, and the importers read it): ``m`` (default: the unit is the metre, every value in
metres, no node scaled; Unity imports it at 1 unit = 1 m, Unreal converts it to its centimetres, Blender takes it
1:1) or ``cm`` (the unit is the centimetre, values in centimetres through an armature node scaled by 100, as Blender
writes it: for Maya, MotionBuilder or Cascadeur scenes in cm). Axes: +Y up and -Z forward (the character faces +Z),
converted in the data: the armature's and the mesh's nodes carry no rotation. Look: the character's colours baked
into a :data:`TEXTURE_PX` square base-colour texture over a UV set, embedded, on one material. The file's time span
and its take are the clip's frames. No Blender: exit 3 with the install line; a Blender that fails, or exits without
writing the file: exit 3 with its last words; Ctrl-C or SIGTERM: Blender is killed, nothing written. A face-only
result becomes the face on an idle body, and the export says so."""

from __future__ import annotations

import shutil
import signal
import subprocess
import tempfile
from pathlib import Path

from anima.errors import AssetNotFound
from anima.export.avatar import write_avatar
from anima.io.atomic import copy_file
from anima.io.sequence import TrackedSequence

SCRIPT = Path(__file__).parent / "blender" / "fbx_from_gltf.py"
UNITS = ("m", "cm")
MAGIC = b"Kaydara FBX Binary  \x00"
TIMEOUT_S = 1800
BROKEN_BY_CTRL_C = ("Sent an internal break event", "Blender killed", "KeyboardInterrupt")
"""What Blender (3.4) prints when Ctrl-C reaches it: it finishes the export and exits 1, or a second one ends it."""
TEXTURE_PX = 2048
"""The side of the base-colour texture, pixels (the body at one texel density over its UV set, the face at twice
it: an iris about 30 pixels across)."""


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
        out = Path(tmp) / Path(path).name  # the embedded texture's file name is under NAME.fbm/, as importers unpack it
        cmd = [exe, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(SCRIPT), "--", str(glb),
               str(out), units, repr(float(seq.fps)), str(TEXTURE_PX)]  # fmt: skip
        rc, said = run_blender(cmd, Path(tmp))
        if rc != 0 or not out.is_file() or fbx_version(out) < 7400:
            what = (f"exited {rc}" if rc != 0 else "exited 0 without writing the FBX" if not out.is_file()
                    else "wrote a file that is not a binary FBX 7.4")  # fmt: skip
            raise AssetNotFound(f"Blender ({exe}) failed to export the FBX: it {what}; its last words: {said}")
        copy_file(out, path)
    return {"format": "FBX binary", "version": fbx_version(path), "units": units, "frames": seq.n_frames,
            "fps": seq.fps, "rig": preset, "body": info.get("body"), "writer": "Blender's FBX exporter",
            "notes": notes}  # fmt: skip


def run_blender(cmd: list[str], logs: Path, timeout: float = TIMEOUT_S) -> tuple[int, str]:
    """Run Blender (``cmd``), its stdout and stderr into files in the folder ``logs``; returns its exit status
    and its last words (the end of its stderr, else of its stdout, errors first). Ctrl-C or SIGTERM here (a
    KeyboardInterrupt) kills it and waits for it before the interrupt goes on: no Blender outlives the command,
    and nothing of it is left to write; a run past ``timeout`` s is stopped so too (exit 3). A Blender that the
    interrupt itself stopped (``anima`` started with SIGINT ignored, as a job that a script puts in the
    background is, while the terminal's Ctrl-C still reaches Blender) is an interrupt too."""
    with open(logs / "blender.out", "w+b") as out, open(logs / "blender.err", "w+b") as err:
        p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=err)
        try:
            rc = p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            rc = None
        finally:  # also on KeyboardInterrupt: nothing left running
            if p.poll() is None:
                p.kill()
                p.wait()
        said = [f.seek(0) or f.read().decode(errors="replace") for f in (err, out)]
    if rc is None:
        raise AssetNotFound(f"Blender ({cmd[0]}) ran past {timeout:g} s exporting the FBX and was stopped")
    if rc == -signal.SIGINT or (rc != 0 and any(w in t for w in BROKEN_BY_CTRL_C for t in said)):
        raise KeyboardInterrupt
    return rc, last_words(said[0] if said[0].strip() else said[1])


def last_words(text: str, n: int = 300) -> str:
    """The end of a program's output as one line: its error lines when it has some, else its last lines, at
    most ``n`` characters; "(nothing)" when it printed nothing."""
    lines = [x.strip() for x in text.splitlines() if x.strip()]
    errors = [x for x in lines if x.lower().startswith(("error", "traceback")) or "Error:" in x]
    words = " ".join((errors or lines)[-6:])
    return words[-n:] if words else "(nothing)"
