"""Keyframed expression events: the face actions that no dataset detector labels (gaze, eye rolls, cheek puff,
pout, lip press, one-sided brows and smiles, winks, ...), made as an envelope on their ARKit channels instead
of being copied from captured segments. Between them, :data:`POSES` and the detector-labelled
events of :mod:`anima.text2face.compose` reach every one of the 53 expression channels.

An event rises over ``attack_s`` (raised cosine), holds its weights for the slot, and falls over
``release_s``: natural facial timing (onsets of 0.1-0.3 s, offsets a little slower; a wink closes in ~80 ms).
A stated intensity scales the weights (:data:`INTENSITY_RANGE`), clipped to [0, 1].

Pure functions of numbers; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from anima.core.contract import EXPR_NAMES, N_EXPR
from anima.core.events import NOD

_IX = {n: i for i, n in enumerate(EXPR_NAMES)}


@dataclass(frozen=True)
class Pose:
    weights: dict[str, float]
    attack_s: float = 0.18
    hold_s: float = 0.8  # natural hold when the prompt gives no time
    release_s: float = 0.25
    sided: bool = False  # "left"/"right" keep that side's _L/_R channels (and the unsided ones)
    default_side: str | None = None  # a one-sided action named without a side ("smirks", "raises one brow")
    gap_s: float = 0.35  # between repeats
    path: dict = field(default_factory=dict)  # direction -> weights (gaze)


def _lr(stem: str, w: float) -> dict[str, float]:
    return {f"{stem}_L": w, f"{stem}_R": w}


GAZE = {  # the subject's left: the left eye looks out, the right eye looks in
    "left": {"eyeLookOut_L": 0.8, "eyeLookIn_R": 0.8},
    "right": {"eyeLookIn_L": 0.8, "eyeLookOut_R": 0.8},
    "up": {**_lr("eyeLookUp", 0.8), **_lr("browOuterUp", 0.15)},
    "down": {**_lr("eyeLookDown", 0.8), **_lr("eyeBlink", 0.2)},
}
POSES: dict[str, Pose] = {
    "wink": Pose({"eyeBlink_L": 0.97, "eyeBlink_R": 0.97, "cheekSquint_L": 0.25, "cheekSquint_R": 0.25,
                  "mouthSmile_L": 0.15, "mouthSmile_R": 0.15}, 0.08, 0.22, 0.14, True, "left", 0.3),
    "gaze": Pose({}, 0.15, 0.9, 0.2, path=GAZE),
    "roll eyes": Pose({**_lr("eyeLookUp", 0.9), **_lr("browInnerUp", 0.2)}, 0.25, 0.6, 0.3),
    "puff cheeks": Pose({**_lr("cheekPuff", 0.85), "mouthClose": 0.15, "jawOpen": 0.08, **_lr("mouthPress", 0.2)},
                        0.25, 0.9, 0.3, True),
    "pout": Pose({"mouthPucker": 0.55, "mouthShrugLower": 0.5, **_lr("mouthFrown", 0.4), **_lr("browInnerUp", 0.2)},
                 0.25, 1.0, 0.3),
    "pucker": Pose({"mouthPucker": 0.85, "mouthFunnel": 0.2}, 0.2, 0.8, 0.25),
    "press lips": Pose({**_lr("mouthPress", 0.75), "mouthRollUpper": 0.15, "mouthRollLower": 0.15}, 0.2, 0.9, 0.25,
                       True),
    "roll lips": Pose({"mouthRollLower": 0.75, "mouthRollUpper": 0.55}, 0.2, 0.8, 0.25),
    "shrug": Pose({"mouthShrugLower": 0.6, "mouthShrugUpper": 0.35, **_lr("mouthFrown", 0.3),
                   **_lr("browInnerUp", 0.35), **_lr("browOuterUp", 0.2)}, 0.2, 0.7, 0.3),
    "grimace": Pose({**_lr("mouthStretch", 0.65), **_lr("mouthUpperUp", 0.3), **_lr("mouthLowerDown", 0.4),
                     **_lr("eyeSquint", 0.3), **_lr("browDown", 0.3)}, 0.15, 0.8, 0.3),
    "funnel": Pose({"mouthFunnel": 0.75, "mouthPucker": 0.2, "jawOpen": 0.18}, 0.15, 0.6, 0.2),
    "bare teeth": Pose({**_lr("mouthUpperUp", 0.65), **_lr("mouthLowerDown", 0.5), **_lr("mouthStretch", 0.25),
                        **_lr("noseSneer", 0.35)}, 0.15, 0.8, 0.3, True),
    "wrinkle nose": Pose({**_lr("noseSneer", 0.75), **_lr("cheekSquint", 0.3), **_lr("mouthUpperUp", 0.15)},
                         0.15, 0.7, 0.25, True),
    "widen eyes": Pose({**_lr("eyeWide", 0.8), **_lr("browOuterUp", 0.2)}, 0.12, 0.8, 0.25),
    "jaw forward": Pose({"jawForward": 0.7, "mouthShrugLower": 0.2}, 0.2, 0.8, 0.25),
    "jaw side": Pose({"jawLeft": 0.6, "jawRight": 0.6}, 0.2, 0.7, 0.25, True, "left"),
    "mouth side": Pose({"mouthLeft": 0.65, "mouthRight": 0.65}, 0.2, 0.7, 0.25, True, "left"),
    # one-sided versions of detector events: made here so the named side moves at full strength
    "brow raise": Pose({"browOuterUp_L": 0.85, "browOuterUp_R": 0.85, "browInnerUp_L": 0.45, "browInnerUp_R": 0.45},
                       0.15, 0.8, 0.25, True, "left"),
    "half smile": Pose({"mouthSmile_L": 0.7, "mouthSmile_R": 0.7, "mouthDimple_L": 0.3, "mouthDimple_R": 0.3,
                        "cheekSquint_L": 0.2, "cheekSquint_R": 0.2}, 0.2, 0.9, 0.3, True, "left"),
    # a head shake: no expression channel, the head's yaw (shake_track); its timing here
    "shake": Pose({}, 0.12, 0.9, 0.15, gap_s=0.9),  # repeats further apart than one shake's swings
    # a nod: the head's pitch (nod_track), one bob down and back up; repeats 0.9 s apart (closer, the dataset's
    # detectors read two bobs as one nod)
    NOD: Pose({}, 0.1, 0.6, 0.1, gap_s=0.9),
}  # fmt: skip
_SIDE_CHANNELS = {"jawLeft": "left", "jawRight": "right", "mouthLeft": "left", "mouthRight": "right"}
INTENSITY_RANGE = {0.6: (0.3, 0.6), 1.0: (0.6, 0.9), 1.4: (0.85, 1.0)}
"""The peak weight of a keyframed event's main channel by stated intensity: "slightly" 0.6x, plain 1x,
"very"/"broadly" 1.4x of the pose's weights (clipped to 1)."""
UNPLACEABLE = {"tongue": "the face model has no tongue (ICT-FaceKit's 53 expressions): not made"}


