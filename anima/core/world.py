"""The motion on the character, in the world: :func:`anima.core.rig.solve`'s rotations grounded by
:mod:`anima.core.ground` (a root that moves in three dimensions, feet planted where they land, never under the
floor) and limited to the steps a body makes (:func:`limit_steps`). Pure functions; the one entry is
:func:`solve`."""

from __future__ import annotations

import numpy as np

from anima.core import contact, ground, rig
from anima.core.contract import JOINT_NAMES
from anima.core.filters import gaussian_smooth
from anima.core.kinematics import aim, local_rotations, two_bone
from anima.core.rotations import matrix_to_rotvec, rotvec_to_matrix

MAX_STEP_DEG = 40.0
"""No bone of any output turns its world direction more than this between two frames (a larger step is spread
over the next frames): the same limit for capture, gesture and text2face."""
LOST_S = 1.0
"""A hand or a leg unseen for longer than this is said in the report (with its frames)."""
_FOOT = {"left": "Left", "right": "Right"}
_FOOT_POINTS = ("Foot", "ToeBase", "Toe_End")
_ARMS = {
    s: (rig.IX[f"{S}Shoulder"], rig.IX[f"{S}Arm"], rig.IX[f"{S}ForeArm"], rig.IX[f"{S}Hand"],
        [rig.IX[f"{S}Hand{f}1"] for f in ("Index", "Middle", "Ring", "Pinky")])
    for s, S in (("left", "Left"), ("right", "Right"))
}  # fmt: skip


_SIZE_SEGMENTS = {("left_shoulder", "right_shoulder"): ("LeftArm", "RightArm"),
                  ("left_hip", "right_hip"): ("LeftUpLeg", "RightUpLeg"),
                  ("left_shoulder", "left_elbow"): ("LeftArm", "LeftForeArm"),
                  ("right_shoulder", "right_elbow"): ("RightArm", "RightForeArm"),
                  ("left_elbow", "left_wrist"): ("LeftForeArm", "LeftHand"),
                  ("right_elbow", "right_wrist"): ("RightForeArm", "RightHand")}  # fmt: skip


def character_size(body3d: np.ndarray, rest: np.ndarray) -> float:
    """The character's size over the tracked person's (the median over shoulders, hips, upper arms and forearms
    of the character's length over the tracker's clip-median length; 1 when none is seen). The picture's metres
    are the tracker's; the root travels in the character's, so that its strides fit its own legs."""
    J = {n: i for i, n in enumerate(JOINT_NAMES)}
    r = []
    for (a, b), (ra, rb) in _SIZE_SEGMENTS.items():
        d = np.linalg.norm(body3d[:, J[a]] - body3d[:, J[b]], axis=-1)
        if np.isfinite(d).any() and np.nanmedian(d) > 1e-3:
            r.append(np.linalg.norm(rest[rig.IX[ra]] - rest[rig.IX[rb]]) / np.nanmedian(d))
    return float(np.clip(np.median(r), 0.5, 2.0)) if r else 1.0


def limit_steps(L: np.ndarray, max_deg: float = MAX_STEP_DEG) -> tuple[np.ndarray, int]:
    """Local rotations ``[F, J, 3, 3]`` whose every frame-to-frame turn is at most ``max_deg`` (a larger turn
    is cut to the limit and the rest carried into the next frames). Returns (the rotations, how many steps
    were cut)."""
    out = L.copy()
    cut = 0
    lim = np.radians(max_deg)
    for f in range(1, len(L)):
        rel = np.einsum("jba,jbc->jac", out[f - 1], L[f])
        rv = matrix_to_rotvec(rel)
        ang = np.linalg.norm(rv, axis=-1)
        big = ang > lim
        if big.any():
            cut += int(big.sum())
            rv[big] *= (lim / ang[big])[:, None]
            out[f, big] = out[f - 1, big] @ rotvec_to_matrix(rv[big])
    return out, cut


