"""The canonical rig every exported skeleton uses (BVH, glTF): conventional joint names, a T-pose rest, one
set of bone lengths per clip, and human-size hands. Pure functions on ``[F, 55, 3]`` anima joints (metres,
``anima.core.skeleton``); the exports in ``anima.export`` turn its rotations into files.

* **Joints** (53): anima's 55 without the two hand-wrist joints, which coincide with the body's wrists (their
  fingers hang off ``LeftHand`` / ``RightHand``). Names follow the common Mixamo-style convention
  (``Hips, Spine, Neck, Head, LeftArm, LeftForeArm, LeftHand, LeftHandIndex1...``); :data:`CONVENTIONS` maps
  them to Mixamo (``mixamorig:`` prefix), VRM 1.0 humanoid and Unreal mannequin names (``docs/rig.md``).
* **Rest pose**: a T-pose in the character's frame (+x its left, +y up, +z forward, as anima's camera
  convention for a person facing the camera): spine, neck and head up, arms out along +-x, palms down, fingers
  along the arm, thumbs forward; hips out to the sides; the nose forward.
* **Bone lengths**: each bone's median over the clip (left and right averaged, so the rig is symmetric);
  bones never seen take :data:`DEFAULT_LENGTHS` (an adult), so a clip where the body is never fully visible
  still has a skeleton (with a warning).
* **Hands**: MediaPipe's hands come out about 30 % small; both hands are scaled so that wrist to middle
  fingertip is ``0.73 x`` the forearm (elbow to wrist), an anthropometric ratio of adults, kept within 17-20 cm.
"""

from __future__ import annotations

import numpy as np

from anima.core.bvh_math import _kabsch, _min_rotation, local_rotations
from anima.core.skeleton import JOINT_NAMES

_BODY = {
    "pelvis": "Hips",
    "left_hip": "LeftUpLeg",
    "right_hip": "RightUpLeg",
    "spine": "Spine",
    "neck": "Neck",
    "head": "Head",
    "nose": "Nose",
    "left_shoulder": "LeftArm",
    "left_elbow": "LeftForeArm",
    "left_wrist": "LeftHand",
    "right_shoulder": "RightArm",
    "right_elbow": "RightForeArm",
    "right_wrist": "RightHand",
}
_FINGERS = {"thumb": "Thumb", "index": "Index", "middle": "Middle", "ring": "Ring", "pinky": "Pinky"}
_SEGMENTS = {
    "thumb": ("cmc", "mcp", "ip", "tip"),
    "index": ("mcp", "pip", "dip", "tip"),
    "middle": ("mcp", "pip", "dip", "tip"),
    "ring": ("mcp", "pip", "dip", "tip"),
    "pinky": ("mcp", "pip", "dip", "tip"),
}


def _build():
    """(anima joint of each rig joint, -1 for the rig's zero-length joints; names; parents)."""
    src, names, parents = [], [], []

    def add(name, parent, source=-1):
        src.append(source)
        names.append(name)
        parents.append(names.index(parent) if parent else -1)

    a = JOINT_NAMES.index
    add("Hips", None, a("pelvis"))
    add("Spine", "Hips", a("spine"))
    add("Neck", "Spine", a("neck"))
    add("Head", "Neck", a("head"))
    add("Nose", "Head", a("nose"))
    for side in ("Left", "Right"):
        lo = side.lower()
        add(f"{side}Shoulder", "Neck")  # zero length: the collarbone turns on its own
        add(f"{side}Arm", f"{side}Shoulder", a(f"{lo}_shoulder"))
        add(f"{side}ForeArm", f"{side}Arm", a(f"{lo}_elbow"))
        add(f"{side}Hand", f"{side}ForeArm", a(f"{lo}_wrist"))
        for finger, segs in _SEGMENTS.items():
            base = f"{side}Hand{_FINGERS[finger]}"
            add(f"{base}0", f"{side}Hand")  # zero length: each finger turns on its own at the wrist
            for k, seg in enumerate(segs, 1):
                add(f"{base}{k}", f"{base}{k - 1}", a(f"{lo}_hand_{finger}_{seg}"))
    add("Pelvis", "Hips")  # zero length: the hip line turns on its own, the torso on the spine
    add("LeftUpLeg", "Pelvis", a("left_hip"))
    add("RightUpLeg", "Pelvis", a("right_hip"))
    return np.array(src), names, np.array(parents)  # depth-first order: as a BVH file lists the joints


