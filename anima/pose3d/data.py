"""Data for the lifter (read ``pose3d/MANIFEST.md`` in the shared data for the sources).

* 3D-labelled training: Human3.6M mocap of S1, S5, S6, S7, S8 (10 fps, 17 joints, world mm) moved into each
  of the subject's 4 real cameras and projected with their radial/tangential distortion
  (:func:`project_h36m`). Detector-like noise is added at batch time (:mod:`anima.pose3d.train`).
  S9 and S11 are never used for training (:data:`TRAIN_SUBJECTS`, checked).
* 2D-only (weak) training: MediaPipe Pose detections on the in-the-wild videos of the shared data
  (:func:`wild_evidence`), cached as npz.
* Tests: the real S9 "Posing 1" images (MediaPipe on the images, ground truth from
  ``derived/h36m_S9_Posing1_c2f_images_gt.npz``) and HumanEva-I validation (ground-truth 2D as input: no
  HumanEva images are available).

All 2D evidence goes through :func:`normalise_2d`: pelvis-centred, divided by the torso height, so that the
same network reads studio projections, MediaPipe pixels and HumanEva pixels.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from anima.io.assets import asset
from anima.io.atomic import write_npz
from anima.io.safe_npz import load_object_member
from anima.io.video import iter_frames, probe_video
from anima.pose3d.joints import BONES, K, humaneva_to_h36m, mediapipe_to_h36m
from anima.track import get

TRAIN_SUBJECTS = ("S1", "S5", "S6", "S7", "S8")
TEST_SUBJECTS = ("S9", "S11")
H36M_MOCAP = "pose3d/derived/h36m_3d17_world_mm_10fps_allsubjects.npz"
H36M_S9_IMAGES = "pose3d/c2f3d_pose/data/h36m-sample/images"
H36M_S9_GT = "pose3d/derived/h36m_S9_Posing1_c2f_images_gt.npz"
HUMANEVA_3D = "pose3d/VideoPose3D-Gerrystev/data/data_3d_humaneva15.npz"
HUMANEVA_2D = "pose3d/VideoPose3D-Gerrystev/data/data_2d_humaneva15.npz"
HUMANEVA_CAMS = "pose3d/derived/humaneva15_dlt_cameras.npz"
WILD_VIDEOS = ("gesture-video", "talking-heads-misc", "liveportrait-examples/assets/examples/source")


# ----------------------------------------------------------------------------------------------- maths
def world_to_camera(X: np.ndarray, R: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Human3.6M convention (derived npz): ``Xc = R @ (Xw - T)``."""
    return (X - T) @ R.T


def project_h36m(Xc: np.ndarray, f, c, k, p) -> np.ndarray:
    """Pinhole projection with the 3d-pose-baseline radial (k1..k3) and tangential (p1, p2) model."""
    xy = Xc[..., :2] / Xc[..., 2:3]
    r2 = (xy**2).sum(-1, keepdims=True)
    radial = 1 + k[0] * r2 + k[1] * r2**2 + k[2] * r2**3
    tan = p[0] * xy[..., 1:2] + p[1] * xy[..., 0:1]
    xy_d = xy * (radial + 2 * tan) + np.asarray([p[1], p[0]]) * r2
    return xy_d * np.asarray(f) + np.asarray(c)


def normalise_2d(uv: np.ndarray, conf: np.ndarray | None = None):
    """Pixels ``(..., 17, 2)`` -> pelvis-centred, torso-height units, and the scale used (pixels per unit).
    Torso height: mean 2D length of pelvis-thorax, l_hip-l_shoulder, r_hip-r_shoulder (visible in both
    full-body and upper-body framing)."""
    root = uv[..., 0:1, :]
    t = (
        np.linalg.norm(uv[..., 8, :] - uv[..., 0, :], axis=-1)
        + np.linalg.norm(uv[..., 11, :] - uv[..., 4, :], axis=-1)
        + np.linalg.norm(uv[..., 14, :] - uv[..., 1, :], axis=-1)
    ) / 3
    t = np.maximum(t, 1e-6)[..., None, None]
    return (uv - root) / t, t[..., 0, 0]


# ------------------------------------------------------------------------------------------- Human3.6M
@dataclass
class H36MSet:
    joints_cam: np.ndarray  # (N, 17, 3) camera mm
    uv: np.ndarray  # (N, 17, 2) pixels (with lens distortion)
    subject: np.ndarray  # (N,) str
    camera: np.ndarray  # (N,) str


