"""The character in the world: a floor, a root that moves in three dimensions, feet that plant. Pure functions.

A monocular tracker's 3D skeleton is centred on the pelvis (MediaPipe's world landmarks are), so where the
person is, how high the hips are and whether a foot is down must come from the picture. Everything here is in
the character's world: metres, +y up with the floor at y = 0, +x the picture's right (the person's left when
they face the camera), +z towards the camera.

* **The picture's scale** (:func:`metres_per_pixel`): per frame, the pixels per metre of the least
  foreshortened of the body's segments (shoulders, hips, torso, upper arms, forearms, thighs, shins: each
  segment's picture length over its clip-median 3D length; the second largest, so one mis-tracked joint does
  not decide), smoothed over a quarter second.
* **The camera** (``Picture.camera``): the background's shift in the picture, summed over frames
  (``anima.capture.camera_motion``), is taken out of every picture position: a panning or tilting camera does
  not move the character.
* **Depth** from the person's apparent size under the clip's camera: distance ``d = f * metres_per_pixel``
  with an assumed focal length :data:`FOCAL` (in units of the picture's long side: a 55 degree field of view
  across it, a phone's main camera in video); the root's z is the distance's change, smoothed over
  :data:`DEPTH_SIGMA_S`.
* **Sideways** as the picture shows it: the shoulders' midpoint's column, through the same camera.
* **The floor** (:func:`floor_rows`): the ground plane's row under the person, a line in their pixels per
  metre whose slope is the camera's height, fitted to the lower foot's rows; what it leaves is taken from the
  nearby frames' lowest foot (a foot was down then).
* **Height**: where the picture shows the hips and the feet, the hips stand as high above the floor's row
  as the picture shows them, in the
  character's scale (:func:`hips_in_picture`: the tracker's legs are too straight in a crouch and a jump's
  flight is only in the picture); elsewhere as high as the character's own legs reach with the lowest point
  of a sole on the floor, lifted by the feet's height above the floor's row when both are off it (a flight).
* **Contacts** (:func:`foot_contacts`), per foot: its lowest point within :data:`CONTACT_M` of the lower
  foot's (the stance foot is the lower one; both, in double support) and the lower foot within
  :data:`FLIGHT_M` of the floor's row (not in flight), moving less than :data:`CONTACT_SPEED` (metres per
  second in the picture, its track smoothed over :data:`FOOT_SIGMA_FRAMES`), for at least three frames
  (two-frame gaps closed).
* **Locking** (:func:`lock_feet`): a planted foot stays where it landed: its ankle held at the landing point
  by a two-bone leg IK (hip, knee, ankle: :func:`anima.core.kinematics.two_bone`; the knee keeps the plane
  the tracked leg bent in), blended in and out over :data:`LOCK_BLEND_S`; a foot never goes under the floor
  (the root rises instead).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anima.core.contract import JOINT_NAMES, LEG_JOINTS
from anima.core.filters import gaussian_smooth

FOCAL = 0.96
"""The assumed focal length, in units of the picture's long side (a 55 degree field of view across it)."""
DEPTH_SIGMA_S = 0.3
SIDE_SIGMA_S = 0.1
SCALE_SIGMA_S = 0.25
FLOOR_WINDOW_S = 0.6
"""The floor's row at a frame: the ground plane's row at the person's distance, corrected by the lowest foot row
(the plane taken out) within this many seconds either side (a foot was down)."""
FLOOR_QUANTILE = 0.75
"""The ground plane's line is fitted to this quantile of the lower foot's rows (the lower foot is down in most
frames; a jump's flight and a mis-tracked foot are the rest)."""
CAMERA_HEIGHT_M = (0.2, 4.0)
"""The camera heights above the floor the ground plane may have; outside them, or when the person's distance
hardly changes, the floor's row is the clip's own (no plane)."""
AIR_DEADBAND_M = 0.03
"""Feet less than this above the floor's row count as on it (the picture's noise)."""
CONTACT_M = 0.04
"""A foot within this of the lower foot (in the picture, metres) may be down."""
FLIGHT_M = 0.10
"""Both feet this far above the floor's row: in the air, no contact."""
CONTACT_SPEED = 0.35
FOOT_SIGMA_FRAMES = 1.5
LOCK_BLEND_S = 0.12
REPLANT_M = 0.18
"""A standing foot (legs not seen) re-plants when the hips have carried it this far from where it stands."""
MIN_CONF = 0.5
HIPS_SIGMA_FRAMES = 1.0

