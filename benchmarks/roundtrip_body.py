"""The body's round trip with ground truth: real mocap with global trajectories played on anima's
character, filmed by a camera in Blender (a still one and one that pans to follow), captured back with anima's
capture, and compared with the truth.

    python benchmarks/roundtrip_body.py            # writes benchmarks/results/roundtrip_body.json (~15-20 min)

**Truth.** Real mocap with global trajectories: Human3.6M's world poses (``pose3d/derived/
h36m_3d17_world_mm_10fps_allsubjects.npz``, S9 "Walking", 5 s from 2 s in, 10 fps resampled to 25 by cubic
splines; Human3.6M's research terms: nothing of it leaves this machine) and a CMU jumping clip
(``pose3d/derived/cmu_dmgnn_38j_mm_30fps.npz``, "train/jumping/jumping_2", the first 5 s, 30 fps; free for any
use; its vertical trajectory is kept, the horizontal one of this conversion is not trusted: the walks' feet
slide in it, so CMU's walks are not used). Fast motion: CMU's "test/basketball/basketball_1" and
"test/soccer/soccer_1", 2.5 s each from 2 s in (their fastest stretch; the wrists reach 2-3 m/s at the 80th
percentile; the feet of this conversion slide, so the truth has no stance frames). A hand resting on the
chest, which no clip shows: Human3.6M S9 "Posing" (3.5 s from 7.5 s in: standing, facing the camera) with the
right arm posed by a two-bone IK (:func:`put_hand_on_chest`: 0.8 s reaching in, the palm held 2 s on the left
of the character's skinned chest, 0.5 s letting go). Each is put on the character (``anima.core.rig.solve`` on its
joints, the hips' trajectory scaled by the character's hip height over the actor's) and written as the
character's glTF. The character's joints by its own forward
kinematics are the truth; a foot is in contact where its truth moves under 0.25 m/s within 5 cm of its
lowest height.

**Film.** ``benchmarks/blender_render_take.py`` renders it at 720 x 720 (a 35 mm lens on a 36 mm sensor, 55
degrees across): the camera 4.5 m in front of the clip's centre at 1.2 m, still (the person fills 30 to 50 % of
the picture's height as they walk); or at the same place turning to follow the hips (a pan). The frames become
an H.264 video at the clip's rate.

**Capture.** ``anima capture VIDEO --no-render`` (the shipped defaults), then the character's motion
(``anima.export.avatar.character_motion``). The capture's world is the camera's frame at the first frame (the
pan taken out), the truth's is the scene's: the two are aligned once, by the rotation about the vertical and
the translation that best match the hips over the first second (a per-frame alignment would hide drift).

**Metrics** (each on the 12 joints both have: hips, knees, ankles, shoulders, elbows, wrists): W-MPJPE (mm,
world joints after that one alignment), root error (mm, the hips), the hips' travel (path length) over the
truth's (and in body heights: the captured character is shaped to the tracker's measures, the truth is the
default character), the feet's contacts against the truth's (precision, recall), foot sliding (mm per frame,
median over the truth's contact frames, the ankle's horizontal step), the feet on those stance frames (the ankle's
height over the ball of the foot against the character's flat foot, the sole's pitch to the floor: a foot on
tip-toe reads high on both; how high the sole is above the floor: a foot that should stand there floats),
penetration (the lowest sole, m), jitter
(mean joint acceleration, m/s^2) and, for the jumps, how high the hips rise (the 95th percentile of their
height over its median). The fast clips add the arms' (shoulders, elbows, wrists) and the legs' W-MPJPE, the
arms' tracked fraction as capture counts it (``joint_groups_tracked``), the wrists' error on the fastest 20 % of
wrist frames (by the truth's wrist speed) and the largest per-frame turn of any body bone's world direction
(degrees; the truth's beside it). The hand on the chest adds, on the hold frames, the palm's distance to the
captured character's own skinned torso (as ``tests/core/test_ground.py`` measures it), its depth over the
torso's front along the chest's forward axis (the side view's error) and the frames capture held the hand on it.
**Baseline**: the raw tracker, MediaPipe Holistic's world landmarks as capture stores
them (pelvis-centred: no root, no floor).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_video
from anima.core import kinematics, rig
from anima.core.character import CharacterMesh, Motion, Skeleton
from anima.core.contract import JOINT_NAMES, LEG_JOINTS
from anima.core.rotations import matrix_to_quat
from anima.export.avatar import character_motion
from anima.facemodel.character import load_character
from anima.io.assets import asset
from anima.io.atomic import write_json
from anima.io.gltf import write_character_glb
from anima.io.sequence import read_sequence, write_sequence
from anima.io.video import FFMPEG
from anima.render.raster import vertex_normals

CMU = "pose3d/derived/cmu_dmgnn_38j_mm_30fps.npz"
H36M = "pose3d/derived/h36m_3d17_world_mm_10fps_allsubjects.npz"
CLIPS = {"walking": ("h36m", "S9/Walking", 2.0, 5.0), "jumping": ("cmu", "train/jumping/jumping_2", 0.0, 5.0),
         "basketball": ("cmu", "test/basketball/basketball_1", 2.0, 2.5),
         "soccer": ("cmu", "test/soccer/soccer_1", 2.0, 2.5),
         "hand_on_chest": ("h36m", "S9/Posing", 7.5, 3.5)}  # fmt: skip
FAST = ("basketball", "soccer")
# the hand on the chest (posed by IK on the clip): seconds before, reaching in, held, letting go
CHEST_TIMES = (0.2, 0.8, 2.0, 0.5)
ARMS = ("LeftArm", "RightArm", "LeftForeArm", "RightForeArm", "LeftHand", "RightHand")
LEGS = ("LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg", "LeftFoot", "RightFoot")
FPS = 25.0
DISTANCE_M, SIZE = 4.5, 720
# Human3.6M's 17 joints -> the CMU indices _CMU uses (for one conversion of both): pelvis 0, r_hip 1, r_knee 2,
# r_ankle 3, l_hip 4, l_knee 5, l_ankle 6, spine 7, thorax 8, neck_nose 9, head 10, l_shoulder 11, l_elbow 12,
# l_wrist 13, r_shoulder 14, r_elbow 15, r_wrist 16
_H36M_AS_CMU = {0: 0, 2: 4, 3: 5, 4: 6, 8: 1, 9: 2, 10: 3, 14: 7, 16: 8, 18: 9, 19: 10, 21: 11, 22: 12, 23: 13,
                30: 14, 31: 15, 32: 16}  # fmt: skip
# CMU (DMGNN's 38 joints) -> anima's tracked joints; chain 1-6 the left leg, 20-28 the left arm (ASF order)
_CMU = {"pelvis": 0, "left_hip": 2, "left_knee": 3, "left_ankle": 4, "left_foot_index": 5, "right_hip": 8,
        "right_knee": 9, "right_ankle": 10, "right_foot_index": 11, "spine": 14, "neck": 16, "head": 18,
        "nose": 19, "left_shoulder": 21, "left_elbow": 22, "left_wrist": 23, "right_shoulder": 30,
        "right_elbow": 31, "right_wrist": 32}  # fmt: skip
COMPARE = ("LeftUpLeg", "RightUpLeg", "LeftLeg", "RightLeg", "LeftFoot", "RightFoot", "LeftArm", "RightArm",
           "LeftForeArm", "RightForeArm", "LeftHand", "RightHand")  # fmt: skip
_RAW = {"LeftUpLeg": "left_hip", "RightUpLeg": "right_hip", "LeftArm": "left_shoulder",
        "RightArm": "right_shoulder", "LeftForeArm": "left_elbow", "RightForeArm": "right_elbow",
        "LeftHand": "left_wrist", "RightHand": "right_wrist"}  # fmt: skip
_RAW_LEGS = {"LeftLeg": "left_knee", "RightLeg": "right_knee", "LeftFoot": "left_ankle", "RightFoot": "right_ankle"}


def _resample(J: np.ndarray, fps: float, start_s: float, seconds: float) -> np.ndarray:
    from scipy.interpolate import CubicSpline

    t = np.arange(len(J)) / fps
    new = start_s + np.arange(int(round(seconds * FPS))) / FPS
    new = new[new <= t[-1]]
    out = np.full((len(new),) + J.shape[1:], np.nan)
    ok = np.isfinite(J).all((0, 2))
    out[:, ok] = CubicSpline(t, J[:, ok], axis=0)(new)
    return out


def clip(kind: str, name: str, start_s: float, seconds: float) -> np.ndarray:
    """A clip's joints ``[F, 38, 3]`` (CMU's indices; Human3.6M's placed at the same ones) in anima's axes
    (metres, +y up), at :data:`FPS`."""
    if kind == "cmu":
        z = np.load(asset(CMU), allow_pickle=False)
        k = list(z["seq_name"]).index(name)
        a, n = int(z["seq_start"][k]), int(z["seq_len"][k])
        J = z["joints38_mm"][a : a + n].astype(np.float64) / 1000.0
        J = np.stack([J[..., 0], J[..., 2], J[..., 1]], -1)  # index 2 up, mirrored by the source's swap: undone
        fps = float(z["source_fps_estimate"]) / float(z["frame_step_from_source"])
    else:
        z = np.load(asset(H36M), allow_pickle=False)
        k = list(z["seq_name"]).index(name)
        a, n = int(z["seq_start"][k]), int(z["seq_len"][k])
        H = z["joints17_world_mm"][a : a + n].astype(np.float64) / 1000.0
        H = np.stack([H[..., 0], H[..., 2], -H[..., 1]], -1)  # z up -> y up (a rotation)
        J = np.full((len(H), 38, 3), np.nan)
        for c, h in _H36M_AS_CMU.items():
            J[:, c] = H[:, h]
        J[:, 5], J[:, 11] = J[:, 4], J[:, 10]  # no toes: the ankles
        fps = 10.0
    return _resample(J, fps, start_s, seconds)


def torso_vertices(ch) -> np.ndarray:
    """The character's torso vertices (those whose main skin joint is the hips or a spine joint)."""
    main = ch.skin_joints[np.arange(len(ch.skin_joints)), np.argmax(ch.skin_weights, 1)]
    return np.isin(main, [rig.IX[n] for n in ("Hips", "Spine", "Spine1", "Spine2")])