SOURCE, NAMES, PARENTS_RIG = _build()  # rig joint i is anima joint SOURCE[i] (-1: a zero-length joint)
N_RIG = len(NAMES)
HEAD = NAMES.index("Head")
ZERO_LENGTH = np.array([s < 0 for s in SOURCE])
# the joints whose directions turn each joint: its one bone; the wrist turns with the palm (the four finger
# roots, a best rigid fit)
DRIVERS = {j: [c for c in np.flatnonzero(PARENTS_RIG == j) if not ZERO_LENGTH[c]] for j in range(N_RIG)}
for _j in range(N_RIG):
    if ZERO_LENGTH[_j] and not DRIVERS[_j]:
        DRIVERS[_j] = [c for c in np.flatnonzero(PARENTS_RIG == _j)][:1]
    if NAMES[_j].endswith("Hand"):
        DRIVERS[_j] = [NAMES.index(f"{NAMES[_j]}{f}1") for f in ("Index", "Middle", "Ring", "Pinky")]
assert N_RIG == 66


def _rest_directions() -> np.ndarray:
    d = np.zeros((N_RIG, 3))
    spread = {
        "Thumb": (0.55, 0.0, 0.84),
        "Index": (0.97, 0.0, 0.25),
        "Middle": (1.0, 0.0, 0.04),
        "Ring": (0.99, 0.0, -0.15),
        "Pinky": (0.94, 0.0, -0.33),
    }
    thumb = [(0.55, 0.0, 0.84), (0.71, 0.0, 0.71), (0.87, 0.0, 0.5), (0.94, 0.0, 0.34)]
    for i, n in enumerate(NAMES):
        sx = 1.0 if n.startswith("Left") else -1.0
        if n == "Hips" or ZERO_LENGTH[i]:
            continue
        if n in ("Spine", "Neck", "Head"):
            d[i] = (0, 1, 0)
        elif n == "Nose":
            d[i] = (0, 0, 1)
        elif n.endswith(("UpLeg", "Arm", "ForeArm", "Hand")):
            d[i] = (sx, 0, 0)
        else:  # fingers: Left/Right Hand <Finger> <k>
            finger, k = n[len("LeftHand") if sx > 0 else len("RightHand") : -1], int(n[-1])
            v = thumb[k - 1] if finger == "Thumb" else (spread[finger] if k == 1 else (1.0, 0.0, 0.0))
            d[i] = (sx * v[0], v[1], v[2])
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return np.where(n > 0, d / np.maximum(n, 1e-12), 0.0)


REST_DIRECTIONS = _rest_directions()

# an adult's bone lengths (metres) for bones a clip never shows
# (the bone of a joint runs from its parent to it: LeftForeArm's is the upper arm, LeftHand's the forearm)
_DEFAULT = {
    "LeftUpLeg": 0.10,
    "Spine": 0.25,
    "Neck": 0.25,
    "Head": 0.12,
    "Nose": 0.10,
    "LeftArm": 0.19,
    "LeftForeArm": 0.29,
    "LeftHand": 0.26,
}
_DEFAULT_HAND = {
    "Thumb": (0.045, 0.04, 0.032, 0.028),
    "Index": (0.095, 0.042, 0.025, 0.022),
    "Middle": (0.092, 0.047, 0.028, 0.024),
    "Ring": (0.085, 0.043, 0.027, 0.023),
    "Pinky": (0.08, 0.033, 0.019, 0.02),
}


def _default_lengths() -> np.ndarray:
    L = np.zeros(N_RIG)
    for i, n in enumerate(NAMES):
        base = n.replace("Right", "Left")
        if ZERO_LENGTH[i]:
            continue
        if base in _DEFAULT:
            L[i] = _DEFAULT[base]
        elif "Hand" in base and base != "LeftHand":
            finger = base[len("LeftHand") : -1]
            L[i] = _DEFAULT_HAND[finger][int(base[-1]) - 1]
    return L


DEFAULT_LENGTHS = _default_lengths()
HAND_TO_FOREARM = 0.73  # adult hand length / forearm length (wrist crease to middle fingertip; elbow to wrist)
HAND_RANGE_M = (0.17, 0.20)


def _chain(name: str) -> list[int]:
    return [NAMES.index(f"{name}{k}") for k in range(1, 5)]


def rig_positions(J: np.ndarray) -> np.ndarray:
    """Anima joints ``[F, 55, 3]`` -> the rig's joints ``[F, 53, 3]`` (a body wrist missing where its hand was
    seen takes the hand's own wrist)."""
    J = np.asarray(J, np.float64)
    P = J[:, np.maximum(SOURCE, 0)].copy()
    for side in ("left", "right"):
        body, hand = JOINT_NAMES.index(f"{side}_wrist"), JOINT_NAMES.index(f"{side}_hand_wrist")
        lost = ~np.isfinite(J[:, body]).all(-1) & np.isfinite(J[:, hand]).all(-1)
        P[lost, NAMES.index(f"{side.capitalize()}Hand")] = J[lost, hand]
    for j in np.flatnonzero(ZERO_LENGTH):  # parents come first
        P[:, j] = P[:, PARENTS_RIG[j]]
    return P


