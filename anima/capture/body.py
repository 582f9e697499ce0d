"""Body and hands: assemble the 55-joint skeleton from MediaPipe Holistic, then clean it (seed 004 §4.3.1-4.3.2).

Assembly, per frame: body joints from Pose *world* landmarks (metres, hip-centred; converted to anima's
axes), made pelvis-relative. Hands come from the hand landmarks in image space (pixels, depth in x units),
scaled to metres by the frame's metres-per-pixel factor (visibility-weighted image-plane extent of the
upper-body landmarks in world vs image coordinates) and attached at the body's wrists.

Cleaning (:func:`clean`): confidence filter (joints below ``min_conf`` are dropped), cubic interpolation of
short drop-outs (``max_gap`` frames; hands are interpolated in wrist-relative coordinates so they stay
attached), longer gaps left missing and flagged, per-frame hand scale stabilisation (each hand brought to
the clip's median hand size: the per-frame metres-per-pixel estimate jitters), zero-phase Gaussian
smoothing (sigma 1.5 frames), optional
resampling (e.g. to 15 fps for gesture work) and optional fixed bone lengths per clip (median length of
each bone, re-imposed along each bone's direction from the root outwards).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from anima.core.filters import gaussian_smooth, resample_joints, valid_runs
from anima.core.skeleton import (
    BODY_JOINTS,
    LEFT_HAND,
    LEG_JOINTS,
    MP_LEGS,
    MP_POSE,
    N_JOINTS,
    RIGHT_HAND,
    bone_lengths,
    fix_bone_lengths,
)

_UPPER = [0, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24]


@dataclass
class BodyTrack:
    joints: np.ndarray  # (F, 55, 3) metres, pelvis-relative, NaN where missing
    conf: np.ndarray  # (F, 55) in [0, 1]
    fps: float
    interpolated: np.ndarray = field(default=None)  # (F, 55) bool: filled by interpolation
    image: np.ndarray = field(default=None)  # (F, 55, 2) pixel positions of the tracked joints (raw)
    legs: np.ndarray = field(default=None)  # (F, 8, 3) metres, pelvis-relative (LEG_JOINTS), NaN where missing
    leg_conf: np.ndarray = field(default=None)  # (F, 8) pose visibility of the leg joints
    leg_image: np.ndarray = field(default=None)  # (F, 8, 2) pixel positions of the leg joints (raw)
    camera_step: np.ndarray = field(default=None)  # (F, 3) the background's shift (px) and log scale per frame

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.joints).all(-1)


def _to_anima(p: np.ndarray) -> np.ndarray:
    """MediaPipe axes (x right, y down, z away) -> anima (x right, y up, z towards the camera)."""
    return p * np.array([1.0, -1.0, -1.0])


def _body_points(g: dict) -> dict:
    """The rig's trunk joints from MediaPipe's named pose landmarks ``g`` (pixels or metres alike): the pelvis
    between the hips, the neck between the shoulders, the spine halfway between them, the head between the
    ears; the hips and the nose as they are."""
    pelvis = (g["left_hip"] + g["right_hip"]) / 2
    neck = (g["left_shoulder"] + g["right_shoulder"]) / 2
    return {
        "pelvis": pelvis,
        "left_hip": g["left_hip"],
        "right_hip": g["right_hip"],
        "spine": (pelvis + neck) / 2,
        "neck": neck,
        "head": (g["left_ear"] + g["right_ear"]) / 2,
        "nose": g["nose"],
    }


def _image_joints(pose: np.ndarray, left, right, width: int, height: int) -> np.ndarray:
    """Pixel positions ``[55, 2]`` of the joints (same construction as the 3D joints)."""
    uv = np.full((N_JOINTS, 2), np.nan)
    px = pose[:, :2].astype(np.float64) * [width, height]
    g = {k: px[i] for k, i in MP_POSE.items()}
    pos = _body_points(g)
    for i, n in enumerate(BODY_JOINTS):
        uv[i] = pos.get(n, g.get(n))
    for hand, sl in ((left, LEFT_HAND), (right, RIGHT_HAND)):
        if hand is not None:
            uv[sl] = hand[:, :2].astype(np.float64) * [width, height]
    return uv


def assemble_frame(
    pose: np.ndarray | None,
    pose_world: np.ndarray | None,
    left: np.ndarray | None,
    right: np.ndarray | None,
    width: int,
    height: int,
):
    """One frame -> (joints ``[55, 3]`` metres pelvis-relative, confidence ``[55]``, pixels ``[55, 2]``)."""
    J = np.full((N_JOINTS, 3), np.nan)
    C = np.zeros(N_JOINTS)
    if pose_world is None or pose is None:
        return J, C, np.full((N_JOINTS, 2), np.nan)
    W = _to_anima(pose_world[:, :3].astype(np.float64))
    vis = pose_world[:, 3].astype(np.float64)
    g = {k: W[i] for k, i in MP_POSE.items()}
    v = {k: vis[i] for k, i in MP_POSE.items()}
    pos = _body_points(g)
    cf = {
        "pelvis": min(v["left_hip"], v["right_hip"]),
        "left_hip": v["left_hip"],
        "right_hip": v["right_hip"],
        "neck": min(v["left_shoulder"], v["right_shoulder"]),
        "head": min(v["left_ear"], v["right_ear"]),
        "nose": v["nose"],
    }
    cf["spine"] = cf["neck"]  # the pelvis is the origin by construction; the spine hangs off the neck
    for side in ("left", "right"):
        for part in ("shoulder", "elbow", "wrist"):
            pos[f"{side}_{part}"] = g[f"{side}_{part}"]
            cf[f"{side}_{part}"] = v[f"{side}_{part}"]
    for i, n in enumerate(BODY_JOINTS):
        J[i] = pos[n] - pos["pelvis"]
        C[i] = cf[n]
    # metres per pixel: image-plane extent of the upper-body landmarks in the world vs in the image
    # (MediaPipe's image-space depth is too noisy to enter the scale; world axes are camera-aligned)
    img = np.stack([pose[:, 0] * width, -pose[:, 1] * height], -1).astype(np.float64)[_UPPER]
    wrl = W[_UPPER, :2]
    wv = np.maximum(vis[_UPPER], 1e-3)[:, None]
    ci, cw = (img * wv).sum(0) / wv.sum(), (wrl * wv).sum(0) / wv.sum()
    s = np.sqrt((wv * (wrl - cw) ** 2).sum() / max((wv * (img - ci) ** 2).sum(), 1e-12))
    for hand, sl, wrist in (
        (left, LEFT_HAND, BODY_JOINTS.index("left_wrist")),
        (right, RIGHT_HAND, BODY_JOINTS.index("right_wrist")),
    ):
        if hand is None:
            continue
        h = np.stack([hand[:, 0] * width, -hand[:, 1] * height, -hand[:, 2] * width], -1).astype(np.float64)
        J[sl] = s * (h - h[0]) + J[wrist]
        C[sl] = 1.0
    return J, C, _image_joints(pose, left, right, width, height)


def assemble_legs(pose_world: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """One frame's legs: (joints ``[8, 3]`` metres pelvis-relative in LEG_JOINTS order, visibility ``[8]``)."""
    if pose_world is None:
        return np.full((len(LEG_JOINTS), 3), np.nan), np.zeros(len(LEG_JOINTS))
    W = _to_anima(pose_world[:, :3].astype(np.float64))
    pelvis = (W[MP_POSE["left_hip"]] + W[MP_POSE["right_hip"]]) / 2
    idx = list(MP_LEGS)
    return W[idx] - pelvis, pose_world[idx, 3].astype(np.float64)