def palm_centre(P: np.ndarray, S: str) -> np.ndarray:
    """The palm's centre ``[..., 3]`` as tests/core/test_ground.py measures it (wrist and index/middle knuckles)."""
    k = [rig.IX[f"{S}Hand{x}1"] for x in ("Index", "Middle")]
    return 0.5 * P[..., rig.IX[f"{S}Hand"], :] + 0.5 * P[..., k, :].mean(-2)


def put_hand_on_chest(L, G, P, rest, V, ch, fps):
    """The right palm brought onto the left of the chest (over the heart, the fingers across the chest, the
    thumb up, the palm on the character's skinned torso surface plus the hand's thickness) by a two-bone IK of
    the arm: :data:`CHEST_TIMES`; the wrist's path from where the clip has it bulges 10 cm forwards. Returns the
    new locals and the hold frames ``[F]``."""
    from anima.core.contact import HAND_THICKNESS_M, TorsoSurface

    F = len(L)
    lead, reach, held, out = (int(round(x * fps)) for x in CHEST_TIMES)
    w = np.zeros(F)
    ramp = lambda n: 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n + 1) / (n + 1))
    w[lead : lead + reach] = ramp(reach)
    w[lead + reach : lead + reach + held] = 1.0
    w[lead + reach + held : lead + reach + held + out] = ramp(out)[::-1]
    hold = w == 1.0
    chest = rig.IX["Spine2"]
    surf = TorsoSurface.from_mesh(V, rest[chest], torso_vertices(ch))
    spot = np.array([0.05, 0.04, 0.0])
    spot[2] = surf.front(spot[None])[0] + HAND_THICKNESS_M
    R0 = np.array([[-1.0, 0, 0], [0, 0, 1], [0, 1, 0]])  # rest (fingers -x, palm -y) -> fingers +x, palm -z
    sh, arm, fore, hand = (rig.IX[n] for n in ("RightShoulder", "RightArm", "RightForeArm", "RightHand"))
    palm_off = palm_centre(rest, "Right") - rest[hand]
    a, b = np.linalg.norm(rest[fore] - rest[arm]), np.linalg.norm(rest[hand] - rest[fore])
    Gc = G[:, chest]
    Gh_t = Gc @ R0
    W_t = P[:, chest] + np.einsum("fij,j->fi", Gc, spot) - np.einsum("fij,j->fi", Gh_t, palm_off)
    fwd = np.einsum("fij,j->fi", Gc, [0.0, 0.0, 1.0])
    W = (1 - w)[:, None] * P[:, hand] + w[:, None] * W_t + 0.1 * np.sin(np.pi * w)[:, None] * fwd
    pole_t = np.einsum("fij,j->fi", Gc, kinematics.unit(np.array([-1.0, -1.0, -0.3])))
    pole = (1 - w)[:, None] * kinematics.unit(P[:, fore] - P[:, arm]) + w[:, None] * pole_t
    on = w > 0
    el = kinematics.two_bone(P[on, arm], W[on], a, b, pole[on])
    Ga = kinematics.aim(G[on, sh], rest[fore] - rest[arm], el - P[on, arm])
    Gf = kinematics.aim(Ga, rest[hand] - rest[fore], W[on] - el)
    Gh = rig.slerp_rot(G[on, hand], Gh_t[on], w[on])
    L = L.copy()
    T = lambda M: np.swapaxes(M, -1, -2)
    L[on, arm], L[on, fore], L[on, hand] = T(G[on, sh]) @ Ga, T(Ga) @ Gf, T(Gf) @ Gh
    return L, hold


