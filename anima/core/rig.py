"""The rig every skeleton anima exports (BVH, glTF, the viewer, the avatar video): the character's skeleton of
``anima.core.contract.RIG_JOINTS`` (Mixamo's hierarchy: hips, a three-bone spine, neck, head, collarbones,
arms, hands with three-bone fingers, legs, feet and toes, plus the end joints of the head, fingers and toes), and
the retargeting of a tracked or generated body (55 joints, ``anima.core.skeleton``) onto it. Pure functions.

* **Rest pose**: the character's T-pose (``rest [65, 3]``, metres, from ``anima.facemodel.character`` with the
  person's shape): +x the character's left, +y up, +z forward, arms out along +-x with the palms down, legs
  straight down, feet on y = 0. Local rotations are relative to it; a joint's rest offset is its rest position
  minus its parent's.
* **Retargeting** (:func:`solve`): every bone of the character turns to point where the tracked body has it,
  keeping the character's own lengths: the chest from the shoulder line and the hips-to-neck line, the hips
  from the hip line (or a third of the chest's turn when the hips are not seen), the spine's three bones
  between the two, the neck halfway to the head, the head from the face fit's rotation (or the ears and nose),
  the collarbones from the shoulders, the arms, the forearms, the palms (a rigid fit of the four knuckles) and
  every finger bone from its two joints. A joint whose drivers are not seen holds its last rotation, and when
  they come back it blends into them over ``blend_s`` (0.3 s): nothing snaps.
* **Legs**: from tracked knees and ankles where the clip has them; otherwise a standing pose: feet planted
  under the hips, a slow weight shift of the hips (1.5 cm, 7 s) with the knees solved to keep the feet down.
* **Root**: the hips translate where the person moves in the picture (its horizontal track, smoothed).
"""

from __future__ import annotations

import numpy as np

from anima.core import kinematics
from anima.core.contract import FINGERS, JOINT_NAMES, RIG_JOINTS, RIG_PARENTS
from anima.core.filters import gaussian_smooth
from anima.core.ground import runs
from anima.core.kinematics import aim, fit_rotation, local_rotations, two_bone, unit
from anima.core.rotations import matrix_to_rotvec, rotvec_to_matrix

NAMES = RIG_JOINTS
PARENTS_RIG = np.array(RIG_PARENTS)
N_RIG = len(NAMES)
IX = {n: i for i, n in enumerate(NAMES)}
HIPS, HEAD = IX["Hips"], IX["Head"]
LEAVES = np.array([not (PARENTS_RIG == j).any() for j in range(N_RIG)])
BLEND_S = 0.3
# a hand that turns more than FLIP_DEG in one frame and back within FLIP_RUN_S is a tracker flip (the palm
# seen edge-on, its depth mistaken): those frames count as unseen (held, then blended back)
FLIP_DEG, FLIP_RUN_S = 60.0, 0.5
FINGER_FLIP_DEG = 35.0
SWAY_M, SWAY_PERIOD_S = 0.015, 7.0
_T = {n: i for i, n in enumerate(JOINT_NAMES)}
_SEG = {"Thumb": ("cmc", "mcp", "ip", "tip"), **{f: ("mcp", "pip", "dip", "tip") for f in FINGERS[1:]}}


def rest_offsets(rest: np.ndarray) -> np.ndarray:
    """Child minus parent of the rest positions ``[J, 3]`` (the root keeps its own position)."""
    off = rest - rest[np.maximum(PARENTS_RIG, 0)]
    off[HIPS] = rest[HIPS]
    return off