def leg_pixels(pose: np.ndarray | None, width: int, height: int) -> np.ndarray:
    """The leg joints' pixel positions ``[8, 2]`` (LEG_JOINTS order; NaN without a pose)."""
    if pose is None:
        return np.full((len(LEG_JOINTS), 2), np.nan)
    return pose[list(MP_LEGS), :2].astype(np.float64) * [width, height]


def assemble(frames, width: int, height: int, fps: float) -> BodyTrack:
    out = [assemble_frame(f.pose, f.pose_world, f.left_hand, f.right_hand, width, height) for f in frames]
    legs = [assemble_legs(f.pose_world if f.pose is not None else None) for f in frames]
    leg_px = np.stack([leg_pixels(f.pose, width, height) for f in frames]) if frames else np.zeros((0, 8, 2))
    steps = [getattr(f, "camera_step", None) for f in frames]
    cam = np.stack([np.zeros(3) if s is None else s for s in steps]) if frames else np.zeros((0, 3))
    J = np.stack([o[0] for o in out]) if out else np.zeros((0, N_JOINTS, 3))
    C = np.stack([o[1] for o in out]) if out else np.zeros((0, N_JOINTS))
    UV = np.stack([o[2] for o in out]) if out else np.zeros((0, N_JOINTS, 2))
    LJ = np.stack([g[0] for g in legs]) if legs else np.zeros((0, len(LEG_JOINTS), 3))
    LC = np.stack([g[1] for g in legs]) if legs else np.zeros((0, len(LEG_JOINTS)))
    return BodyTrack(J, C, fps, np.zeros(C.shape, bool), UV, LJ, LC, leg_px, cam)