def load_h36m(subjects=TRAIN_SUBJECTS, every: int = 1) -> H36MSet:
    """Every mocap pose of ``subjects`` seen from each of their 4 cameras."""
    d = np.load(asset(H36M_MOCAP))
    J = d["joints17_world_mm"].astype(np.float64)
    names = d["seq_name"]
    starts, lens = d["seq_start"], d["seq_len"]
    out_J, out_uv, out_s, out_c = [], [], [], []
    for s in subjects:
        idx = np.concatenate(
            [np.arange(st, st + n)[::every] for nm, st, n in zip(names, starts, lens) if nm.split("/")[0] == s]
        )
        for ci in np.flatnonzero(d["cam_subject"] == s):
            Xc = world_to_camera(J[idx], d["cam_R"][ci], d["cam_T_mm"][ci])
            out_J.append(Xc)
            out_uv.append(project_h36m(Xc, d["cam_f"][ci], d["cam_c"][ci], d["cam_k"][ci], d["cam_p"][ci]))
            out_s.append(np.full(len(idx), s))
            out_c.append(np.full(len(idx), d["cam_name"][ci]))
    return H36MSet(
        np.concatenate(out_J).astype(np.float32),
        np.concatenate(out_uv).astype(np.float32),
        np.concatenate(out_s),
        np.concatenate(out_c),
    )


def subject_bone_lengths(subjects=TRAIN_SUBJECTS) -> dict[str, np.ndarray]:
    """Per training subject, median length (mm) of each of the 16 H36M bones (for eq. 3.6)."""
    d = np.load(asset(H36M_MOCAP))
    J = d["joints17_world_mm"]
    out = {}
    for s in subjects:
        idx = np.concatenate(
            [
                np.arange(st, st + n)
                for nm, st, n in zip(d["seq_name"], d["seq_start"], d["seq_len"])
                if nm.split("/")[0] == s
            ]
        )
        out[s] = np.median(np.linalg.norm(J[idx][:, BONES[:, 0]] - J[idx][:, BONES[:, 1]], axis=-1), 0)
    return out


# ----------------------------------------------------------------------------------- MediaPipe evidence
class PoseDetector:
    """The tracker's pose model (:mod:`anima.track`). Returns pixel landmarks ``(33, 2)``, visibility ``(33,)``
    and world landmarks ``(33, 3)`` in metres (MediaPipe axes), or None."""

    def __init__(self, static_image_mode: bool = True, model_complexity: int = 1):
        if model_complexity != 1:
            raise ValueError("the tracker's pose model runs at model_complexity 1")
        self._p = get().pose(static=static_image_mode)

    def __call__(self, rgb: np.ndarray):
        h, w = rgb.shape[:2]
        r = self._p(rgb)
        if r is None:
            return None
        uv = (r.image[:, :2].astype(np.float64) * [w, h]).astype(np.float32)
        return uv, r.image[:, 3].copy(), r.world[:, :3].copy()

    def close(self):
        self._p.close()


def _cache_file(cache: Path, name: str, key: str) -> Path:
    return Path(cache) / f"{name}-{hashlib.sha1(key.encode()).hexdigest()[:10]}.npz"


def s9_image_evidence(cache: Path, progress: bool = False) -> dict[str, np.ndarray]:
    """MediaPipe on every staged S9 image, with the ground truth of each: uv/conf (17), MediaPipe world
    joints (17, mm, camera-aligned axes), gt camera-frame joints (mm) and gt 2D. Cached."""
    folder = asset(H36M_S9_IMAGES)
    files = sorted(p for p in folder.glob("*.jpg") if p.stat().st_size > 0)
    f = _cache_file(cache, "s9_mediapipe", "|".join(p.name for p in files) + "|complexity1")
    if f.exists():
        return dict(np.load(f))
    gt = np.load(asset(H36M_S9_GT))
    index = {n: i for i, n in enumerate(gt["imgname"])}
    det = PoseDetector(True, 1)
    rows = {k: [] for k in ("uv", "conf", "world", "gt3d", "gt2d", "found", "camera")}
    for p in tqdm(files, desc="MediaPipe on S9 images", disable=not progress, unit="img"):
        i = index[p.name]
        r = det(cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB))
        found = r is not None
        if found:
            uv, conf = mediapipe_to_h36m(r[0].astype(np.float64), r[1].astype(np.float64))
            world = mediapipe_to_h36m(r[2].astype(np.float64)) * 1000.0
        else:
            uv, conf, world = np.zeros((K, 2)), np.zeros(K), np.zeros((K, 3))
        for k, v in (
            ("uv", uv),
            ("conf", conf),
            ("world", world),
            ("gt3d", gt["joints17_cam_mm"][i]),
            ("gt2d", gt["joints17_2d_px"][i]),
            ("found", found),
            ("camera", gt["camera"][i]),
        ):
            rows[k].append(v)
    det.close()
    out = {k: np.stack(v) if k != "camera" else np.array(v) for k, v in rows.items()}
    write_npz(f, **out)
    return out