def limit_world_steps(L: np.ndarray, rest: np.ndarray, root: np.ndarray, max_deg: float = MAX_STEP_DEG):
    """Local rotations ``L`` whose every bone's world direction turns at most ``max_deg`` between two frames: the
    limit of :func:`limit_steps` on each joint's world rotation (a bone's direction is its parent joint's world
    rotation of its rest offset), so a finger whose hand turns too cannot add its turn to the hand's. Returns
    (the local rotations, how many steps were cut)."""
    G, _ = rig.forward(L, rest, root)
    G, cut = limit_steps(G, max_deg)
    if not cut:
        return L, 0
    L = local_rotations(G, rig.PARENTS_RIG)
    L[:, rig.LEAVES] = np.eye(3)
    return L, cut


def _foot_low(P: np.ndarray, side: str, rest: np.ndarray) -> np.ndarray:
    """The height of a foot's sole ``[F]``: the lowest of its points (ankle, ball, toe tip) over its height in
    the rest pose, where the sole is flat on the floor (the joints sit inside the foot: a flat foot is 0, a
    foot on its toes is held up by them, one on its heel by the heel)."""
    return np.min([P[:, rig.IX[f"{_FOOT[side]}{n}"], 1] - rest[rig.IX[f"{_FOOT[side]}{n}"], 1] for n in _FOOT_POINTS],
                  0)  # fmt: skip


def flat_foot(G: np.ndarray, rest: np.ndarray, S: str, w: np.ndarray) -> None:
    """Level ``S``'s foot (``Left`` / ``Right``) by ``w [F]`` (0 keeps it, 1 lays its sole flat): the smallest
    turn that brings the sole's heel-to-toe line level with the floor, so the foot keeps where it points and
    only its pitch and roll about that line go. The toes follow the foot (they bend only where the foot is
    free to lift its heel). ``G`` (global rotations) updated in place."""
    sole = rig.sole_direction(rest, S)
    foot, toe = rig.IX[f"{S}Foot"], rig.IX[f"{S}ToeBase"]
    d = np.einsum("fij,j->fi", G[:, foot], sole)
    level = d * [1.0, 0.0, 1.0]
    on = (w > 0) & (np.linalg.norm(level, axis=-1) > 0.2)  # a foot pointing straight down has no level to keep
    if not on.any():
        return
    flat = aim(G[on, foot], sole, level[on])
    G[on, foot] = rig.slerp_rot(G[on, foot], flat, w[on])
    G[on, toe] = G[on, foot]


def flat_feet(L: np.ndarray, rest: np.ndarray, root: np.ndarray, down: np.ndarray, fps: float) -> np.ndarray:
    """Local rotations ``L`` with each foot laid flat where it is planted (``down [F, 2]``, left and right,
    eased in and out as the feet are locked: :func:`anima.core.ground.lock_weights`); see :func:`flat_foot`."""
    if not down.any():
        return L
    G, _ = rig.forward(L, rest, root)
    for k, side in enumerate(("left", "right")):
        flat_foot(G, rest, _FOOT[side], ground.lock_weights(down[:, k], fps))
    L = local_rotations(G, rig.PARENTS_RIG)
    L[:, rig.LEAVES] = np.eye(3)
    return L


REACH = 0.995
"""A planted leg reaches its anchor at most this share of its full length (a knee locked straight pops)."""
MAX_DROP_M = 0.08
"""How far at most the hips come down so that planted feet reach the floor. Chosen on the body round trip's
development takes (Human3.6M's walk, CMU's jump) and a standing clip (LivePortrait s13): 0 leaves the walk's
planted feet 10.5 cm above the floor (median; 5.6 before the feet were laid flat), 0.08 leaves 3.0 with the
hips 10 cm under the truth's (0.4 before), 0.15 leaves 0 with the hips 17 cm under it."""


