"""A VMC protocol receiver on 127.0.0.1 for the tests of ``anima vmc`` and ``anima live --vmc``: it parses each
UDP packet with python-osc (an OSC implementation independent of anima's writer) and checks what a VMC receiver
(VSeeFace, Warudo) relies on: the addresses, the argument types, Unity's humanoid bone names and unit
quaternions."""

import socket
import threading
import time

import numpy as np
from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage

UNITY_HUMAN_BONES = {
    "Hips", "LeftUpperLeg", "RightUpperLeg", "LeftLowerLeg", "RightLowerLeg", "LeftFoot", "RightFoot", "Spine",
    "Chest", "UpperChest", "Neck", "Head", "LeftShoulder", "RightShoulder", "LeftUpperArm", "RightUpperArm",
    "LeftLowerArm", "RightLowerArm", "LeftHand", "RightHand", "LeftToes", "RightToes", "LeftEye", "RightEye", "Jaw",
    *(f"{s}{f}{p}" for s in ("Left", "Right") for f in ("Thumb", "Index", "Middle", "Ring", "Little")
      for p in ("Proximal", "Intermediate", "Distal")),
}  # fmt: skip
"""Unity's ``HumanBodyBones`` (the names the VMC protocol's ``/VMC/Ext/Bone/Pos`` carries)."""
TYPES = {"/VMC/Ext/Root/Pos": "sfffffff", "/VMC/Ext/Bone/Pos": "sfffffff", "/VMC/Ext/Blend/Val": "sf",
         "/VMC/Ext/Blend/Apply": "", "/VMC/Ext/OK": "iiii", "/VMC/Ext/T": "f"}  # fmt: skip


def _messages(data: bytes) -> list:
    if OscBundle.dgram_is_bundle(data):
        out = []
        for c in OscBundle(data):
            out += _messages(c.dgram)
        return out
    m = OscMessage(data)
    return [(m.address, "".join("s" if isinstance(x, str) else "i" if isinstance(x, int) else "f" for x in m.params),
             list(m.params))]  # fmt: skip


class VmcReceiver:
    """``with VmcReceiver() as rx:`` then ``rx.port``; after the block (packets are parsed when it ends)
    ``rx.frames`` holds one dict per bundle: ``t`` (arrival), ``bones`` {name: (pos [3], quat [4])}, ``blend``
    {name: value}, ``ok``, ``time``; ``rx.bad`` lists what broke the protocol (an unknown address, wrong types,
    an unknown bone, a quaternion off unit)."""

    def __init__(self, idle_s: float = 5.0):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(idle_s)
        self.port = self.sock.getsockname()[1]
        self.raw: list = []
        self.frames: list = []
        self.bad: list = []

    def _listen(self) -> None:
        """Arrival times and packets only while the sender runs (parsing with python-osc costs about three times
        what anima spends writing a bundle, and would share the sender's cores); parsed when the block ends."""
        while True:
            try:
                data = self.sock.recvfrom(65536)[0]
            except TimeoutError:
                return
            self.raw.append((time.perf_counter(), data))

    def _frame(self, t: float, data: bytes) -> dict:
        f = {"t": t, "bones": {}, "blend": {}, "ok": None, "time": None, "applied": False}
        for addr, types, args in _messages(data):
            if TYPES.get(addr) != types:
                self.bad.append(f"{addr} {types}")
                continue
            if addr == "/VMC/Ext/Bone/Pos":
                q = np.array(args[4:8])
                if args[0] not in UNITY_HUMAN_BONES or abs(np.linalg.norm(q) - 1) > 1e-3:
                    self.bad.append(f"bone {args[0]} |q| {np.linalg.norm(q):.4f}")
                f["bones"][args[0]] = (np.array(args[1:4]), q)
            elif addr == "/VMC/Ext/Blend/Val":
                f["blend"][args[0]] = args[1]
            elif addr == "/VMC/Ext/Blend/Apply":
                f["applied"] = True
            elif addr == "/VMC/Ext/OK":
                f["ok"] = args
            elif addr == "/VMC/Ext/T":
                f["time"] = args[0]
        return f

    def __enter__(self):
        self.th = threading.Thread(target=self._listen, daemon=True)
        self.th.start()
        return self

    def __exit__(self, *exc):
        self.th.join()
        self.sock.close()
        self.frames = [self._frame(t, data) for t, data in self.raw]

    def moving(self) -> tuple[int, int]:
        """(bones whose rotation moves by more than 1 degree, blend values that move by more than 0.01)."""
        names = set.intersection(*(set(f["bones"]) for f in self.frames))
        Q = {n: np.stack([f["bones"][n][1] for f in self.frames]) for n in names}
        moved = sum(1 for q in Q.values() if np.degrees(2 * np.arccos(np.clip(np.abs(q @ q[0]), 0, 1))).max() > 1)
        B = [np.array([f["blend"].get(n, 0.0) for f in self.frames]) for n in self.frames[0]["blend"]]
        return moved, sum(1 for b in B if np.ptp(b) > 0.01)