_J = {n: i for i, n in enumerate(JOINT_NAMES)}
_L = {n: i for i, n in enumerate(LEG_JOINTS)}
_BODY_SEGMENTS = (("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"), ("neck", "pelvis"),
                  ("left_shoulder", "left_elbow"), ("left_elbow", "left_wrist"),
                  ("right_shoulder", "right_elbow"), ("right_elbow", "right_wrist"))  # fmt: skip
_LEG_SEGMENTS = (("left_knee", "left_ankle"), ("right_knee", "right_ankle"))
_FOOT_POINTS = {"left": ("left_ankle", "left_heel", "left_foot_index"),
                "right": ("right_ankle", "right_heel", "right_foot_index")}  # fmt: skip


@dataclass
class Picture:
    """The 2D evidence of a clip: the picture's size, the joints' pixel positions (``body [F, 55, 2]``, ``legs
    [F, 8, 2]`` or None), their 3D positions (pelvis-relative metres) and the legs' visibility, the
    background's cumulative shift ``camera [F, 2]`` (pixels; zeros for a still camera). The background's
    scale (``camera_step``'s third column) is not used: a similarity fitted to a pan's background takes its
    perspective for a zoom (4 % over a 14-degree pan in the round trip), which would read as the person
    walking away."""

    width: int
    height: int
    body: np.ndarray
    body3d: np.ndarray
    legs: np.ndarray | None = None
    legs3d: np.ndarray | None = None
    leg_conf: np.ndarray | None = None
    camera: np.ndarray | None = None

    def __post_init__(self):
        if self.camera is None:
            self.camera = np.zeros((len(self.body), 2))

    @property
    def n(self) -> int:
        return len(self.body)

    def stable(self, px: np.ndarray) -> np.ndarray:
        """Pixel positions ``[F, ..., 2]`` with the camera's motion taken out."""
        return px - self.camera.reshape((self.n,) + (1,) * (px.ndim - 2) + (2,))

    def leg_px(self) -> np.ndarray | None:
        """The legs' pixel positions, NaN where not seen (visibility under :data:`MIN_CONF`), camera taken out."""
        if self.legs is None:
            return None
        px = np.array(self.legs, np.float64)
        if self.leg_conf is not None:
            px[self.leg_conf < MIN_CONF] = np.nan
        return self.stable(px)


def _fill(x: np.ndarray) -> np.ndarray:
    """NaN frames of ``x [F]`` interpolated from their neighbours (held at the ends); zeros when none is set."""
    ok = np.isfinite(x)
    if not ok.any():
        return np.zeros_like(x)
    return np.interp(np.arange(len(x)), np.flatnonzero(ok), x[ok])


def _smooth(x: np.ndarray, sigma_frames: float) -> np.ndarray:
    return gaussian_smooth(x[:, None], sigma_frames)[:, 0] if sigma_frames > 0 and len(x) > 1 else x


