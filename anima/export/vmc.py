"""The VMC protocol (protocol.vmc.info; VSeeFace, Warudo, VNyan, VMagicMirror, XR Animator receive it): one OSC
bundle per frame over UDP (:mod:`anima.io.osc`), to port 39539 by default.

Each frame's bundle, in order:

* ``/VMC/Ext/Root/Pos "root" px py pz qx qy qz qw``: the model's root, at the origin (the motion is in the hips);
* ``/VMC/Ext/Bone/Pos NAME px py pz qx qy qz qw`` for each of the 52 humanoid bones of anima's rig that Unity's
  ``HumanBodyBones`` names (:data:`UNITY_BONES`: hips to toes, every finger bone): the bone's local position
  (its rest offset from its parent; the hips: their position in the model, metres) and local rotation,
  relative to the character's T-pose rest (identity at rest, as a VRM's normalised bones are);
* ``/VMC/Ext/Blend/Val NAME v`` for the 52 ARKit channels under the "perfect sync" names (``EyeBlinkLeft``,
  ``JawOpen``, ...) and the VRM 0.x presets derived from them (``A I U E O Blink Blink_L Blink_R Joy Angry
  Sorrow Fun``), then ``/VMC/Ext/Blend/Apply``;
* ``/VMC/Ext/OK 1 3 0 tracked`` (loaded, calibrated, normal mode, tracking status) and ``/VMC/Ext/T seconds``.

Coordinates: Unity's left-handed axes, as the protocol expects. anima's are right-handed (+x the character's
left, +y up, +z forward); Unity's +x is the character's right, so a position ``(x, y, z)`` is sent as
``(-x, y, z)`` and a rotation quaternion ``(x, y, z, w)`` as ``(x, -y, -z, w)`` (the mirror ``S R S`` with
``S = diag(-1, 1, 1)``, as UniVRM converts glTF)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima.core import rig
from anima.core.contract import EXPR_NAMES
from anima.core.rotations import matrix_to_quat
from anima.errors import InputError
from anima.export.avatar import character_face, character_motion
from anima.export.retarget import find_sequence
from anima.export.vrm import arkit_weights, vrm_expressions
from anima.io.arkit import LIVE_LINK_COLUMNS
from anima.io.osc import FloatMessages, bundle, message
from anima.io.sequence import read_sequence
from anima.io.udp import parse_address, udp_socket

PORT = 39539
_THUMB = {"Metacarpal": "Proximal", "Proximal": "Intermediate", "Distal": "Distal"}


def _unity(vrm: str) -> str:
    """A VRM 1.0 humanoid bone name -> Unity's ``HumanBodyBones`` name (VRM 0.x's thumb names)."""
    for side in ("left", "right"):
        if vrm.startswith(side + "Thumb"):
            return side.capitalize() + "Thumb" + _THUMB[vrm[len(side) + 5 :]]
    return vrm[0].upper() + vrm[1:]


UNITY_BONES: dict[int, str] = {
    j: _unity(rig.CONVENTIONS["vrm"][n]) for j, n in enumerate(rig.NAMES) if rig.CONVENTIONS["vrm"][n]
}
"""Rig joint index -> Unity humanoid bone name (52 bones)."""
VRM0_PRESETS = {
    "aa": "A", "ih": "I", "ou": "U", "ee": "E", "oh": "O", "blink": "Blink", "blinkLeft": "Blink_L",
    "blinkRight": "Blink_R", "happy": "Joy", "angry": "Angry", "sad": "Sorrow", "relaxed": "Fun",
}  # fmt: skip
"""anima's VRM 1.0 presets (``anima.export.vrm.VRM_PRESETS``) -> the VRM 0.x names VMC receivers use."""
BLEND_NAMES = [*LIVE_LINK_COLUMNS, *VRM0_PRESETS.values()]

_S = np.array([-1.0, 1.0, 1.0])
_QS = np.array([1.0, -1.0, -1.0, 1.0])


def to_unity_position(p: np.ndarray) -> np.ndarray:
    return np.asarray(p, np.float64) * _S


def to_unity_rotation(q: np.ndarray) -> np.ndarray:
    """anima quaternions ``[..., 4]`` (x, y, z, w) -> Unity's (the mirror; its own inverse)."""
    return np.asarray(q, np.float64) * _QS