def _interp_gaps(x: np.ndarray, max_gap: int) -> tuple[np.ndarray, np.ndarray]:
    """Cubic interpolation over NaN gaps of at most ``max_gap`` frames, per column of ``x [F, D]``
    (a gap at the clip's ends is not interpolated). Returns (filled, filled-mask [F])."""
    F = len(x)
    ok = np.isfinite(x).all(1)
    filled = np.zeros(F, bool)
    if ok.sum() < 4 or ok.all():
        return x, filled
    idx = np.flatnonzero(ok)
    cs = CubicSpline(idx, x[idx], axis=0)
    for a, b in valid_runs(~ok):
        if a == 0 or b == F or b - a > max_gap:
            continue
        x[a:b] = cs(np.arange(a, b))
        filled[a:b] = True
    return x, filled


def clean(
    track: BodyTrack,
    min_conf: float = 0.5,
    max_gap: int = 8,
    sigma: float = 1.5,
    fixed_bones: bool = False,
    resample_fps: float | None = None,
) -> BodyTrack:
    J = track.joints.copy()
    drop = track.conf < min_conf
    drop[:, 0] = False  # the pelvis is the origin by construction (its visibility only tells about the hips)
    J[drop] = np.nan
    interp = np.zeros(track.conf.shape, bool)
    # body joints: each joint on its own
    for j in range(13):
        J[:, j], interp[:, j] = _interp_gaps(J[:, j], max_gap)
    # hands: wrist-relative shape, re-attached to the (interpolated) body wrist; where the body wrist was
    # dropped as unsure but the hand was seen, the hand keeps its own wrist (where the detector put it)
    for sl, wrist in ((LEFT_HAND, BODY_JOINTS.index("left_wrist")), (RIGHT_HAND, BODY_JOINTS.index("right_wrist"))):
        rel = (J[:, sl] - J[:, sl][:, :1]).reshape(len(J), -1)
        rel, f = _interp_gaps(rel, max_gap)
        anchor = J[:, wrist].copy()
        own = ~np.isfinite(anchor).all(-1) & np.isfinite(track.joints[:, sl][:, 0]).all(-1)
        anchor[own] = track.joints[own, sl.start]
        J[:, sl] = rel.reshape(len(J), -1, 3) + anchor[:, None]
        interp[:, sl] = f[:, None] & np.isfinite(J[:, sl]).all(-1)
    # interpolated frames get the clip's median bone lengths (a spline per coordinate does not keep them)
    if interp.any():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(bone_lengths(np.where(interp[..., None], np.nan, J)), axis=0)
        rows = interp.any(1)
        fixed = fix_bone_lengths(J[rows], np.nan_to_num(med))
        J[rows] = np.where(interp[rows][..., None], fixed, J[rows])
    # hand scale: the per-frame metres-per-pixel estimate jitters; bring each frame's hand to the clip's
    # median hand size (median ratio of its bone lengths to their clip medians), keeping its shape
    for sl in (LEFT_HAND, RIGHT_HAND):
        L = bone_lengths(J)[:, sl][:, 1:]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # frames / clips without this hand
            med = np.nanmedian(L, 0)
            ratio = np.nanmedian(L / med, 1) if np.isfinite(med).all() and (med > 0).all() else None
        if ratio is not None:
            ok = np.isfinite(ratio) & (ratio > 0)
            own_wrist = J[ok][:, sl][:, :1]  # the body wrist, or the hand's own where that was unsure
            J[np.flatnonzero(ok)[:, None], np.arange(sl.start, sl.stop)[None]] = (J[ok][:, sl] - own_wrist) / ratio[ok][
                :, None, None
            ] + own_wrist
    if sigma > 0:
        # hands are smoothed wrist-relative and re-attached, so they stay on the (smoothed) body wrists (or on
        # their own smoothed wrist where the body wrist was unsure)
        own = {"L": J[:, LEFT_HAND.start].copy(), "R": J[:, RIGHT_HAND.start].copy()}
        rel = {"L": J[:, LEFT_HAND] - J[:, LEFT_HAND][:, :1], "R": J[:, RIGHT_HAND] - J[:, RIGHT_HAND][:, :1]}
        for j in range(N_JOINTS):
            src = J[:, j] if j < 13 else (rel["L"][:, j - 13] if j < 34 else rel["R"][:, j - 34])
            ok = np.isfinite(src).all(-1)
            sm = np.where(ok[:, None], gaussian_smooth(np.nan_to_num(src), sigma, ok), np.nan)
            if j < 13:
                J[:, j] = sm
            elif j < 34:
                rel["L"][:, j - 13] = sm
            else:
                rel["R"][:, j - 34] = sm
        for key, sl, wrist in (("L", LEFT_HAND, "left_wrist"), ("R", RIGHT_HAND, "right_wrist")):
            anchor = J[:, BODY_JOINTS.index(wrist)].copy()
            ok = np.isfinite(own[key]).all(-1)
            own_sm = np.where(ok[:, None], gaussian_smooth(np.nan_to_num(own[key]), sigma, ok), np.nan)
            lost = ~np.isfinite(anchor).all(-1)
            anchor[lost] = own_sm[lost]
            J[:, sl] = rel[key] + anchor[:, None]
    fps = track.fps
    conf = np.where(np.isfinite(J).all(-1), np.maximum(track.conf, interp * min_conf), 0.0)
    if resample_fps and abs(resample_fps - fps) > 1e-6:
        J, conf, interp = resample_joints(J, conf, interp, fps, resample_fps)
        fps = resample_fps
    if fixed_bones:
        J = fix_bone_lengths(J)
    legs, leg_conf = (None, None)
    if track.legs is not None:
        legs, leg_conf = clean_legs(track.legs, track.leg_conf, track.fps, min_conf, max_gap, sigma, resample_fps)
    return BodyTrack(J, conf, fps, interp, legs=legs, leg_conf=leg_conf)