def metres_per_pixel(pic: Picture, fps: float) -> np.ndarray | None:
    """Metres per pixel ``[F]`` at the person (see the module docstring); None without two seen segments."""
    ratios = []
    for a, b in _BODY_SEGMENTS:
        l3 = np.linalg.norm(pic.body3d[:, _J[a]] - pic.body3d[:, _J[b]], axis=-1)
        l2 = np.where(np.isfinite(l3), np.linalg.norm(pic.body[:, _J[a]] - pic.body[:, _J[b]], axis=-1), np.nan)
        ratios.append(l2 / np.nanmedian(l3) if np.isfinite(l3).any() else np.full(pic.n, np.nan))
    if pic.legs is not None and pic.legs3d is not None:
        legs = pic.leg_px()
        for a, b in _LEG_SEGMENTS:
            l3 = np.linalg.norm(pic.legs3d[:, _L[a]] - pic.legs3d[:, _L[b]], axis=-1)
            l2 = np.where(np.isfinite(l3), np.linalg.norm(legs[:, _L[a]] - legs[:, _L[b]], axis=-1), np.nan)
            ratios.append(l2 / np.nanmedian(l3) if np.isfinite(l3).any() else np.full(pic.n, np.nan))
    R = np.stack(ratios, 1)
    R[~np.isfinite(R) | (R <= 0)] = np.nan
    n_ok = np.isfinite(R).sum(1)
    S = np.sort(np.where(np.isfinite(R), R, -np.inf), 1)
    ppm = np.where(n_ok >= 3, S[:, -2], np.where(n_ok >= 1, S[:, -1], np.nan))
    ppm[~np.isfinite(ppm) | (ppm <= 0)] = np.nan
    if np.isfinite(ppm).sum() < 1:
        return None
    ppm = _smooth(_fill(ppm), SCALE_SIGMA_S * fps)
    return 1.0 / np.maximum(ppm, 1e-6)