def humaneva_validation() -> dict[str, np.ndarray]:
    """HumanEva-I validation chunks, all subjects and colour cameras: ground-truth 2D (mapped to H36M-17,
    nose masked) and camera-frame 3D (mm) from the DLT cameras (decomposed with OpenCV)."""
    d3 = load_object_member(asset(HUMANEVA_3D), "positions_3d")
    d2 = load_object_member(asset(HUMANEVA_2D), "positions_2d")
    cams = np.load(asset(HUMANEVA_CAMS))
    Ps = {k: P for k, P in zip(cams["key"], cams["P_world_m_to_px"])}
    uv_all, conf_all, gt_all, act = [], [], [], []
    for subj_key, actions in d3.items():
        if not subj_key.startswith("Validate/"):
            continue
        subj = subj_key.split("/")[1]
        for a, X in actions.items():
            for ci, uv in enumerate(d2[subj_key][a]):
                key = f"{subj}/C{ci + 1}"
                if key not in Ps:
                    continue
                Kc, Rc, C = cv2.decomposeProjectionMatrix(Ps[key])[:3]
                C = (C[:3] / C[3]).ravel()
                Rc = np.sign(np.diag(Kc))[:, None] * Rc  # positive focal lengths: image x right, y down
                if np.linalg.det(Rc) < 0:  # P is defined up to a (possibly negative) scale
                    Rc = -Rc
                Xc = (X.astype(np.float64) - C) @ Rc.T * 1000.0
                u, c = humaneva_to_h36m(uv.astype(np.float64))
                g, _ = humaneva_to_h36m(Xc)
                ok = np.isfinite(u).all((1, 2)) & np.isfinite(g).all((1, 2))
                uv_all.append(u[ok][::3])
                conf_all.append(c[ok][::3])
                gt_all.append(g[ok][::3])
                act += [a.split(" ")[0]] * int(ok[::3].sum())
    return {
        "uv": np.concatenate(uv_all),
        "conf": np.concatenate(conf_all),
        "gt3d": np.concatenate(gt_all),
        "action": np.array(act),
    }


def wild_evidence(
    cache: Path, every: int = 2, max_frames_per_video: int = 600, progress: bool = False
) -> dict[str, np.ndarray]:
    """2D-only training data: MediaPipe Pose (video mode) on the in-the-wild videos of the shared data, every
    ``every``-th frame. Frames with no person are skipped. Cached."""
    videos = sorted(p for root in WILD_VIDEOS for p in asset(root).rglob("*.mp4"))
    f = _cache_file(cache, "wild_mediapipe", "|".join(str(v.name) for v in videos) + f"|{every}|{max_frames_per_video}")
    if f.exists():
        return dict(np.load(f))
    uv_all, conf_all, vid = [], [], []
    for vi, v in enumerate(tqdm(videos, desc="MediaPipe on in-the-wild videos", disable=not progress, unit="video")):
        det = PoseDetector(False, 1)
        try:
            for i, rgb in enumerate(iter_frames(probe_video(v))):
                if i >= max_frames_per_video:
                    break
                r = det(rgb)
                if r is None or i % every:
                    continue
                uv, conf = mediapipe_to_h36m(r[0].astype(np.float64), r[1].astype(np.float64))
                uv_all.append(uv)
                conf_all.append(conf)
                vid.append(vi)
        finally:
            det.close()
    out = {
        "uv": np.asarray(uv_all, np.float32),
        "conf": np.asarray(conf_all, np.float32),
        "video": np.asarray(vid),
        "videos": np.array([str(v.relative_to(asset("."))) for v in videos]),
    }
    write_npz(f, **out)
    return out