def _reach_drop(P: np.ndarray, rest: np.ndarray, goals: list, fps: float) -> np.ndarray:
    """How far ``[F]`` the hips must come down for every planted ankle (``goals``: ``(side, target [F, 3],
    weight [F])``) to reach its anchor's height within :data:`REACH` of its leg's length, the foot where the
    legs put it across the floor (at most :data:`MAX_DROP_M`; smoothed over 0.1 s so the hips do not jerk). A
    foot held above its floor anchor by a leg too short there floats."""
    drop = np.zeros(len(P))
    off = rig.rest_offsets(rest)
    for side, target, w in goals:
        S = _FOOT[side]
        hip = P[:, rig.IX[f"{S}UpLeg"]]
        reach = REACH * (np.linalg.norm(off[rig.IX[f"{S}Leg"]]) + np.linalg.norm(off[rig.IX[f"{S}Foot"]]))
        across = np.sum((hip - P[:, rig.IX[f"{S}Foot"]])[:, ::2] ** 2, -1)  # where the legs put the foot
        need = (hip[:, 1] - target[:, 1]) - np.sqrt(np.maximum(reach**2 - across, 0.0))
        ok = (w > 0) & np.isfinite(need)
        drop = np.maximum(drop, np.where(ok, np.clip(need, 0.0, MAX_DROP_M) * np.where(ok, w, 0.0), 0.0))
    if not drop.any():
        return drop
    return np.maximum(gaussian_smooth(drop[:, None], 0.05 * fps)[:, 0], 0.0)