def clean_legs(legs, conf, fps: float, min_conf=0.5, max_gap=8, sigma=1.5, resample_fps=None):
    """The legs' track cleaned by the body's rules: joints under ``min_conf`` dropped, short drop-outs
    interpolated, zero-phase smoothing, optional resampling. Returns (legs ``[F, 8, 3]``, confidence ``[F, 8]``)."""
    L = np.where((conf >= min_conf)[..., None], legs, np.nan)
    interp = np.zeros(conf.shape, bool)
    for j in range(L.shape[1]):
        L[:, j], interp[:, j] = _interp_gaps(L[:, j], max_gap)
        ok = np.isfinite(L[:, j]).all(-1)
        if sigma > 0 and ok.any():
            L[:, j] = np.where(ok[:, None], gaussian_smooth(np.nan_to_num(L[:, j]), sigma, ok), np.nan)
    C = np.where(np.isfinite(L).all(-1), np.maximum(conf, interp * min_conf), 0.0)
    if resample_fps and abs(resample_fps - fps) > 1e-6:
        L, C, _ = resample_joints(L, C, interp, fps, resample_fps)
    return L, C


def bone_length_cv(J: np.ndarray) -> float:
    """Mean over bones (non-zero length) of the coefficient of variation of the bone length over frames."""
    L = bone_lengths(J)[:, 1:]
    m = np.nanmean(L, 0)
    keep = m > 5e-3  # hand wrists sit on the body wrists (zero-length bones)
    return float(np.nanmean(np.nanstd(L[:, keep], 0) / m[keep]))