def natural_frames(name: str, count: int, fps: float) -> int:
    p = POSES[name]
    one = p.attack_s + p.hold_s + p.release_s
    return int(round((count * one + (count - 1) * p.gap_s) * fps))


def weights(name: str, side: str | None) -> dict[str, float]:
    """The channels a pose moves, restricted to ``side`` ("left"/"right", or a gaze direction)."""
    p = POSES[name]
    if p.path:
        return dict(p.path.get(side or "left", {}))
    w = dict(p.weights)
    side = side if side in ("left", "right") else p.default_side
    if p.sided and side:
        drop = "_R" if side == "left" else "_L"
        w = {k: v for k, v in w.items() if not k.endswith(drop) and _SIDE_CHANNELS.get(k, side) == side}
    return w


def envelope(n: int, attack: int, release: int) -> np.ndarray:
    """``n`` frames: a raised-cosine rise over ``attack``, 1, a raised-cosine fall over ``release``."""
    e = np.ones(n, np.float32)
    attack, release = min(attack, n // 2), min(release, n - min(attack, n // 2))
    if attack > 0:
        e[:attack] = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, attack + 1)[:-1] + np.pi / (attack + 1))
    if release > 0:
        e[n - release :] = 0.5 + 0.5 * np.cos(np.linspace(0, np.pi, release + 1)[1:])
    return e


def _repeats(name: str, n: int, count: int, fps: float):
    """``(start, frames, envelope)`` of each of ``count`` repeats of pose ``name`` spread over ``n`` frames,
    its gap between them."""
    p = POSES[name]
    gap = int(round(p.gap_s * fps))
    each = max(2, (n - gap * (count - 1)) // count)
    att, rel = int(round(p.attack_s * fps)), int(round(p.release_s * fps))
    t = 0
    for _ in range(count):
        k = min(each, n - t)
        if k <= 0:
            return
        yield t, k, envelope(k, att, rel)
        t += k + gap


SHAKE_HALF_SWINGS = 4  # one shake ("no"): right, left, right, left, two cycles


def shake_track(n: int, count: int, peak: float, fps: float) -> np.ndarray:
    """Head yaw offsets ``[n]`` (radians): ``count`` shakes spread over ``n`` frames, each
    :data:`SHAKE_HALF_SWINGS` equal swings of ``peak`` about facing forward, eased in and out."""
    out = np.zeros(n, np.float32)
    for t, k, env in _repeats("shake", n, count, fps):
        swing = np.sin(np.linspace(0.0, SHAKE_HALF_SWINGS * np.pi, k))
        out[t : t + k] = peak * env * swing / max(float(np.abs(swing).max()), 1e-9)
    return out


def nod_track(n: int, count: int, peak: float, fps: float) -> np.ndarray:
    """Head pitch offsets ``[n]`` (radians, positive: the chin down): ``count`` nods spread over ``n`` frames,
    each one bob of ``peak`` down and back up (a raised cosine), so a viewer counts exactly ``count`` (captured
    nod segments bob two to six times)."""
    out = np.zeros(n, np.float32)
    for t, k, _ in _repeats(NOD, n, count, fps):
        out[t : t + k] = peak * np.sin(np.linspace(0.0, np.pi, k)) ** 2
    return out


def pose_track(name: str, side: str | None, n: int, count: int, gain: float, fps: float) -> np.ndarray:
    """Expression offsets ``[n, 53]``: ``count`` repeats of the pose spread over ``n`` frames."""
    out = np.zeros((n, N_EXPR), np.float32)
    w = weights(name, side)
    vec = np.zeros(N_EXPR, np.float32)
    for k, v in w.items():
        vec[_IX[k]] = v
    for t, k, env in _repeats(name, n, count, fps):
        if name == "roll eyes":  # the eyes sweep across the top: up-left, up, up-right
            lateral = np.sin(np.linspace(-np.pi / 2, np.pi / 2, k))
            track = env[:, None] * vec[None]
            for kk, v in (("eyeLookOut_L", -1), ("eyeLookIn_R", -1), ("eyeLookIn_L", 1), ("eyeLookOut_R", 1)):
                track[:, _IX[kk]] = env * 0.5 * np.clip(v * lateral, 0, None)
            out[t : t + k] = np.maximum(out[t : t + k], track)
        else:
            out[t : t + k] = np.maximum(out[t : t + k], env[:, None] * vec[None])
    return np.clip(out * gain, 0.0, 1.0)