def _standing_anchors(free: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Planted standing feet (legs not seen): each foot stays where it stands until the hips have carried its
    free place :data:`anima.core.ground.REPLANT_M` away, then steps there over 0.3 s. ``free [F, 3]``: where
    the foot would stand under the hips. Returns (the foot's place ``[F, 3]``, steps ``[F]`` bool)."""
    F = len(free)
    out = free.copy()
    steps = np.zeros(F, bool)
    n = max(1, int(round(0.3 * fps)))
    anchor, f = free[0].copy(), 0
    while f < F:
        if np.linalg.norm((free[f] - anchor)[[0, 2]]) > ground.REPLANT_M:
            new = free[min(F - 1, f + n)].copy()
            k = np.arange(min(n, F - f))
            w = ((k + 1) / n)[:, None]
            out[f : f + len(k)] = anchor * (1 - w) + new * w
            out[f : f + len(k), 1] = anchor[1] + 0.04 * np.sin(np.pi * (k + 1) / n)  # the foot lifts as it steps
            steps[f : f + len(k)] = True
            anchor, f = new, f + len(k)
            continue
        out[f] = anchor
        f += 1
    return out, steps


def _ik_leg(G: np.ndarray, P: np.ndarray, rest: np.ndarray, side: str, target: np.ndarray, w: np.ndarray) -> None:
    """Move ``side``'s ankle towards ``target [F, 3]`` by ``w [F]`` with a two-bone IK (the knee keeps its
    plane, the foot its world rotation); ``G`` (global rotations) updated in place where ``w > 0``."""
    S = _FOOT[side]
    up, leg, foot = rig.IX[f"{S}UpLeg"], rig.IX[f"{S}Leg"], rig.IX[f"{S}Foot"]
    off = rig.rest_offsets(rest)
    on = (w > 0) & np.isfinite(target).all(-1)
    if not on.any():
        return
    hip, knee, ankle = P[on, up], P[on, leg], P[on, foot]
    goal = ankle + (target[on] - ankle) * w[on, None]
    a, b = np.linalg.norm(off[leg]), np.linalg.norm(off[foot])
    new_knee = two_bone(hip, goal, a, b, knee - hip)
    Gu = aim(G[on, rig.HIPS], off[leg], new_knee - hip)
    Gl = aim(Gu, off[foot], goal - new_knee)
    G[on, up], G[on, leg] = Gu, Gl


def lost_runs(body: np.ndarray, legs: dict | None, fps: float) -> list[dict]:
    """The hands and legs the clip shows and then loses for more than :data:`LOST_S` (frame ranges), for the
    report (a part never in the picture, as the hands of a head-and-shoulders clip, is not lost: it stands at
    ease)."""
    out = []
    parts = {"left hand": body[:, JOINT_NAMES.index("left_hand_wrist")],
             "right hand": body[:, JOINT_NAMES.index("right_hand_wrist")]}  # fmt: skip
    if legs:
        for side in ("left", "right"):
            if legs.get(f"{side}_ankle") is not None:
                parts[f"{side} leg"] = legs[f"{side}_ankle"]
    n = int(round(LOST_S * fps))
    for name, x in parts.items():
        seen = np.isfinite(x).all(-1)
        if not seen.any():
            continue
        for a, b in ground.runs(~seen):
            if b - a > n:
                out.append({"part": name, "frames": [int(a), int(b - 1)], "seconds": round((b - a) / fps, 2)})
    return out


def solve(
    body: np.ndarray | None,
    rest: np.ndarray,
    fps: float,
    head_rot: np.ndarray | None = None,
    picture: ground.Picture | None = None,
    legs: dict | None = None,
    seed: int = 0,
    frames: int | None = None,
    surface: contact.TorsoSurface | None = None,
    seated: bool = False,
) -> dict:
    """The motion on the rig, in the world: :func:`anima.core.rig.solve`'s (the same arguments; ``picture``:
    the clip's 2D evidence, :class:`anima.core.ground.Picture`) with the root in three dimensions, the feet
    planted and on the floor, and every bone's step limited (``seated``: ``legs`` are a seated pose the picture
    does not show: the hips stay on their chair, no travel, the feet go with the legs). Returns ``root``,
    ``local``, ``global``, ``positions``, ``contact [F, 2]`` (left, right) and the ``report``."""
    mo = rig.solve(body, rest, fps, head_rot, image=None, legs=legs, seed=seed, frames=frames)
    L, root = mo["local"], mo["root"].copy()
    F = len(L)
    report = dict(mo["report"])
    L = _idle_where_never_seen(L, report, rest, fps, head_rot, seed)
    leg_seen = np.asarray(mo.get("leg_seen", np.zeros(F, bool)), bool)
    mpp = ground.metres_per_pixel(picture, fps) if picture is not None else None
    feet = ground.feet_in_picture(picture, mpp, fps) if mpp is not None else None
    if mpp is not None and not seated:
        x, z = ground.picture_travel(picture, mpp, fps)
        size = character_size(picture.body3d, rest)
        root[:, 0] += size * x
        root[:, 2] += size * z
    L, cut = limit_world_steps(L, rest, root)
    # contacts seen in the picture; planted feet will stand flat (the sole level, heel and toe down)
    feet_down = np.zeros((F, 2), bool)
    if feet is not None:
        feet_down = ground.foot_contacts(feet, fps) & leg_seen[:, None]
    w_leg = np.asarray(mo["leg_weight"], np.float64)  # tracked legs' share, 0 where the legs stand
    root[:, 1] = _hips_height(L, rest, root, feet, w_leg, fps)
    L = flat_feet(L, rest, root, feet_down, fps)  # after the height: the tracked feet's pitch is the legs' say
    G, P = rig.forward(L, rest, root)
    # contacts: tracked legs from the picture (else from the 3D feet); standing legs are planted
    if feet is None and leg_seen.any() and not seated:
        for k, side in enumerate(("left", "right")):
            h = _foot_low(P, side, rest)
            v = np.linalg.norm(np.gradient(P[:, rig.IX[f"{_FOOT[side]}Foot"], ::2], axis=0), axis=-1) * fps
            feet_down[:, k] = ground.clean_runs((h < ground.CONTACT_M) & (v < ground.CONTACT_SPEED) & leg_seen)
        L = flat_feet(L, rest, root, feet_down, fps)
        G, P = rig.forward(L, rest, root)
    goals, steps_total = _foot_goals(P, rest, feet_down, leg_seen, w_leg, fps)
    G, L, P = _plant_feet(G, P, rest, root, goals, fps)
    hands = np.zeros((F, 2), bool)
    if picture is not None and surface is not None:
        hands = contact.hand_contacts(picture, fps)
        if hands.any():
            G, L, P, report["hand_contact"] = _hands_on_torso(G, P, rest, root, hands, surface, fps)
    L, cut2 = limit_world_steps(L, rest, root)  # what the feet and hands moved obeys the same limit
    if cut2:
        G, P = rig.forward(L, rest, root)
    cut += cut2
    # never under the floor: a frame whose lowest foot point is below it raises the root
    low = np.minimum(_foot_low(P, "left", rest), _foot_low(P, "right", rest))
    lift = np.maximum(-low, 0.0)
    if lift.any():
        root[:, 1] += lift
        G, P = rig.forward(L, rest, root)
    report.update(_grounding_report(P, rest, root, feet_down, fps, mpp is not None, feet, cut, steps_total))
    if body is not None:
        report["lost"] = lost_runs(body, legs, fps)
    return {"root": root, "local": L, "global": G, "positions": P, "contact": feet_down, "hand_contact": hands,
            "report": report}  # fmt: skip


def _idle_where_never_seen(L, report: dict, rest, fps: float, head_rot, seed: int) -> np.ndarray:
    """``L`` with the joints the clip never shows (``report["joints_never_seen"]``) at the idle body's pose: an
    arm never seen hangs at ease (the rig's rest would hold it out in a T); says so in ``report``."""
    never = [rig.IX[n] for n in report.get("joints_never_seen", [])]
    if never:
        idle = rig.solve(None, rest, fps, head_rot, image=None, seed=seed, frames=len(L))["local"]
        L = L.copy()
        L[:, never] = idle[:, never]
        report["never_seen"] = "the idle body's pose (arms hanging at ease)"
    return L


def _hips_height(L, rest, root, feet: dict | None, w_leg: np.ndarray, fps: float) -> np.ndarray:
    """The hips' height ``[F]``: as high as the legs reach (the lowest foot point on the floor), plus flight;
    where the picture shows the hips above the floor, its height (in the character's scale) for the tracked
    legs' share ``w_leg``: crouches, jumps, sitting."""
    G, P = rig.forward(L, rest, root)
    low = np.minimum(_foot_low(P, "left", rest), _foot_low(P, "right", rest)) - root[:, 1]
    air = ground.air_height(feet) if feet is not None else np.zeros(len(L))
    legs_say = -low + w_leg * air  # standing or tracked, the lowest foot point is on the floor
    seen = ground.hips_in_picture(feet, legs_say, fps) if feet is not None else None
    if seen is not None:
        legs_say = (1 - w_leg) * legs_say + w_leg * seen
    return legs_say


def _foot_goals(P, rest, feet_down, leg_seen, w_leg, fps: float) -> tuple[list, int]:
    """Per foot ``(side, target [F, 3], weight [F])``: where it is held (its contact's landing point, the sole on
    the floor; standing legs planted and re-planted when the hips carry them too far), and the standing legs'
    steps."""
    locks = np.stack([ground.lock_weights(feet_down[:, k], fps) for k in range(2)], 1)
    steps_total, goals = 0, []
    for k, side in enumerate(("left", "right")):
        S = _FOOT[side]
        ankle = P[:, rig.IX[f"{S}Foot"]]
        sole = _foot_low(P, side, rest)
        target = ground.anchors(ankle - sole[:, None] * [0.0, 1.0, 0.0], feet_down[:, k], fps)  # sole on the floor
        w = locks[:, k]
        if (~leg_seen).any():  # standing legs: planted, re-planted when the hips carry them too far
            free = ankle.copy()
            free[:, 1] = rest[rig.IX[f"{S}Foot"], 1]
            placed, steps = _standing_anchors(free, fps)
            stand = 1.0 - w_leg
            target = np.where((stand > 0)[:, None], placed, target)
            w = np.maximum(w, stand)
            steps_total += int(len(ground.runs(steps & (stand > 0))))
        goals.append((side, target, w))
    return goals, steps_total


def _plant_feet(G, P, rest, root, goals: list, fps: float):
    """``(G, L, P)`` with the feet held at their ``goals`` by leg IK (the hips lowered, in ``root``, where a
    planted foot could not reach the floor) and a free foot that reaches under the floor bending its knee."""
    drop = _reach_drop(P, rest, goals, fps)
    if drop.any():  # hips too high for a planted foot to reach the floor: they come down, the feet stay down
        root[:, 1] -= drop
        G, P = rig.forward(local_rotations(G, rig.PARENTS_RIG), rest, root)
    for side, target, w in goals:
        _ik_leg(G, P, rest, side, target, w)
    L = local_rotations(G, rig.PARENTS_RIG)
    L[:, rig.LEAVES] = np.eye(3)
    G, P = rig.forward(L, rest, root)
    for side in ("left", "right"):  # a free foot that reaches under the floor bends its knee, the hips stay
        sole = _foot_low(P, side, rest)
        up = np.minimum(sole, 0.0)[:, None] * [0.0, 1.0, 0.0]
        _ik_leg(G, P, rest, side, P[:, rig.IX[f"{_FOOT[side]}Foot"]] - up, (sole < 0).astype(np.float64))
    L = local_rotations(G, rig.PARENTS_RIG)
    L[:, rig.LEAVES] = np.eye(3)
    G, P = rig.forward(L, rest, root)
    return G, L, P


def _hands_on_torso(G, P, rest, root, hands, surface: contact.TorsoSurface, fps: float):
    """``(G, L, P, report)`` with the palms in contact (``hands [F, 2]``) put on the torso's ``surface``."""
    gap = contact.place_hands(G, P, rest, hands, surface, rig.IX["Spine2"], _ARMS, fps)
    L = local_rotations(G, rig.PARENTS_RIG)
    L[:, rig.LEAVES] = np.eye(3)
    G, P = rig.forward(L, rest, root)
    report = {
        "fraction": [round(float(hands[:, k].mean()), 3) for k in range(2)],
        "palm_to_torso_m": [
            round(float(np.nanmedian(gap[:, k])), 3) if hands[:, k].any() else None for k in range(2)
        ],  # fmt: skip
    }
    return G, L, P, report


def _floor_said(feet: dict | None) -> str:
    if feet is None:
        return "the character's feet (no feet seen)"
    h = feet.get("camera_height")
    if h is None:
        return "the feet's lowest plants in the picture"
    return f"the ground plane through the feet's plants (the camera {h:.2f} m above it, in the tracker's metres)"


def _grounding_report(P, rest, root, contact, fps, travel: bool, feet: dict | None, cut: int, steps: int) -> dict:
    skate = []
    for k, side in enumerate(("left", "right")):
        a = P[:, rig.IX[f"{_FOOT[side]}Foot"], ::2]
        both = contact[1:, k] & contact[:-1, k]
        if both.any():
            skate.append(np.linalg.norm(np.diff(a, axis=0), axis=-1)[both])
    low = np.minimum(_foot_low(P, "left", rest), _foot_low(P, "right", rest))
    return {
        "ground": {
            "root": "picture travel (sideways, depth from apparent size) and height from the legs"
            if travel
            else "in place, height from the legs",
            "floor": _floor_said(feet),
            "floor_camera_m": None
            if feet is None or feet.get("camera_height") is None
            else round(float(feet["camera_height"]), 3),
            "contact_fraction": [round(float(contact[:, k].mean()), 3) for k in range(2)],
            "skating_mm_per_frame": round(1000 * float(np.median(np.concatenate(skate))), 2) if skate else None,
            "lowest_foot_m": round(float(low.min()), 4),
            "hips_height_range_m": round(float(np.ptp(root[:, 1])), 4),
            "root_travel_m": [round(float(np.ptp(root[:, i])), 3) for i in range(3)],
            "standing_steps": steps,
            "steps_limited": cut,
        }
    }