def forward(L: np.ndarray, rest: np.ndarray, root: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Global rotations and positions ``[F, J, 3, 3]``, ``[F, J, 3]`` of local rotations ``L`` with the hips at
    ``root [F, 3]`` (:func:`anima.core.kinematics.forward` on the rig)."""
    return kinematics.forward(L, PARENTS_RIG, rest_offsets(rest), root)


def slerp_rot(A: np.ndarray, B: np.ndarray, t) -> np.ndarray:
    """Rotations a fraction ``t`` of the way from ``A`` to ``B`` (``[..., 3, 3]``; ``t`` broadcasts)."""
    d = matrix_to_rotvec(np.swapaxes(A, -1, -2) @ B)
    return A @ rotvec_to_matrix(d * np.asarray(t, np.float64)[..., None])


# the rig's own earlier names, kept for the body round trip benchmark (benchmarks/roundtrip_body.py)


def _tracked(body: np.ndarray, name: str) -> np.ndarray:
    return body[:, _T[name]]


def _flipped_runs(G: np.ndarray, fps: float, max_deg: float = FLIP_DEG, max_run_s: float = FLIP_RUN_S) -> np.ndarray:
    """Frames ``[F]`` of rotation track ``G [F, 3, 3]`` (NaN where unseen) after a step of more than ``max_deg``
    from the previous frame: up to the step back (or an unseen frame) when one comes within ``max_run_s`` (a
    tracker's flip), else the ``max_run_s`` after it (a one-way snap, faster than a person turns: the caller
    holds those frames and blends into the new rotation instead of snapping)."""
    F = len(G)
    if F < 2:
        return np.zeros(F, bool)
    seen = np.isfinite(G).all((-1, -2))
    step = np.zeros(F)
    both = seen[1:] & seen[:-1]
    rel = np.einsum("fji,fjk->fik", G[:-1][both], G[1:][both])
    step[1:][both] = np.degrees(np.linalg.norm(matrix_to_rotvec(rel), axis=-1))
    jump = step > max_deg
    out = np.zeros(F, bool)
    n = max(1, int(round(max_run_s * fps)))
    back = np.zeros(F, bool)  # steps that end a flip: the return, not a new snap
    for a in np.flatnonzero(jump):
        if back[a]:
            continue
        b = a + 1
        while b < F and seen[b] and not jump[b] and b - a <= n:
            b += 1
        if b - a <= n and (b == F or not seen[b] or jump[b]):
            out[a:b] = True
            if b < F:
                back[b] = True
        else:
            out[a : min(F, a + n)] = True
    return out


FACE_BLEND_S = 0.3
"""Where the face fit's head rotation starts or stops (the face found again after a fast turn, or lost), the head
eases between it and the body's own head line (ears and nose) over this long: the two can disagree by tens of
degrees, and a snap between them is a pop."""


def face_weight(seen: np.ndarray, n: int) -> np.ndarray:
    """``[F]`` weights of the face's head rotation: 1 inside each run of ``seen`` frames, rising over its first
    ``n`` frames and falling over its last ``n`` (not at the clip's ends, where nothing comes before or after),
    0 where unseen."""
    w = np.zeros(len(seen))
    for a, b in runs(seen):
        k = np.arange(a, b, dtype=np.float64)
        up = np.ones(b - a) if a == 0 else np.minimum(1.0, (k - a + 1) / (n + 1))
        down = np.ones(b - a) if b == len(seen) else np.minimum(1.0, (b - k) / (n + 1))
        w[a:b] = np.minimum(up, down)
    return w


def bridge_short_gaps(R: np.ndarray, n: int) -> np.ndarray:
    """Rotations ``[F, 3, 3]`` (NaN where unseen) with each gap of at most ``n`` frames between two seen frames
    filled along the shortest arc from the one before to the one after (a face lost for a blink of the tracker
    is not a reason to turn the head elsewhere)."""
    seen = np.isfinite(R).all((-1, -2))
    out = R.copy()
    for a, b in runs(~seen):
        if 0 < a and b < len(R) and b - a <= n:
            t = (np.arange(a, b) - (a - 1)) / (b - a + 1)
            out[a:b] = slerp_rot(np.broadcast_to(R[a - 1], (b - a, 3, 3)), np.broadcast_to(R[b], (b - a, 3, 3)), t)
    return out


def _globals(body: np.ndarray, rest: np.ndarray, head_rot: np.ndarray | None, fps: float) -> np.ndarray:
    """Global rotations ``[F, J, 3, 3]`` of the upper body from the tracked joints (NaN where unseen; the legs
    and the end joints are left NaN for the caller)."""
    F = len(body)
    t = lambda n: _tracked(body, n)
    r = lambda n: rest[IX[n]]
    G = np.full((F, N_RIG, 3, 3), np.nan)
    ls, rs, lh, rh = t("left_shoulder"), t("right_shoulder"), t("left_hip"), t("right_hip")
    neck = (ls + rs) / 2
    pelvis = np.where(np.isfinite(t("pelvis")), t("pelvis"), 0.0)
    up_t = upright(neck - pelvis, np.isfinite(lh).all(-1) & np.isfinite(rh).all(-1), fps)
    mid_r = (r("LeftArm") + r("RightArm")) / 2
    up_r = mid_r - r("Hips")
    chest = fit_rotation(np.stack([r("LeftArm") - r("RightArm"), up_r]), np.stack([ls - rs, up_t], 1))
    hips = fit_rotation(np.stack([r("LeftUpLeg") - r("RightUpLeg"), up_r]), np.stack([lh - rh, up_t], 1))
    no_hips = ~np.isfinite(hips).all((-1, -2)) & np.isfinite(chest).all((-1, -2))
    hips[no_hips] = slerp_rot(np.eye(3), chest[no_hips], 1 / 3)  # the hips unseen: a third of the chest's turn
    G[:, HIPS] = hips
    G[:, IX["Spine"]] = slerp_rot(hips, chest, 1 / 3)
    G[:, IX["Spine1"]] = slerp_rot(hips, chest, 2 / 3)
    G[:, IX["Spine2"]] = chest
    # the head: the face fit's rotation where there is one, else the ears' and the nose's line; the neck halfway
    head_t, nose_t = t("head"), t("nose")
    face = np.full((F, 3, 3), np.nan)
    if head_rot is not None:
        face = np.where(np.isfinite(head_rot).all((-1, -2))[:, None, None], head_rot, np.nan)
    nose_dir = aim(chest, np.array([0.0, 0.0, 1.0]), nose_t - head_t)
    face = bridge_short_gaps(face, int(round(2 * FACE_BLEND_S * fps)))
    has_face = np.isfinite(face).all((-1, -2))
    head = np.where(has_face[:, None, None], face, nose_dir)
    w = face_weight(has_face, int(round(FACE_BLEND_S * fps)))  # the face lost and found: eased, never snapped
    both = has_face & np.isfinite(nose_dir).all((-1, -2)) & (w < 1.0)
    head[both] = slerp_rot(nose_dir[both], face[both], w[both])
    G[:, HEAD] = head
    G[:, IX["Neck"]] = slerp_rot(chest, head, 0.4)
    for S, s in (("Left", "left"), ("Right", "right")):
        sh = aim(chest, r(f"{S}Arm") - mid_r, t(f"{s}_shoulder") - neck)
        G[:, IX[f"{S}Shoulder"]] = sh
        arm = aim(sh, r(f"{S}ForeArm") - r(f"{S}Arm"), t(f"{s}_elbow") - t(f"{s}_shoulder"))
        G[:, IX[f"{S}Arm"]] = arm
        fore = aim(arm, r(f"{S}Hand") - r(f"{S}ForeArm"), t(f"{s}_wrist") - t(f"{s}_elbow"))
        G[:, IX[f"{S}ForeArm"]] = fore
        knuckles = [f"{s}_hand_{f.lower()}_mcp" for f in FINGERS[1:]]
        wrist = t(f"{s}_hand_wrist")
        hand = fit_rotation(
            np.stack([r(f"{S}Hand{f}1") - r(f"{S}Hand") for f in FINGERS[1:]]),
            np.stack([t(k) - wrist for k in knuckles], 1),
        )
        hand[_flipped_runs(hand, fps)] = np.nan
        G[:, IX[f"{S}Hand"]] = hand
        for f in FINGERS:
            seg = _SEG[f]
            parent = hand
            for k in range(1, 4):
                a, b = t(f"{s}_hand_{f.lower()}_{seg[k - 1]}"), t(f"{s}_hand_{f.lower()}_{seg[k]}")
                g = aim(parent, r(f"{S}Hand{f}{k + 1}") - r(f"{S}Hand{f}{k}"), b - a)
                # a finger bone that turns more than FINGER_FLIP_DEG in one frame is the tracker's (fingers
                # crossing, seen edge-on): held and blended like the hand's flips
                g[_flipped_runs(g, fps, FINGER_FLIP_DEG)] = np.nan
                G[:, IX[f"{S}Hand{f}{k}"]] = g
                parent = g
    return G


LEAN_DEG = 15.0  # contract: not a rate (degrees)
"""The torso's pitch (towards or away from the camera) is what the monocular tracker's depth says least
reliably: a standing person's spine reads 15 degrees forward, then back. The pitch the character gets is the
tracked pitch smoothed over :data:`LEAN_SMOOTH_S` and shrunk by ``p - D tanh(p / D)`` with ``D`` this many
degrees (15 degrees of noise become 4, a 40-degree bow stays 25); with the hips unseen it is 0 (no evidence).
The roll (the lean the picture shows) is kept as tracked."""
LEAN_SMOOTH_S = 0.3


def upright(up: np.ndarray, hips_seen: np.ndarray, fps: float) -> np.ndarray:
    """Torso up vectors ``[F, 3]`` (pelvis to neck) with their pitch limited to the evidence (see
    :data:`LEAN_DEG`)."""
    ok = np.isfinite(up).all(-1)
    if not ok.any():
        return up
    pitch = np.where(ok, np.arctan2(up[:, 2], up[:, 1]), np.nan)
    p = np.interp(np.arange(len(up)), np.flatnonzero(ok), pitch[ok])
    p = gaussian_smooth(p[:, None], LEAN_SMOOTH_S * fps)[:, 0] if len(p) > 1 else p
    D = np.radians(LEAN_DEG)
    keep = np.where(hips_seen, p - D * np.tanh(p / D), 0.0)
    c, s = np.cos(keep - pitch), np.sin(keep - pitch)  # turn about x by the difference
    y, z = up[:, 1], up[:, 2]
    out = up.copy()
    out[:, 1] = c * y - s * z
    out[:, 2] = s * y + c * z
    return np.where(ok[:, None], out, up)


def hold_and_blend(L: np.ndarray, fps: float, blend_s: float = BLEND_S) -> tuple[np.ndarray, np.ndarray]:
    """Local rotation tracks ``[F, J, 3, 3]`` with NaN frames filled: held from the last seen frame (the first
    seen one before it; the rest pose for a joint never seen), and when the joint is seen again, blended from
    the held rotation into the tracked one over ``blend_s`` seconds. Returns (the filled tracks, the seen
    mask ``[F, J]``)."""
    F, J = L.shape[:2]
    seen = np.isfinite(L).all((-1, -2))
    out = L.copy()
    n_blend = max(1, int(round(blend_s * fps)))
    for j in range(J):
        s = seen[:, j]
        if s.all():
            continue
        if not s.any():
            out[:, j] = np.eye(3)
            continue
        first = int(np.argmax(s))
        out[:first, j] = L[first, j]
        held = L[first, j]
        f = first
        while f < F:
            if s[f]:
                held = out[f, j]
                f += 1
                continue
            g = f
            while g < F and not s[g]:
                g += 1
            out[f:g, j] = held
            if g < F:  # back: blend in over n_blend frames (or until it is lost again)
                e = g
                while e < F and e - g < n_blend and s[e]:
                    e += 1
                k = np.arange(e - g)
                out[g:e, j] = slerp_rot(np.broadcast_to(held, (len(k), 3, 3)), L[g:e, j], (k + 1) / (n_blend + 1))
                g = e
            f = g
            if f < F:
                held = out[f - 1, j]
    return out, seen


def _run_depth(mask: np.ndarray) -> np.ndarray:
    """Per frame, the distance in frames to the nearest frame outside ``mask`` (0 outside it; the clip's ends
    count as outside)."""
    F = len(mask)
    i = np.arange(F)
    last_off = np.maximum.accumulate(np.where(~mask, i, -1))
    next_off = np.minimum.accumulate(np.where(~mask, i, F)[::-1])[::-1]
    return np.where(mask, np.minimum(i - last_off, next_off - i), 0).astype(np.float64)


def standing_legs(G: np.ndarray, root: np.ndarray, rest: np.ndarray) -> None:
    """Legs of a person standing with the feet under the hips (the rest pose's feet, moved with the root's
    horizontal travel) for hips at ``root``: the knees from two-bone IK bending forwards, the feet flat and
    forwards. Fills the leg joints of ``G`` in place."""
    F = len(G)
    off = rest_offsets(rest)
    travel = np.stack([root[:, 0] - rest[HIPS, 0], np.zeros(F), root[:, 2] - rest[HIPS, 2]], -1)
    for S in ("Left", "Right"):
        up, leg, foot = IX[f"{S}UpLeg"], IX[f"{S}Leg"], IX[f"{S}Foot"]
        hip = root + np.einsum("fij,j->fi", G[:, HIPS], off[up])
        target = rest[foot] + travel
        a, b = np.linalg.norm(off[leg]), np.linalg.norm(off[foot])
        pole = np.einsum("fij,j->fi", G[:, HIPS], np.array([0.0, 0.0, 1.0]))
        knee = two_bone(hip, target, a, b, pole)
        G[:, up] = aim(G[:, HIPS], off[leg], knee - hip)
        G[:, leg] = aim(G[:, up], off[foot], target - knee)
        G[:, foot] = np.eye(3)
        G[:, IX[f"{S}ToeBase"]] = np.eye(3)


def sole_direction(rest: np.ndarray, side: str) -> np.ndarray:
    """The unit direction of a foot's sole in the rest pose (``side``: ``Left`` / ``Right``): heel to toe tip,
    level with the floor (the rest foot stands flat), i.e. the ankle-to-toe-tip line with its height taken out.
    A tracked heel-to-toe-tip line aims it, so a flat foot in the picture is a flat foot on the character
    (the ankle-to-ball bone slopes down: aimed at the ankle-to-toe-tip line it stood the foot on its toes)."""
    d = rest[IX[f"{side}Toe_End"]] - rest[IX[f"{side}Foot"]]
    d = np.array([d[0], 0.0, d[2]])
    return d / max(np.linalg.norm(d), 1e-9)


def seated_legs(body: np.ndarray, rest: np.ndarray) -> dict:
    """Legs of a person seated on a chair, as :func:`tracked_legs` takes them (``{"left_hip": [F, 3], ...}``,
    pelvis-relative, the body's metres): each thigh forward from its hip and level, each shin straight down,
    the feet flat and forward, all turned with the hips (their left-right line; the chest's where the hips are
    unseen). For a speaker seen from the waist up while seated, whose legs the picture never shows."""
    t = lambda n: body[:, _T[n]].astype(np.float64)
    across = t("left_hip") - t("right_hip")
    chest = t("left_shoulder") - t("right_shoulder")
    across = np.where(np.isfinite(across).all(-1, keepdims=True), across, chest)
    across[:, 1] = 0.0
    up = np.array([0.0, 1.0, 0.0])
    fwd = unit(np.cross(across, up))
    fwd = np.where(np.isfinite(fwd).all(-1, keepdims=True), fwd, [0.0, 0.0, 1.0])
    scale = np.nanmedian(np.linalg.norm(chest, axis=-1)) / max(
        np.linalg.norm(rest[IX["LeftArm"]] - rest[IX["RightArm"]]), 1e-6
    )
    scale = float(scale) if np.isfinite(scale) and scale > 0 else 1.0
    off = rest_offsets(rest) * scale
    out = {}
    hips = {}
    for s in ("left", "right"):
        hip = t(f"{s}_hip")
        hips[s] = np.where(np.isfinite(hip).all(-1, keepdims=True), hip, (0.5 if s == "left" else -0.5) * across)
    shin = np.linalg.norm(off[IX["LeftFoot"]])
    floor = np.minimum(hips["left"][:, 1], hips["right"][:, 1]) - shin  # both feet on it, whatever the hips' roll
    for S, s in (("Left", "left"), ("Right", "right")):
        half = hips[s]
        thigh, shin = np.linalg.norm(off[IX[f"{S}Leg"]]), np.linalg.norm(off[IX[f"{S}Foot"]])
        drop = np.clip(half[:, 1] - shin - floor, 0.0, 0.8 * thigh)[:, None]  # the higher hip's thigh slopes
        knee = half + fwd * np.sqrt(thigh**2 - drop**2) - up * drop
        ankle = knee - up * shin
        out[f"{s}_hip"], out[f"{s}_knee"], out[f"{s}_ankle"] = half, knee, ankle
        out[f"{s}_heel"] = ankle - up * 0.05 * scale - fwd * 0.04 * scale
        out[f"{s}_foot_index"] = ankle - up * 0.05 * scale + fwd * 0.16 * scale
    return out


def tracked_legs(G: np.ndarray, legs: dict, rest: np.ndarray) -> np.ndarray:
    """Legs from tracked knees and ankles (``legs``: ``{"left_knee": [F, 3], ...}`` hips-relative like the
    body); fills the leg joints of ``G`` where seen and returns the frames where both legs were seen."""
    off = rest_offsets(rest)
    ok = np.ones(len(G), bool)
    for S, s in (("Left", "left"), ("Right", "right")):
        up, leg, foot = IX[f"{S}UpLeg"], IX[f"{S}Leg"], IX[f"{S}Foot"]
        hip, knee, ankle = legs.get(f"{s}_hip"), legs.get(f"{s}_knee"), legs.get(f"{s}_ankle")
        if hip is None or knee is None or ankle is None:
            return np.zeros(len(G), bool)
        g_up = aim(G[:, HIPS], off[leg], knee - hip)
        g_leg = aim(g_up, off[foot], ankle - knee)
        # the thigh seen, the shin not (a seated person cut off at the knees): the shin hangs straight down
        hang = aim(g_up, off[foot], np.broadcast_to(np.array([0.0, -1.0, 0.0]), knee.shape))
        g_leg = np.where((~np.isfinite(g_leg).all((-1, -2)) & np.isfinite(g_up).all((-1, -2)))[:, None, None], hang,
                         g_leg)  # fmt: skip
        toe, heel = legs.get(f"{s}_foot_index"), legs.get(f"{s}_heel")
        if toe is not None and heel is not None:  # the foot's pitch from its sole line, heel to toe tip
            g_foot = aim(g_leg, sole_direction(rest, S), toe - heel)
        else:
            g_foot = aim(g_leg, off[IX[f"{S}ToeBase"]], toe - ankle) if toe is not None else g_leg
        g_foot = np.where(np.isfinite(g_foot).all((-1, -2))[:, None, None], g_foot, g_leg)  # the toe unseen
        seen = np.isfinite(g_up).all((-1, -2)) & np.isfinite(g_leg).all((-1, -2))
        ok &= seen
        for j, g in ((up, g_up), (leg, g_leg), (foot, g_foot), (IX[f"{S}ToeBase"], g_foot)):
            G[seen, j] = g[seen]
    return ok


def root_track(image: np.ndarray | None, body: np.ndarray, fps: float) -> np.ndarray:
    """Horizontal travel ``[F]`` (metres, +x the picture's right) of the person: the shoulders' midpoint in the
    picture, in metres by the clip's metres per pixel (world over picture shoulder width), relative to its
    median, smoothed over half a second; zeros without a picture track."""
    F = len(body)
    if image is None:
        return np.zeros(F)
    ls, rs = _T["left_shoulder"], _T["right_shoulder"]
    u = (image[:, ls, 0] + image[:, rs, 0]) / 2
    wpx = np.linalg.norm(image[:, ls] - image[:, rs], axis=-1)
    wm = np.linalg.norm(body[:, ls] - body[:, rs], axis=-1)
    ok = np.isfinite(u) & np.isfinite(wpx) & np.isfinite(wm) & (wpx > 1)
    if ok.sum() < 2:
        return np.zeros(F)
    mpp = float(np.median(wm[ok] / wpx[ok]))
    x = np.interp(np.arange(F), np.flatnonzero(ok), (u[ok] - np.median(u[ok])) * mpp)
    return np.clip(gaussian_smooth(x[:, None], 0.5 * fps)[:, 0], -1.0, 1.0)


def solve(
    body: np.ndarray | None,
    rest: np.ndarray,
    fps: float,
    head_rot: np.ndarray | None = None,
    image: np.ndarray | None = None,
    legs: dict | None = None,
    seed: int = 0,
    blend_s: float = BLEND_S,
    frames: int | None = None,
) -> dict:
    """The motion on the rig: ``{"root" [F, 3], "local" [F, J, 3, 3], "global", "positions" [F, J, 3],
    "report"}``. ``body [F, 55, 3]``: tracked or generated joints (pelvis-relative, NaN where unseen; None: an
    idle body, e.g. for a face from text); ``rest [J, 3]``: the character's rest joints; ``head_rot [F, 3, 3]``:
    the face fit's head rotations (they turn the head where finite); ``image [F, 55, 2]``: the joints in the
    picture (the root's travel); ``legs``: tracked leg joints (else the standing legs)."""
    F = len(body) if body is not None else frames if frames is not None else len(head_rot)
    idle = body is None
    if idle:
        body = idle_body(F, rest, fps, seed)
    G = _globals(body, rest, head_rot, fps)
    t = np.arange(F) / fps
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi)
    sway = SWAY_M * np.sin(2 * np.pi * t / SWAY_PERIOD_S + phase)
    root = np.tile(rest[HIPS], (F, 1))
    root[:, 0] += sway + root_track(image, body, fps)
    root[:, 1] += -0.008 - 0.004 * (1 - np.cos(4 * np.pi * t / SWAY_PERIOD_S + 2 * phase)) / 2
    # the upper body's rotations as locals, held and blended where unseen, then forward again
    upper = np.ones(N_RIG, bool)
    for S in ("Left", "Right"):
        for n in ("UpLeg", "Leg", "Foot", "ToeBase", "Toe_End"):
            upper[IX[f"{S}{n}"]] = False
    par = np.maximum(PARENTS_RIG, 0)
    Lu = np.full_like(G, np.nan)
    for j in range(N_RIG):
        if not upper[j] or LEAVES[j]:
            continue
        Lu[:, j] = G[:, j] if j == HIPS else np.swapaxes(G[:, par[j]], -1, -2) @ G[:, j]
    for j in np.flatnonzero(LEAVES):
        Lu[:, j] = np.eye(3)
    filled, seen = hold_and_blend(np.where(upper[None, :, None, None], Lu, np.eye(3)), fps, blend_s)
    G2, _ = forward(filled, rest, root)
    standing_legs(G2, root, rest)
    for j in np.flatnonzero(LEAVES):
        G2[:, j] = G2[:, PARENTS_RIG[j]]
    L = local_rotations(G2, PARENTS_RIG)
    leg_seen = np.zeros(F, bool)
    leg_weight = np.zeros(F)
    if legs:
        Gt = G2.copy()
        leg_seen = tracked_legs(Gt, legs, rest)
        if leg_seen.any():
            # tracked where both legs are seen; between such frames the legs hold their last tracked pose and
            # blend into the next (a seated person stays seated when the legs leave the picture for a moment);
            # standing only before the first and after the last seen frame, cross-faded over blend_s
            Lt = local_rotations(Gt, PARENTS_RIG)
            legj = np.flatnonzero(~upper & ~LEAVES)
            Lt[~leg_seen] = np.nan
            first, last = np.flatnonzero(leg_seen)[[0, -1]]
            held, _ = hold_and_blend(Lt[:, legj], fps, blend_s)
            n = max(1, int(round(blend_s * fps)))
            w = np.ones(F)  # open at the clip's ends: legs seen from the first frame are tracked from it
            w[:first] = np.clip(1.0 - (first - np.arange(first)) / (n + 1), 0.0, 1.0)
            w[last + 1 :] = np.clip(1.0 - (np.arange(last + 1, F) - last) / (n + 1), 0.0, 1.0)
            for k, j in enumerate(legj):
                L[:, j] = slerp_rot(L[:, j], held[:, k], w)
            leg_weight = w
            leg_seen = w > 0
    G3, P = forward(L, rest, root)
    report = {
        "joints_never_seen": [NAMES[j] for j in range(N_RIG) if upper[j] and not LEAVES[j] and not seen[:, j].any()]
        if not idle
        else [],
        "legs": "tracked"
        if leg_seen.all()
        else ("standing" if not leg_seen.any() else "tracked where seen, else standing"),
        "max_joint_step_m": round(float(np.linalg.norm(np.diff(P, axis=0), axis=-1).max()), 4) if F > 1 else 0.0,
    }
    return {"root": root, "local": L, "global": G3, "positions": P, "report": report, "leg_seen": leg_seen,
            "leg_weight": leg_weight}  # fmt: skip


def _relaxed_hand(J: np.ndarray, s: str, wrist: np.ndarray, down: np.ndarray, palm: np.ndarray, rest) -> None:
    """A hanging hand at rest: the palm towards the thigh (``palm``), the fingers down along ``down`` and
    curled a little towards the palm, the thumb forwards; lengths from the character's rest hand."""
    S = s.capitalize()
    r = lambda n: rest[IX[f"{S}{n}"]]
    side = unit(np.cross(palm, down))  # across the knuckles, from the little finger to the index
    if (side @ np.array([0.0, 0.0, 1.0])).mean() < 0:
        side = -side
    J[:, _T[f"{s}_hand_wrist"]] = wrist
    spread = {"index": 0.028, "middle": 0.008, "ring": -0.011, "pinky": -0.028}
    for f, off in spread.items():
        F_ = f.capitalize()
        lens = [np.linalg.norm(r(f"Hand{F_}{k + 1}") - r(f"Hand{F_}{k}")) for k in (1, 2, 3)]
        p = wrist + down * np.linalg.norm(r(f"Hand{F_}1") - r("Hand")) + side * off
        J[:, _T[f"{s}_hand_{f}_mcp"]] = p
        for k, (seg, ln) in enumerate(zip(("pip", "dip", "tip"), lens), 1):
            p = p + ln * unit(down + 0.35 * k * palm)
            J[:, _T[f"{s}_hand_{f}_{seg}"]] = p
    fwd = np.broadcast_to(np.array([0.0, 0.0, 1.0]), wrist.shape)
    p = wrist + down * 0.03 + side * 0.03
    J[:, _T[f"{s}_hand_thumb_cmc"]] = p
    for seg in ("mcp", "ip", "tip"):
        p = p + 0.03 * unit(down + fwd + 0.3 * palm)
        J[:, _T[f"{s}_hand_thumb_{seg}"]] = p


def idle_body(F: int, rest: np.ndarray, fps: float, seed: int = 0) -> np.ndarray:
    """A tracked-like body ``[F, 55, 3]`` of a person standing at ease (for a face from text): arms hanging
    with the elbows slightly bent, breathing (the chest rising 4 mm every 4 s), a slow sway of the arms; hands
    relaxed. Made from the character's rest proportions, pelvis-relative."""
    rng = np.random.default_rng(seed)
    t = np.arange(F) / fps
    J = np.full((F, len(JOINT_NAMES), 3), np.nan)
    hips = rest[HIPS]
    put = lambda name, p: J.__setitem__((slice(None), _T[name]), p)
    breath = 0.004 * np.sin(2 * np.pi * t / 4.0 + rng.uniform(0, 6.3))[:, None]
    put("pelvis", np.zeros((F, 3)))
    put("left_hip", np.tile(rest[IX["LeftUpLeg"]] - hips, (F, 1)))
    put("right_hip", np.tile(rest[IX["RightUpLeg"]] - hips, (F, 1)))
    for S, s, sx in (("Left", "left", 1.0), ("Right", "right", -1.0)):
        sh = rest[IX[f"{S}Arm"]] - hips + np.array([0, 1, 0]) * breath
        upper = np.linalg.norm(rest[IX[f"{S}ForeArm"]] - rest[IX[f"{S}Arm"]])
        fore = np.linalg.norm(rest[IX[f"{S}Hand"]] - rest[IX[f"{S}ForeArm"]])
        swing = 0.03 * np.sin(2 * np.pi * t / 5.5 + rng.uniform(0, 6.3))
        elbow = sh + upper * unit(np.stack([np.full(F, sx * 0.12), -np.ones(F), swing], -1))
        wrist = elbow + fore * unit(np.stack([np.full(F, sx * 0.05), -np.ones(F), 0.3 + swing], -1))
        put(f"{s}_shoulder", sh)
        put(f"{s}_elbow", elbow)
        put(f"{s}_wrist", wrist)
        _relaxed_hand(J, s, wrist, unit(wrist - elbow), np.array([-sx, 0.0, 0.0]), rest)
    put("neck", (J[:, _T["left_shoulder"]] + J[:, _T["right_shoulder"]]) / 2)
    head = J[:, _T["neck"]] + (rest[HEAD] - (rest[IX["LeftArm"]] + rest[IX["RightArm"]]) / 2) + np.array([0, 0.08, 0])
    put("head", head)
    put("nose", head + np.array([0.0, -0.02, 0.10]))
    put("spine", J[:, _T["neck"]] / 2)
    return J


# ---- names in other conventions ----------------------------------------------------------------------------

_VRM_BODY = {
    "Hips": "hips", "Spine": "spine", "Spine1": "chest", "Spine2": "upperChest", "Neck": "neck", "Head": "head",
    "Shoulder": "Shoulder", "Arm": "UpperArm", "ForeArm": "LowerArm", "Hand": "Hand",
    "UpLeg": "UpperLeg", "Leg": "LowerLeg", "Foot": "Foot", "ToeBase": "Toes",
}  # fmt: skip
_VRM_FINGER = {
    "Thumb": ("Metacarpal", "Proximal", "Distal"),
    **{f: ("Proximal", "Intermediate", "Distal") for f in FINGERS[1:]},
}
_UE_BODY = {
    "Hips": "pelvis", "Spine": "spine_01", "Spine1": "spine_02", "Spine2": "spine_03", "Neck": "neck_01",
    "Head": "head", "Shoulder": "clavicle", "Arm": "upperarm", "ForeArm": "lowerarm", "Hand": "hand",
    "UpLeg": "thigh", "Leg": "calf", "Foot": "foot", "ToeBase": "ball",
}  # fmt: skip


def _convention(name: str, kind: str) -> str:
    """A rig joint's name in ``kind`` (mixamo, vrm, unreal); "" where the convention names no such joint."""
    if kind == "anima":
        return name
    if kind == "mixamo":
        return f"mixamorig:{name}"
    side = "Left" if name.startswith("Left") else "Right" if name.startswith("Right") else ""
    rest = name[len(side) :]
    if rest.startswith("Hand") and rest[4:-1] in FINGERS:
        finger, k = rest[4:-1], int(rest[-1])
        if k == 4:
            return ""
        if kind == "vrm":  # VRM calls the little finger "Little"
            return f"{side.lower()}{'Little' if finger == 'Pinky' else finger}{_VRM_FINGER[finger][k - 1]}"
        return f"{finger.lower()}_0{k}_{side[0].lower()}"
    table = _VRM_BODY if kind == "vrm" else _UE_BODY
    if rest not in table:
        return ""
    if not side:
        return table[rest]
    if kind == "vrm":
        return f"{side.lower()}{table[rest]}"
    return f"{table[rest]}_{side[0].lower()}"


CONVENTIONS = {k: {n: _convention(n, k) for n in NAMES} for k in ("anima", "mixamo", "vrm", "unreal")}
"""``{convention: {rig joint: its name there}}`` ("" where the convention has no such joint: the end joints in
VRM and Unreal)."""
PRESETS = tuple(CONVENTIONS)
NAME_SEARCH = ("mixamo", "unreal", "vrm", "anima")
"""The order a user's skeleton is matched against the conventions by bone name (the one with most matches wins,
a tie goes to the earlier): the exporters' conventions first, anima's own last."""


def preset_names(preset: str) -> list[str]:
    """The rig's joint names in ``preset`` (anima, vrm, mixamo, unreal); a joint the convention does not name
    keeps anima's name (VRM's and Unreal's end joints)."""
    if preset not in CONVENTIONS:
        raise ValueError(f"unknown rig preset {preset!r}; one of {', '.join(PRESETS)}")
    return [CONVENTIONS[preset][n] or n for n in NAMES]


def frame_locals(
    body: np.ndarray, rest: np.ndarray, head_rot: np.ndarray | None, held: np.ndarray, legs: dict | None = None
) -> np.ndarray:
    """One frame of a stream (``anima live``): local rotations ``[J, 3, 3]`` of the upper body from tracked joints
    ``body [55, 3]`` (NaN where unseen) and the face fit's head rotation (``[3, 3]`` or None), every joint not
    seen now kept at ``held`` (the previous frame's locals); the legs from ``legs`` (``{"left_hip": [3],
    "left_knee": ..., ...}``, as :func:`tracked_legs` takes them for one frame) where both are seen, else
    standing straight; the end joints rest. No look-ahead: the offline retargeting's blends and flip rules need
    the clip's future, a stream has none."""
    any_rate = 30.0  # contract: not (one frame: no rate is used)
    G = _globals(body[None], rest, None if head_rot is None else head_rot[None], any_rate)[0]
    par = np.maximum(PARENTS_RIG, 0)
    L = np.einsum("jba,jbc->jac", G[par], G)
    L[HIPS] = G[HIPS]
    ok = np.isfinite(L).all((-1, -2))
    out = np.where(ok[:, None, None], L, held)
    legj = [IX[f"{S}{n}"] for S in ("Left", "Right") for n in ("UpLeg", "Leg", "Foot", "ToeBase")]
    seen = False
    if legs and np.isfinite(G[HIPS]).all():
        Gl = G[None].copy()
        seen = bool(tracked_legs(Gl, {k: np.asarray(v, np.float64)[None] for k, v in legs.items()}, rest)[0])
        if seen:
            Ll = np.einsum("jba,jbc->jac", Gl[0][par], Gl[0])
            out[legj] = Ll[legj]
    if not seen:
        out[legj] = np.eye(3)
    out[LEAVES] = np.eye(3)
    return out