def measure_lengths(J: np.ndarray) -> tuple[np.ndarray, dict]:
    """Bone lengths ``[53]`` of a clip (see the module docstring) and a report: the bones that took the
    default, the measured and the rig's hand length."""
    P = rig_positions(J)
    par = np.where(PARENTS_RIG < 0, np.arange(N_RIG), PARENTS_RIG)
    with np.errstate(all="ignore"):
        L = np.linalg.norm(P - P[:, par], axis=-1)
        med = np.array([np.nanmedian(L[:, i]) if np.isfinite(L[:, i]).any() else np.nan for i in range(N_RIG)])
    for i, n in enumerate(NAMES):  # symmetric: average left and right where both are seen
        if n.startswith("Left"):
            r = NAMES.index("Right" + n[4:])
            pair = [x for x in (med[i], med[r]) if np.isfinite(x)]
            if pair:
                med[i] = med[r] = float(np.mean(pair))
    bones = [i for i in range(1, N_RIG) if not ZERO_LENGTH[i]]
    defaulted = [NAMES[i] for i in bones if not np.isfinite(med[i]) or med[i] <= 0]
    out = np.where(np.isfinite(med) & (med > 0), med, DEFAULT_LENGTHS)
    out[0] = 0.0
    out[ZERO_LENGTH] = 0.0
    measured = float(sum(out[i] for i in _chain("LeftHandMiddle")))
    forearm = out[NAMES.index("LeftHand")]  # elbow to wrist
    target = float(np.clip(HAND_TO_FOREARM * forearm, *HAND_RANGE_M))
    s = target / measured if measured > 0 else 1.0
    for i, n in enumerate(NAMES):
        if "Hand" in n and not n.endswith("Hand"):  # the fingers (zero-length joints stay 0)
            out[i] *= s
    report = {
        "defaulted_bones": defaulted,
        "hand_length_measured_m": round(measured, 4),
        "hand_length_m": round(target, 4),
        "forearm_m": round(float(forearm), 4),
    }
    return out, report


def rest_offsets(lengths: np.ndarray) -> np.ndarray:
    """T-pose offsets ``[53, 3]`` (child minus parent, metres)."""
    return REST_DIRECTIONS * np.asarray(lengths)[:, None]


def rest_positions(lengths: np.ndarray) -> np.ndarray:
    """Global T-pose joint positions ``[53, 3]`` (the hips at the origin)."""
    off = rest_offsets(lengths)
    P = np.zeros((N_RIG, 3))
    for i in range(1, N_RIG):
        P[i] = P[PARENTS_RIG[i]] + off[i]
    return P