def blend_values(arkit: np.ndarray) -> np.ndarray:
    """``[F, 52 + 12]``: ARKit weights ``[F, 52]`` and the VRM 0.x presets (:data:`BLEND_NAMES` order)."""
    ex = vrm_expressions(arkit)
    return np.concatenate([arkit, np.stack([ex[k] for k in VRM0_PRESETS], 1)], 1)


_ROOT = message("/VMC/Ext/Root/Pos", "root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
_BONES = FloatMessages([("/VMC/Ext/Bone/Pos", name) for name in UNITY_BONES.values()], 7)
_BONE_JOINTS = np.array(list(UNITY_BONES))
_BLENDS = FloatMessages([("/VMC/Ext/Blend/Val", name) for name in BLEND_NAMES], 1)
_APPLY = message("/VMC/Ext/Blend/Apply")


def frame_bundle(local: np.ndarray, hips: np.ndarray, offsets: np.ndarray, blends: np.ndarray, t: float,
                 tracked: bool = True) -> bytes:  # fmt: skip
    """One frame: rig local rotations ``[65, 3, 3]``, the hips' position ``[3]`` (metres, the character's
    space), the rig's rest offsets ``[65, 3]``, blend values ``[64]`` (:func:`blend_values`), time ``t``."""
    q = to_unity_rotation(matrix_to_quat(local[_BONE_JOINTS]))
    p = np.array(offsets, np.float64)[_BONE_JOINTS]
    p[_BONE_JOINTS == rig.HIPS] = hips
    bones = _BONES.encode(np.concatenate([to_unity_position(p), q], 1))
    return bundle([_ROOT, *bones, *_BLENDS.encode(blends), _APPLY, message("/VMC/Ext/OK", 1, 3, 0, int(bool(tracked))),
                   message("/VMC/Ext/T", float(t))])  # fmt: skip


def parse_vmc(to: str, flag: str = "--vmc") -> tuple[str, int]:
    """``HOST:PORT`` of a VMC receiver (one line, exit 2, for anything else)."""
    return parse_address(to, flag, f"127.0.0.1:{PORT} (the VMC protocol's port)")


class VmcSender:
    """VMC bundles to ``(host, port)``. A receiver that goes away does not stop the sender: each failed send
    is counted (``unsent``)."""

    def __init__(self, target: tuple[str, int], rest: np.ndarray):
        self.target = target
        self.offsets = rig.rest_offsets(rest)
        self.sock = udp_socket(target[0])
        self.sent = self.unsent = 0
        self.t0 = time.perf_counter()

    def send(self, local: np.ndarray, hips: np.ndarray, blends: np.ndarray, tracked: bool = True) -> None:
        data = frame_bundle(local, hips, self.offsets, blends, time.perf_counter() - self.t0, tracked)
        try:
            self.sock.sendto(data, self.target)
            self.sent += 1
        except OSError:
            self.unsent += 1

    def close(self) -> None:
        self.sock.close()


def send(result: str | Path, to: str, loops: int = 1, progress: bool = True) -> dict:
    """``anima vmc RESULT --to HOST:PORT``: play a result's sequence (capture, gesture, text2face) into a VMC
    receiver at its own frame rate, ``loops`` times; returns what was sent."""
    target = parse_vmc(to, "--to")
    if not 1 <= loops <= 1_000_000:
        raise InputError("--loops: 1 to 1,000,000")
    seq = read_sequence(find_sequence(result))  # the landmarks too: the face the character shows
    m = character_motion(seq)
    blends = blend_values(arkit_weights(character_face(seq), list(EXPR_NAMES)))
    out = VmcSender(target, m["rest"])
    F, fps = seq.n_frames, seq.fps
    t0 = time.perf_counter()
    try:
        for k in tqdm(range(F * loops), disable=not progress, desc="vmc", unit="frame"):
            f = k % F
            delay = t0 + k / fps - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            out.send(m["local"][f], m["root"][f], blends[f], bool(seq.tracked[f]))
    finally:
        out.close()
    wall = time.perf_counter() - t0
    return {"to": f"{target[0]}:{target[1]}", "frames": F * loops, "bundles_sent": out.sent,
            "unsent": out.unsent, "seconds": round(wall, 3), "bundles_per_s": round(out.sent / max(wall, 1e-9), 2),
            "fps": fps, "bones": len(UNITY_BONES), "blend_values": len(BLEND_NAMES)}  # fmt: skip