def truth_motion(J: np.ndarray, fps: float, on_chest: bool = False):
    """The clip on the character: its rig motion (rotations from the clip's joints, the hips where the clip's
    are, scaled to the character) and the character's rest."""
    pelvis = J[:, 0]
    F = len(J)
    body = np.full((F, len(JOINT_NAMES), 3), np.nan)
    for n, i in _CMU.items():
        if n in JOINT_NAMES:
            body[:, JOINT_NAMES.index(n)] = J[:, i] - pelvis
    body[:, JOINT_NAMES.index("neck")] = (J[:, 21] + J[:, 30]) / 2 - pelvis
    legs = {n: J[:, _CMU[n]] - pelvis for n in LEG_JOINTS if n in _CMU}
    legs["left_hip"], legs["right_hip"] = (
        body[:, JOINT_NAMES.index("left_hip")],
        body[:, JOINT_NAMES.index("right_hip")],
    )
    ch = load_character()
    V, rest = ch.shaped(np.zeros(ch.n_components))
    mo = rig.solve(body, rest, fps, None, legs=legs, frames=F)
    floor = np.percentile(J[:, [4, 10], 1].min(1), 2)
    scale = rest[rig.HIPS, 1] / np.median(pelvis[:, 1] - floor)
    root = np.stack([pelvis[:, 0] * scale, (pelvis[:, 1] - floor) * scale, pelvis[:, 2] * scale], -1)
    root[:, [0, 2]] -= root[:, [0, 2]].mean(0)
    G, P = rig.forward(mo["local"], rest, root)
    sole = np.min([P[:, rig.IX[n], 1] - rest[rig.IX[n], 1] for n in ("LeftFoot", "RightFoot", "LeftToeBase",
                                                                      "RightToeBase")], 0)  # fmt: skip
    root[:, 1] -= np.percentile(sole, 2)  # the truth stands on the floor
    G, P = rig.forward(mo["local"], rest, root)
    hold = None
    if on_chest:
        mo["local"], hold = put_hand_on_chest(mo["local"], G, P, rest, V, ch, fps)
        G, P = rig.forward(mo["local"], rest, root)
    return {
        "hold": hold,
        "local": mo["local"],
        "root": root,
        "global": G,
        "positions": P,
        "rest": rest,
        "vertices": V,
        "ch": ch,
    }