def _fill(P: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Missing joints: held from the nearest frame where seen; never seen: the rest offset from the parent."""
    P = P.copy()
    F = len(P)
    off = rest_offsets(lengths)
    for j in range(N_RIG):
        if ZERO_LENGTH[j]:
            P[:, j] = P[:, PARENTS_RIG[j]]
            continue
        ok = np.isfinite(P[:, j]).all(-1)
        if ok.all():
            continue
        if ok.any():
            idx = np.flatnonzero(ok)
            near = idx[np.clip(np.searchsorted(idx, np.arange(F)), 0, len(idx) - 1)]
            prev = idx[np.clip(np.searchsorted(idx, np.arange(F)) - 1, 0, len(idx) - 1)]
            pick = np.where(np.abs(prev - np.arange(F)) < np.abs(near - np.arange(F)), prev, near)
            P[~ok, j] = P[pick[~ok], j]
        else:
            P[:, j] = (P[:, PARENTS_RIG[j]] if j else 0.0) + off[j]
    return P


def pose_on_rig(J: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The clip's motion on the rig: joint positions ``[F, 53, 3]`` with the rig's bone lengths (each bone
    keeps its direction; missing joints held or put at rest, see :func:`_fill`)."""
    P = _fill(rig_positions(J), lengths)
    out = P.copy()
    for j in range(1, N_RIG):
        p = PARENTS_RIG[j]
        if ZERO_LENGTH[j]:
            out[:, j] = out[:, p]
            continue
        d = P[:, j] - P[:, p]
        n = np.linalg.norm(d, axis=-1, keepdims=True)
        unit = np.where(n > 1e-9, d / np.maximum(n, 1e-9), REST_DIRECTIONS[j])
        out[:, j] = out[:, p] + lengths[j] * unit
    return out


def solve_rotations(P: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Global rotations ``[F, 66, 3, 3]`` turning the T-pose into positions ``P`` (made by
    :func:`pose_on_rig`). A joint with one driver bone: its parent's rotation followed by the smallest rotation
    aligning that bone (stable twist); the wrists: a best rigid fit of the palm (four finger roots); a leaf: its
    parent's rotation. Every bone then points exactly where ``P`` has it."""
    F = len(P)
    rest = rest_positions(lengths)
    G = np.tile(np.eye(3), (F, N_RIG, 1, 1))
    for j in range(N_RIG):
        base = G[:, PARENTS_RIG[j]] if PARENTS_RIG[j] >= 0 else np.tile(np.eye(3), (F, 1, 1))
        drv = DRIVERS[j]
        if not drv:
            G[:, j] = base
        elif len(drv) == 1:
            G[:, j] = _min_rotation(base @ (rest[drv[0]] - rest[j]), P[:, drv[0]] - P[:, j]) @ base
        else:
            A = np.broadcast_to(rest[drv] - rest[j], (F, len(drv), 3))
            G[:, j] = _kabsch(A, P[:, drv] - P[:, j][:, None])
    return G


def rig_rotations(J: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(root positions ``[F, 3]``, local rotations ``[F, 53, 3, 3]`` relative to the T-pose, the posed rig
    positions ``[F, 53, 3]``). Forward kinematics of the rotations from the T-pose offsets gives the posed
    positions."""
    P = pose_on_rig(J, lengths)
    G = solve_rotations(P, lengths)
    return P[:, 0], local_rotations(G, PARENTS_RIG), P


# Names of the rig's joints in other conventions ("" where the convention has no such joint).
def _conventions() -> dict[str, dict[str, str]]:
    vrm = {
        "Hips": "hips",
        "LeftUpLeg": "leftUpperLeg",
        "RightUpLeg": "rightUpperLeg",
        "Spine": "spine",
        "Neck": "neck",
        "Head": "head",
        "Nose": "",
        "LeftArm": "leftUpperArm",
        "LeftForeArm": "leftLowerArm",
        "LeftHand": "leftHand",
        "RightArm": "rightUpperArm",
        "RightForeArm": "rightLowerArm",
        "RightHand": "rightHand",
    }
    ue = {
        "Hips": "pelvis",
        "LeftUpLeg": "thigh_l",
        "RightUpLeg": "thigh_r",
        "Spine": "spine_01",
        "Neck": "neck_01",
        "Head": "head",
        "Nose": "",
        "LeftArm": "upperarm_l",
        "LeftForeArm": "lowerarm_l",
        "LeftHand": "hand_l",
        "RightArm": "upperarm_r",
        "RightForeArm": "lowerarm_r",
        "RightHand": "hand_r",
    }
    vrm_seg = {
        "Thumb": ("Metacarpal", "Proximal", "Distal", ""),
        "Index": ("Proximal", "Intermediate", "Distal", ""),
        "Middle": ("Proximal", "Intermediate", "Distal", ""),
        "Ring": ("Proximal", "Intermediate", "Distal", ""),
        "Pinky": ("Proximal", "Intermediate", "Distal", ""),
    }
    ue_name = {"Thumb": "thumb", "Index": "index", "Middle": "middle", "Ring": "ring", "Pinky": "pinky"}
    extra = {
        "Pelvis": ("", "", ""),
        "LeftShoulder": ("mixamorig:LeftShoulder", "leftShoulder", "clavicle_l"),
        "RightShoulder": ("mixamorig:RightShoulder", "rightShoulder", "clavicle_r"),
    }
    out = {"mixamo": {}, "vrm": {}, "unreal": {}}
    for n in NAMES:
        out["mixamo"][n] = "" if n == "Nose" or n.endswith("0") else f"mixamorig:{n}"
        if n in extra:
            out["mixamo"][n], out["vrm"][n], out["unreal"][n] = extra[n]
            continue
        if n in vrm:
            out["vrm"][n], out["unreal"][n] = vrm[n], ue[n]
            continue
        side = "Left" if n.startswith("Left") else "Right"
        finger, k = n[len(side) + 4 : -1], int(n[-1])
        if k == 0:  # the finger's zero-length root at the wrist: UE5's metacarpal joints
            out["vrm"][n] = ""
            out["unreal"][n] = "" if finger == "Thumb" else f"{ue_name[finger]}_metacarpal_{side[0].lower()}"
            continue
        seg = vrm_seg[finger][k - 1]
        out["vrm"][n] = f"{side.lower()}{finger}{seg}" if seg else ""
        out["unreal"][n] = f"{ue_name[finger]}_0{k}_{side[0].lower()}" if k < 4 else ""
    return out


CONVENTIONS = _conventions()