def picture_travel(pic: Picture, mpp: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The person's sideways and depth travel ``x [F]``, ``z [F]`` (metres, relative to their clip medians) in
    the first frame's camera: the shoulders' midpoint through a pinhole camera of focal :data:`FOCAL`, its depth
    from apparent size, its bearing the picture's angle plus the camera's turn (a pan turns the camera: the
    background's cumulative shift over the focal length)."""
    f = FOCAL * max(pic.width, pic.height)
    u = pic.body[:, [_J["left_shoulder"], _J["right_shoulder"]]].mean(1)[:, 0]
    depth = _smooth(f * mpp, DEPTH_SIGMA_S * fps)
    alpha = np.arctan(_fill((u - pic.width / 2) / f))
    turn = -pic.camera[:, 0] / f
    bearing = _smooth(alpha + turn, SIDE_SIGMA_S * fps)
    r = depth / np.cos(alpha)  # along the ray
    X, Z = r * np.sin(bearing), r * np.cos(bearing)
    return X - np.median(X), -(Z - np.median(Z))


def _rolling_max(x: np.ndarray, half: int) -> np.ndarray:
    out = np.full_like(x, np.nan)
    for i in range(len(x)):
        w = x[max(0, i - half) : i + half + 1]
        if np.isfinite(w).any():
            out[i] = np.nanmax(w)
    return out


def foot_rows(pic: Picture) -> np.ndarray | None:
    """Each foot's lowest row in the picture ``[F, 2]`` (left, right; camera taken out; NaN where unseen)."""
    legs = pic.leg_px()
    if legs is None:
        return None
    rows = []
    for side in ("left", "right"):
        v = legs[:, [_L[n] for n in _FOOT_POINTS[side]], 1]
        with np.errstate(all="ignore"):
            rows.append(np.where(np.isfinite(v).any(1), np.nanmax(np.where(np.isfinite(v), v, -np.inf), 1), np.nan))
    return np.stack(rows, 1)


def _quantile_line(x: np.ndarray, y: np.ndarray, q: float, iters: int = 60) -> tuple[float, float]:
    """``a, b`` of the line ``y = a + b x`` under which a share ``q`` of the points lie (quantile regression by
    iteratively reweighted least squares)."""
    x0 = float(np.mean(x))
    A = np.stack([np.ones_like(x), x - x0], 1)
    beta = np.linalg.lstsq(A, y, rcond=None)[0]
    eps = 1e-3 * max(float(np.std(y)), 1e-6)
    for _ in range(iters):
        r = y - A @ beta
        w = np.where(r > 0, q, 1.0 - q) / np.maximum(np.abs(r), eps)
        Aw = A * w[:, None]
        beta = np.linalg.solve(Aw.T @ A + 1e-12 * np.eye(2), Aw.T @ y)
    return float(beta[0] - beta[1] * x0), float(beta[1])


def floor_rows(low: np.ndarray, mpp: np.ndarray, fps: float) -> tuple[np.ndarray, float | None]:
    """The floor's row under the person ``[F]`` (pixels, camera taken out) from the lower foot's lowest row ``low
    [F]`` (NaN where unseen), and the camera's height above the floor (metres) when the plane was used.

    A floor seen by a level pinhole camera puts a point at distance ``d`` at the row ``horizon + f h / d``
    (``h`` the camera's height), and the person's metres per pixel are ``d / f``: the floor's row under them is
    ``horizon + h / mpp``, a line in ``1 / mpp`` whose slope is the camera's height. It is fitted to the lower
    foot's rows (:data:`FLOOR_QUANTILE`); what is left (tilt the camera track missed, a slope) is the nearby
    frames' lowest residual (:data:`FLOOR_WINDOW_S`). A person walking towards or away from the camera no
    longer stands above or below a floor taken from other distances."""
    ok = np.isfinite(low) & np.isfinite(mpp)
    plane = np.zeros(len(low))
    height = None
    if ok.sum() >= 10:
        x = 1.0 / mpp[ok]
        if np.std(x) > 0.03 * np.mean(x):
            a, b = _quantile_line(x, low[ok], FLOOR_QUANTILE)
            if CAMERA_HEIGHT_M[0] <= b <= CAMERA_HEIGHT_M[1]:
                plane = b / mpp
                height = b
    plane = np.where(np.isfinite(plane), plane, 0.0)
    rest = _rolling_max(low - plane, int(round(FLOOR_WINDOW_S * fps)))
    rest[~np.isfinite(rest)] = np.nan
    return plane + _smooth(_fill(rest), 0.1 * fps), height


def feet_in_picture(pic: Picture, mpp: np.ndarray, fps: float) -> dict | None:
    """The feet against the floor in the picture: ``height [F, 2]`` (metres of each foot's lowest point above
    the floor's row), ``speed [F, 2]`` (metres per second in the picture), ``seen [F, 2]``, and ``hips [F]``
    (the hips' height above the floor's row where they are seen, else NaN); None when the feet are never
    seen."""
    rows = foot_rows(pic)
    if rows is None or not np.isfinite(rows).any():
        return None
    legs = pic.leg_px()
    low = np.nanmax(np.where(np.isfinite(rows), rows, -np.inf), 1)
    low[~np.isfinite(low)] = np.nan
    floor, camera_height = floor_rows(low, mpp, fps)
    height = (floor[:, None] - rows) * mpp[:, None]
    speed = np.full((pic.n, 2), np.nan)
    for k, side in enumerate(("left", "right")):
        pts = legs[:, [_L[n] for n in _FOOT_POINTS[side]]]
        seen = np.isfinite(pts).all(-1).any(1)
        n_seen = np.isfinite(pts).all(-1).sum(1)[:, None]  # (no numpy warning on frames with none seen)
        p = np.where(seen[:, None], np.nansum(pts, 1) / np.maximum(n_seen, 1), np.nan)
        p = np.stack([_fill(p[:, 0]), _fill(p[:, 1])], -1)
        p = gaussian_smooth(p, FOOT_SIGMA_FRAMES) if pic.n > 1 else p  # a pixel of jitter is 25 cm/s at 25 fps
        v = np.linalg.norm(np.gradient(p, axis=0), axis=-1) * mpp * fps if pic.n > 1 else np.zeros(pic.n)
        speed[:, k] = np.where(seen, v, np.nan)
    pelvis = pic.stable(pic.body[:, [_J["left_hip"], _J["right_hip"]]]).mean(1)[:, 1]
    hips_seen = np.isfinite(pic.body3d[:, [_J["left_hip"], _J["right_hip"]]]).all((-1, -2))
    hips = np.where(hips_seen, (floor - pelvis) * mpp, np.nan)
    return {"height": height, "speed": speed, "seen": np.isfinite(rows), "hips": hips, "camera_height": camera_height}


def hips_in_picture(feet: dict, legs_say: np.ndarray, fps: float) -> np.ndarray | None:
    """The hips' height ``[F]`` as the picture shows it above the floor's row, in the character's scale (the
    picture's metres times the median ratio of the legs' height to the picture's over the frames with a foot
    on the floor: the tracker's size is not the character's), where the hips are seen (else the legs' own);
    None when the picture never shows both. What a crouch, a jump and a seated pose look like, whatever the
    tracked legs say."""
    h = feet["hips"]
    with np.errstate(all="ignore"):
        low = np.nanmin(np.where(feet["seen"], feet["height"], np.nan), 1)
        down = np.isfinite(h) & (low < FLIGHT_M) & (h > 0.2)
    if down.sum() < 3:
        return None
    ratio = float(np.median(legs_say[down] / h[down]))
    if not 0.5 < ratio < 2.0:
        return None
    seen = np.isfinite(h)
    out = np.where(seen, ratio * np.where(seen, h, 0.0), legs_say)
    return _smooth(out, HIPS_SIGMA_FRAMES)


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` of each run of True in ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(int)))
    return list(zip(d[::2], d[1::2]))


def clean_runs(mask: np.ndarray, min_len: int = 3, max_gap: int = 2) -> np.ndarray:
    """``mask`` with gaps of at most ``max_gap`` frames inside its runs closed and runs shorter than ``min_len``
    dropped."""
    out = np.asarray(mask, bool).copy()
    for a, b in runs(~out):  # close short gaps inside contacts
        if a > 0 and b < len(out) and b - a <= max_gap:
            out[a:b] = True
    for a, b in runs(out):
        if b - a < min_len:
            out[a:b] = False
    return out


def foot_contacts(feet: dict, fps: float) -> np.ndarray:
    """Contact ``[F, 2]`` per foot (see the module docstring)."""
    h, v = feet["height"], feet["speed"]
    with np.errstate(all="ignore"):
        low = np.nanmin(np.where(feet["seen"], h, np.nan), 1, keepdims=True)
        c = (h - low < CONTACT_M) & (low < FLIGHT_M) & (v < CONTACT_SPEED) & feet["seen"]
    return np.stack([clean_runs(c[:, k]) for k in range(2)], 1)


def air_height(feet: dict) -> np.ndarray:
    """How high the lower foot is above the floor ``[F]`` when both feet are off it (0 otherwise)."""
    h = np.where(feet["seen"], feet["height"], np.nan)
    with np.errstate(all="ignore"):
        low = np.nanmin(h, 1)
    low = np.where(np.isfinite(low), low, 0.0)
    return np.maximum(low - AIR_DEADBAND_M, 0.0)


def lock_weights(contact: np.ndarray, fps: float) -> np.ndarray:
    """Per frame ``[F]``, how much a foot (or a hand) is held at its contact point: 1 throughout a contact,
    ramping up over the :data:`LOCK_BLEND_S` before it and down over those after it (the approach and the
    release ease in and out, no pop)."""
    n = max(1, int(round(LOCK_BLEND_S * fps)))
    w = np.zeros(len(contact))
    for a, b in runs(contact):
        w[a:b] = 1.0
        head = np.arange(max(0, a - n), a)
        w[head] = np.maximum(w[head], 1.0 - (a - head) / (n + 1))
        tail = np.arange(b, min(len(w), b + n))
        w[tail] = np.maximum(w[tail], 1.0 - (tail - b + 1) / (n + 1))
    return w


def anchors(ankle: np.ndarray, contact: np.ndarray, fps: float) -> np.ndarray:
    """The point each frame's foot is held at ``[F, 3]``: where its contact began (the mean of its first frames),
    carried through the release (NaN where there is no contact nearby)."""
    out = np.full_like(ankle, np.nan)
    n = max(1, int(round(LOCK_BLEND_S * fps)))
    for a, b in runs(contact):
        k = min(b, a + 3)
        p = np.nanmean(ankle[a:k], 0)
        out[max(0, a - n) : min(len(out), b + n)] = p
    return out