def write_take(m: dict, fps: float, path: Path) -> Path:
    ch = m["ch"]
    F = len(m["root"])
    skeleton = Skeleton(rig.preset_names("anima"), rig.PARENTS_RIG, m["rest"])
    morphs = list(zip(ch.morph_index, ch.morph_delta))
    c = CharacterMesh(skeleton, m["vertices"], vertex_normals(m["vertices"], ch.faces), ch.faces, ch.skin_joints,
                      ch.skin_weights, morphs, [f"m{k}" for k in range(len(morphs))])  # fmt: skip
    motion = Motion(m["root"], matrix_to_quat(m["local"]), fps, np.zeros((F, len(ch.morph_index))), ~rig.LEAVES)
    write_character_glb(path, c, motion, {}, {"anima_fps": fps})
    return path


def film(glb: Path, m: dict, fps: float, pan: bool, work: Path) -> Path:
    F = len(m["root"])
    centre = m["root"].mean(0)
    pos = np.tile([centre[0], 1.2, centre[2] + DISTANCE_M], (F, 1))
    hips = m["root"] * [1, 0, 1] + [0, 1.0, 0]
    target = hips if pan else np.tile([centre[0], 1.0, centre[2]], (F, 1))
    cam = {"fps": fps, "frames": F, "size": SIZE, "lens_mm": 35.0, "sensor_mm": 36.0, "position": pos.tolist(),
           "target": target.tolist()}  # fmt: skip
    (work / "camera.json").write_text(json.dumps(cam))
    frames = work / ("frames_pan" if pan else "frames_still")
    frames.mkdir(exist_ok=True)
    script = Path(__file__).with_name("blender_render_take.py")
    r = subprocess.run(
        [shutil.which("blender"), "-b", "--factory-startup", "--python", str(script), "--", str(glb), str(frames),
         str(work / "camera.json")],
        capture_output=True, text=True, timeout=3600,
    )  # fmt: skip
    if r.returncode != 0 or "anima-render: done" not in r.stdout:
        raise RuntimeError((r.stdout + r.stderr)[-2000:])
    video = work / f"{'pan' if pan else 'still'}.mp4"
    subprocess.run([FFMPEG, "-v", "error", "-y", "-framerate", repr(fps), "-i", str(frames / "frame_%04d.png"),
                    "-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "18", str(video)], check=True)  # fmt: skip
    return video


def _align(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation about +y and the horizontal translation taking points ``A [N, 3]`` onto ``B``, least
    squares (the heights are each motion's own: both stand on a floor at y = 0)."""
    a0, b0 = A.mean(0), B.mean(0)
    H = (A - a0)[:, [0, 2]].T @ (B - b0)[:, [0, 2]]
    th = np.arctan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    c, s = np.cos(th), np.sin(th)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    t = b0 - a0 @ R.T
    t[1] = 0.0
    return R, t


def contacts(P: np.ndarray, rest: np.ndarray, fps: float) -> np.ndarray:
    out = []
    for S in ("Left", "Right"):
        a = P[:, rig.IX[f"{S}Foot"]]
        v = np.linalg.norm(np.gradient(a, axis=0), axis=-1) * fps
        h = a[:, 1] - a[:, 1].min()
        out.append((v < 0.25) & (h < 0.05))
    return np.stack(out, 1)


def metrics(P: np.ndarray, root: np.ndarray, truth: dict, fps: float, rest: np.ndarray | None) -> dict:
    """P ``[F, 65, 3]`` a motion's joints (rig order), already in the truth's frame; ``rest``: its character's
    rest (None for the raw tracker: no soles)."""
    T, Tr = truth["positions"], truth["root"]
    F = min(len(P), len(T))
    idx = [rig.IX[n] for n in COMPARE]
    err = np.linalg.norm(P[:F, idx] - T[:F, idx], axis=-1)
    path = lambda r: np.linalg.norm(np.diff(r[:F, [0, 2]], axis=0), axis=-1).sum()
    c = contacts(T[:F], truth["rest"], fps)
    slide = []
    for k, S in enumerate(("Left", "Right")):
        a = P[:F, rig.IX[f"{S}Foot"], ::2]
        both = c[1:, k] & c[:-1, k]
        slide.append(np.linalg.norm(np.diff(a, axis=0), axis=-1)[both])
    slide = np.concatenate(slide)
    acc = np.nanmean(np.linalg.norm(np.diff(P[:F, idx], 2, axis=0), axis=-1)) * fps * fps
    out = {
        "w_mpjpe_mm": round(1000 * float(np.nanmean(err)), 1),
        "root_error_mm": round(1000 * float(np.nanmean(np.linalg.norm(root[:F] - Tr[:F], axis=-1))), 1),
        "hips_travel_ratio": round(float(path(root) / max(path(Tr), 1e-6)), 3),
        "foot_sliding_mm_per_frame": round(1000 * float(np.median(slide)), 2) if len(slide) else None,
        "contact_frames": int(c.sum()),
        "jitter_m_s2": round(float(acc), 2),
        "hips_rise_m": round(float(np.percentile(root[:F, 1], 95) - np.median(root[:F, 1])), 3),
    }  # fmt: skip
    if rest is not None:
        sole = np.min([P[:F, rig.IX[n], 1] - rest[rig.IX[n], 1] for n in ("LeftFoot", "RightFoot", "LeftToeBase",
                                                                           "RightToeBase", "LeftToe_End",
                                                                           "RightToe_End")], 0)  # fmt: skip
        out["lowest_sole_m"] = round(float(sole.min()), 3)
        if c.any():  # (a clip whose truth never plants a foot has no stance frames)
            out.update(stance_feet(P[:F], rest, c))
    return out


def stance_feet(P: np.ndarray, rest: np.ndarray, contact: np.ndarray) -> dict:
    """On the truth's stance frames (``contact [F, 2]``): the ankle's height over the ball of the foot (the
    character's own flat foot: the rest pose's) and the sole's angle to the floor (the ankle-to-toe-tip line's
    pitch against the rest pose's; 0 flat, positive toes down), medians and the worst frame."""
    over, pitch, above = [], [], []
    for k, S in enumerate(("Left", "Right")):
        f = np.flatnonzero(contact[:, k])
        a, ball, tip = (P[f, rig.IX[f"{S}{n}"]] for n in ("Foot", "ToeBase", "Toe_End"))
        over.append(a[:, 1] - ball[:, 1])
        above.append(np.min([P[f, rig.IX[f"{S}{n}"], 1] - rest[rig.IX[f"{S}{n}"], 1]
                             for n in ("Foot", "ToeBase", "Toe_End")], 0))  # fmt: skip
        line = tip - a
        r = rest[rig.IX[f"{S}Toe_End"]] - rest[rig.IX[f"{S}Foot"]]
        pitch.append(
            np.degrees(np.arcsin(-line[:, 1] / np.linalg.norm(line, axis=-1)) - np.arcsin(-r[1] / np.linalg.norm(r)))
        )
    over, pitch, above = np.concatenate(over), np.concatenate(pitch), np.concatenate(above)
    flat = float(np.mean([rest[rig.IX[f"{S}Foot"], 1] - rest[rig.IX[f"{S}ToeBase"], 1] for S in ("Left", "Right")]))
    return {"stance_ankle_over_ball_cm": round(100 * float(np.median(over)), 2),
            "stance_ankle_over_ball_max_cm": round(100 * float(np.max(over)), 2),
            "flat_foot_ankle_over_ball_cm": round(100 * flat, 2),
            "stance_sole_pitch_deg": round(float(np.median(pitch)), 1),
            "stance_sole_pitch_abs_max_deg": round(float(np.max(np.abs(pitch))), 1),
            "stance_sole_above_floor_cm": round(100 * float(np.median(above)), 1),
            "stance_sole_above_floor_p90_cm": round(100 * float(np.percentile(above, 90)), 1)}  # fmt: skip


def _err(P: np.ndarray, T: np.ndarray, names) -> np.ndarray:
    idx = [rig.IX[n] for n in names]
    return np.linalg.norm(P[:, idx] - T[:, idx], axis=-1)


def fast_metrics(P: np.ndarray, truth: dict, fps: float, seq) -> dict:
    """Fast motion: the arms' and legs' W-MPJPE (mm), the arms' tracked fraction as capture counts it, the
    wrists' error (mm) on the fastest 20 % of wrist frames (by the truth's wrist speed) against all, the arms'
    error with each motion's hips put together (the limbs without the root's), and the largest per-frame turn
    (degrees) of any body bone's world direction (fingers left out), captured and true."""
    T = truth["positions"]
    F = min(len(P), len(T))
    P, T = P[:F], T[:F]
    wr = [rig.IX["LeftHand"], rig.IX["RightHand"]]
    speed = np.linalg.norm(np.gradient(T[:, wr], axis=0), axis=-1) * fps
    fast = speed >= np.percentile(speed, 80)
    ew = _err(P, T, ("LeftHand", "RightHand"))

    def turn(Q):
        body = [j for j, n in enumerate(rig.NAMES) if rig.PARENTS_RIG[j] >= 0
                and (not n.startswith(("LeftHand", "RightHand")) or n in ("LeftHand", "RightHand"))]  # fmt: skip
        d = Q[:, body] - Q[:, rig.PARENTS_RIG[body]]
        d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        a = np.degrees(np.arccos(np.clip((d[1:] * d[:-1]).sum(-1), -1, 1)))
        f, k = np.unravel_index(np.nanargmax(a), a.shape)
        return round(float(a[f, k]), 1), rig.NAMES[body[k]], int(f)

    mx, bone, at = turn(P)
    rel = _err(P - P[:, rig.HIPS, None], T - T[:, rig.HIPS, None], ARMS)
    groups = seq.body_summary()["joint_groups_tracked"]
    return {"arms_w_mpjpe_mm": round(1000 * float(np.nanmean(_err(P, T, ARMS))), 1),
            "legs_w_mpjpe_mm": round(1000 * float(np.nanmean(_err(P, T, LEGS))), 1),
            "arms_tracked": groups["arms"], "hands_tracked": [groups["left_hand"], groups["right_hand"]],
            "arms_mpjpe_hips_relative_mm": round(1000 * float(np.nanmean(rel)), 1),
            "wrist_error_mm": round(1000 * float(np.nanmean(ew)), 1),
            "wrist_error_fastest20_mm": round(1000 * float(np.nanmean(ew[fast])), 1),
            "truth_wrist_speed_p80_m_s": round(float(np.percentile(speed, 80)), 2),
            "max_bone_turn_deg": mx, "max_bone_turn_bone": bone, "max_bone_turn_frame": at,
            "truth_max_bone_turn_deg": turn(T)[0]}  # fmt: skip


def chest_metrics(m: dict, truth: dict, F: int) -> dict:
    """The right hand held on the chest: on the hold frames, the palm's distance (cm) to the captured
    character's own skinned torso (as tests/core/test_ground.py measures it) and the truth's to its own; the
    palm's depth over the torso's front along the chest's forward axis (cm, the side view's error: positive in
    front of it); the frames capture's contact held the right hand."""
    from anima.core.contact import TorsoSurface
    from anima.facemodel.character import skin

    ch = load_character()
    torso = torso_vertices(ch)
    hold = np.flatnonzero(truth["hold"][:F])
    chest = rig.IX["Spine2"]

    def dist(Vr, rest, G, P):
        Vs = skin(Vr, rest, G[hold], P[hold], ch)
        pc = palm_centre(P[hold], "Right")
        d = np.array([np.linalg.norm(Vs[i][torso] - pc[i], axis=-1).min() for i in range(len(hold))])
        surf = TorsoSurface.from_mesh(Vr, rest[chest], torso)
        loc = np.einsum("fji,fj->fi", G[hold, chest], pc - P[hold, chest])
        return d, loc[:, 2] - surf.front(loc)

    d, gap = dist(m["vertices"], m["rest"], m["global"], m["positions"])
    dt, gt = dist(truth["vertices"], truth["rest"], truth["global"], truth["positions"])
    hc = m["hand_contact"][:F]
    return {"hold_frames": int(len(hold)),
            "palm_to_torso_cm": round(100 * float(np.median(d)), 1),
            "palm_to_torso_max_cm": round(100 * float(np.max(d)), 1),
            "truth_palm_to_torso_cm": round(100 * float(np.median(dt)), 1),
            "palm_depth_over_torso_cm": round(100 * float(np.nanmedian(gap)), 1),
            "truth_palm_depth_over_torso_cm": round(100 * float(np.nanmedian(gt)), 1),
            "right_hand_contact_on_hold": round(float(hc[hold, 1].mean()), 3),
            "hand_contact_frames": [int(x) for x in hc.sum(0)]}  # fmt: skip


def raw_positions(seq) -> np.ndarray:
    """The raw tracker's joints on rig indices (pelvis-centred, no root), NaN where it has none."""
    P = np.full((seq.n_frames, rig.N_RIG, 3), np.nan)
    for n, t in _RAW.items():
        P[:, rig.IX[n]] = seq.body_joints_raw[:, JOINT_NAMES.index(t)]
    if seq.leg_joints is not None:
        for n, t in _RAW_LEGS.items():
            P[:, rig.IX[n]] = seq.leg_joints[:, LEG_JOINTS.index(t)]
    return P


def run_case(name: str, pan: bool, work: Path, cache: Path | None = None) -> dict:
    """One clip and camera; ``cache``: a folder keeping the rendered video and its capture (reused when there)."""
    J, fps = clip(*CLIPS[name]), FPS
    truth = truth_motion(J, fps, on_chest=name == "hand_on_chest")
    t0 = time.perf_counter()
    key = f"{name}_{'pan' if pan else 'still'}"
    if cache is not None and (cache / f"{key}.npz").is_file():
        seq = read_sequence(cache / f"{key}.npz")
    else:
        glb = write_take(truth, fps, work / "truth.glb")
        video = film(glb, truth, fps, pan, work)
        seq = capture_video(str(video), CaptureConfig(), progress=False)
        if cache is not None:
            cache.mkdir(parents=True, exist_ok=True)
            write_sequence(seq, cache / f"{key}.npz")
            shutil.copy(video, cache / f"{key}.mp4")
    t1 = time.perf_counter()
    m = character_motion(seq)
    F = min(seq.n_frames, len(truth["root"]))
    n = max(2, min(F, int(round(fps))))
    R, t = _align(m["root"][:n], truth["root"][:n])
    P = m["positions"] @ R.T + t
    root = m["root"] @ R.T + t
    ours = metrics(P, root, truth, fps, m["rest"])
    # the capture's character is shaped to the tracker's measures, the truth is the default character: the
    # travel in body heights takes that size out (the tracker's metres are its own, not the scene's)
    tall = float(truth["vertices"][:, 1].max() - truth["vertices"][:, 1].min())
    ours["hips_travel_ratio_in_heights"] = round(ours["hips_travel_ratio"] * tall / m["report"]["height_m"], 3)
    ours["character_height_m"], ours["truth_height_m"] = m["report"]["height_m"], round(tall, 3)
    tc = contacts(truth["positions"][:F], truth["rest"], fps)
    hit = (m["contact"][:F] & tc).sum()
    ours["contact_precision"] = round(float(hit / max(m["contact"][:F].sum(), 1)), 3)
    ours["contact_recall"] = round(float(hit / max(tc.sum(), 1)), 3)
    raw = raw_positions(seq) + truth["root"][:1]  # the tracker's pelvis-centred joints where the truth starts
    base = metrics(raw, np.tile(truth["root"][:1], (seq.n_frames, 1)), truth, fps, None)
    Tr = truth["root"]
    if name in FAST:
        ours.update(fast_metrics(P, truth, fps, seq))
    if truth["hold"] is not None:
        ours.update(chest_metrics(m, truth, F))
    return {"clip": name, "source": " ".join(map(str, CLIPS[name])), "frames": F, "fps": round(fps, 2),
            "camera": "panning to follow" if pan else "still",
            "truth_hips_rise_m": round(float(np.percentile(Tr[:, 1], 95) - np.median(Tr[:, 1])), 3),
            "truth_travel_m": round(float(np.linalg.norm(np.diff(Tr[:, [0, 2]], axis=0), axis=-1).sum()), 2),
            "anima": ours, "raw_holistic": base, "render_and_capture_s": round(t1 - t0, 1),
            "ground": m["report"].get("ground")}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "roundtrip_body.json"))
    ap.add_argument("--clips", nargs="*", default=list(CLIPS), choices=list(CLIPS))
    ap.add_argument("--cache", default=None, help="keep the rendered videos and their captures here (and reuse them)")
    a = ap.parse_args()
    if shutil.which("blender") is None:
        sys.exit("benchmarks/roundtrip_body.py renders with Blender: ./dev setup installs it")
    rows = []
    for name in a.clips:
        for pan in (False, True) if name == "walking" else (False,):
            with tempfile.TemporaryDirectory(prefix="anima-roundtrip-") as tmp:
                r = run_case(name, pan, Path(tmp), Path(a.cache) if a.cache else None)
            rows.append(r)
            print(json.dumps(r), flush=True)
    write_json(a.out, {"rows": rows, "protocol": "benchmarks/roundtrip_body.py docstring",
                       "machine": "2 cores, no GPU"})  # fmt: skip


if __name__ == "__main__":
    main()
