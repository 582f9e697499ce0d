"""Self-contact: a hand seen resting on the body is put on the character's body, not in front of it. Pure
functions.

A monocular tracker places a hand resting on the chest 20 cm or more in front of it (depth is what it sees
least). Where the picture says the hand is on the body, the depth is replaced, and only the depth:

* **Contact** (:func:`hand_contacts`), per hand and frame: the palm's centre (wrist and the four knuckles,
  in the picture) lies inside the torso's outline in the picture (the quadrilateral of the shoulders and
  hips, shrunk by a tenth), in its upper :data:`CHEST_FRACTION` (the chest and the upper belly: hands folded
  at the waist rest on a desk or a lap as often as on the body); the arm lies along the body, as an arm whose
  hand is on the chest does: its forearm and upper arm show at least :data:`MIN_FOREARM` and
  :data:`MIN_UPPER_ARM` of their length in the picture (a hand held out in front of the body, gesturing, has
  its forearm pointing at the camera and foreshortened to half); the hand rests there (it moves less than
  :data:`REST_SPEED` shoulder widths a second relative to the torso); and the tracked depth is plausible (the
  palm at most :data:`MAX_GAP_M` in front of the torso's joints); at least :data:`MIN_S` long. Where the hand
  tracker lost the hand (a hand flat on the chest, its back to the camera, is the one it loses most), the pose's
  wrist stands in for the palm.
* **Placement** (:func:`place_hands`): the palm's centre moves along the camera's axis (the world's z: its
  picture position stays) onto the character's torso surface (:class:`TorsoSurface`, measured on the
  character's rest mesh in the chest's frame), plus the hand's thickness; the arm reaches it by a two-bone IK
  (shoulder, elbow, wrist; the elbow keeps the plane it bent in; the hand keeps its turn), blended in and
  out over :data:`BLEND_S`. A hand whose palm would be inside the torso is moved out the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anima.core import ground
from anima.core.contract import JOINT_NAMES
from anima.core.filters import gaussian_smooth
from anima.core.kinematics import aim, two_bone

REST_SPEED = 0.6
MAX_GAP_M = 0.50  # the tracker put a palm held on the chest 39-41 cm in front of the torso's joints (round trip)
MIN_S = 0.25
CHEST_FRACTION = 0.6
MIN_FOREARM = 0.80
MIN_UPPER_ARM = 0.75
BLEND_S = 0.15
HAND_THICKNESS_M = 0.025
SHRINK = 0.1
_J = {n: i for i, n in enumerate(JOINT_NAMES)}
_PALM = ("hand_wrist", "hand_index_mcp", "hand_middle_mcp", "hand_ring_mcp", "hand_pinky_mcp")


def palm(points: np.ndarray, side: str) -> np.ndarray:
    """The palm's centre ``[F, D]`` from the 55 joints ``[F, 55, D]`` (pixels or metres)."""
    return np.mean([points[:, _J[f"{side}_{n}"]] for n in _PALM], 0)


def palm_or_wrist(points: np.ndarray, side: str) -> np.ndarray:
    """:func:`palm`, or the pose's wrist where the hand tracker lost the hand (a hand flat on the chest, its
    back to the camera, is the hand it loses most)."""
    c = palm(points, side)
    return np.where(np.isfinite(c).all(-1, keepdims=True), c, points[:, _J[f"{side}_wrist"]])


def _inside(p: np.ndarray, quad: np.ndarray) -> np.ndarray:
    """Whether points ``[F, 2]`` lie inside convex quadrilaterals ``[F, 4, 2]`` (either winding)."""
    s = []
    for k in range(4):
        a, b = quad[:, k], quad[:, (k + 1) % 4]
        s.append((b[:, 0] - a[:, 0]) * (p[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (p[:, 0] - a[:, 0]))
    S = np.stack(s, 1)
    with np.errstate(invalid="ignore"):
        return (S > 0).all(1) | (S < 0).all(1)


def in_picture_plane(pic: ground.Picture, mpp: np.ndarray, a: str, b: str) -> np.ndarray:
    """How much of the bone ``a``-``b``'s length the picture shows ``[F]`` (its picture length in metres over
    its clip-median 3D length: 1 in the picture's plane, less when it points at or away from the camera)."""
    l2 = np.linalg.norm(pic.body[:, _J[b]] - pic.body[:, _J[a]], axis=-1) * mpp
    l3 = np.linalg.norm(pic.body3d[:, _J[b]] - pic.body3d[:, _J[a]], axis=-1)
    return l2 / np.nanmedian(l3) if np.isfinite(l3).any() else np.full(pic.n, np.nan)


def hand_contacts(pic: ground.Picture, fps: float) -> np.ndarray:
    """Contact ``[F, 2]`` (left hand, right hand) of each hand with the torso (see the module docstring)."""
    mpp = ground.metres_per_pixel(pic, fps)
    if mpp is None:
        return np.zeros((pic.n, 2), bool)
    px, P3 = pic.stable(pic.body), pic.body3d
    quad = np.stack([px[:, _J[n]] for n in ("left_shoulder", "right_shoulder", "right_hip", "left_hip")], 1)
    centre = quad.mean(1, keepdims=True)
    quad = centre + (1 - SHRINK) * (quad - centre)
    width = np.linalg.norm(px[:, _J["left_shoulder"]] - px[:, _J["right_shoulder"]], axis=-1)
    Z = np.stack([P3[:, _J[n], 2] for n in ("left_shoulder", "right_shoulder", "spine", "neck")], 0)
    seen = np.isfinite(Z).sum(0)  # (a frame with none of them seen: NaN, without numpy's empty-mean warning)
    torso_z = np.where(seen > 0, np.nansum(Z, 0) / np.maximum(seen, 1), np.nan)
    out = np.zeros((pic.n, 2), bool)
    for k, side in enumerate(("left", "right")):
        c = palm_or_wrist(px, side)
        rel = (c - centre[:, 0]) / np.maximum(width, 1.0)[:, None]
        ok = np.isfinite(rel).all(-1)
        if ok.sum() < 2:
            continue
        r = np.where(ok[:, None], rel, 0.0)
        r = gaussian_smooth(r, 0.1 * fps) if len(r) > 1 else r
        speed = np.linalg.norm(np.gradient(r, axis=0), axis=-1) * fps if len(r) > 1 else np.zeros(len(r))
        gap = palm_or_wrist(P3, side)[:, 2] - torso_z
        top = (px[:, _J["left_shoulder"]] + px[:, _J["right_shoulder"]]) / 2
        bottom = (px[:, _J["left_hip"]] + px[:, _J["right_hip"]]) / 2
        axis = bottom - top
        down = np.einsum("fi,fi->f", c - top, axis) / np.maximum(np.einsum("fi,fi->f", axis, axis), 1.0)
        fore = in_picture_plane(pic, mpp, f"{side}_elbow", f"{side}_wrist")
        upper = in_picture_plane(pic, mpp, f"{side}_shoulder", f"{side}_elbow")
        with np.errstate(invalid="ignore"):
            along = (fore >= MIN_FOREARM) & (upper >= MIN_UPPER_ARM)
            chest = down <= CHEST_FRACTION
            c_ok = ok & _inside(c, quad) & chest & along & (speed < REST_SPEED) & (gap < MAX_GAP_M) & (gap > -0.2)
        out[:, k] = ground.clean_runs(c_ok, min_len=max(2, int(round(MIN_S * fps))), max_gap=2)
    return out


@dataclass
class TorsoSurface:
    """The front of the character's torso as a height field in the chest's frame: ``z[i, j]`` the most forward
    torso point (metres, from the chest joint) in the cell at ``x0 + i * cell``, ``y0 + j * cell``."""

    z: np.ndarray
    x0: float
    y0: float
    cell: float

    @classmethod
    def from_mesh(cls, V: np.ndarray, chest: np.ndarray, torso: np.ndarray, cell: float = 0.02) -> TorsoSurface:
        """``V [N, 3]`` the rest mesh, ``chest [3]`` the chest joint, ``torso [N]`` the torso's vertices."""
        Q = V[torso] - chest
        x0, y0 = Q[:, 0].min(), Q[:, 1].min()
        nx = int(np.ceil((Q[:, 0].max() - x0) / cell)) + 1
        ny = int(np.ceil((Q[:, 1].max() - y0) / cell)) + 1
        z = np.full((nx, ny), np.nan)
        i = ((Q[:, 0] - x0) / cell).astype(int)
        j = ((Q[:, 1] - y0) / cell).astype(int)
        np.fmax.at(z, (i, j), Q[:, 2])
        return cls(z, float(x0), float(y0), cell)

    def front(self, p: np.ndarray) -> np.ndarray:
        """The surface's z ``[F]`` in front of chest-frame points ``p [F, 3]`` (NaN off the torso)."""
        i = np.round((p[:, 0] - self.x0) / self.cell).astype(int)
        j = np.round((p[:, 1] - self.y0) / self.cell).astype(int)
        ok = (i >= 0) & (i < self.z.shape[0]) & (j >= 0) & (j < self.z.shape[1])
        out = np.full(len(p), np.nan)
        out[ok] = self.z[i[ok], j[ok]]
        return out


def place_hands(G, P, rest, contact, surface: TorsoSurface, chest: int, arms: dict, fps: float):
    """Move the palms of the hands in ``contact [F, 2]`` onto ``surface`` along the world's z (in place on the
    global rotations ``G [F, J, 3, 3]``; ``P`` their positions). ``arms``: per side the rig indices
    ``(shoulder_parent, arm, forearm, hand, [knuckles])``; the arm bent by two-bone IK
    (:mod:`anima.core.kinematics`).
    Returns the palms' distance to the surface ``[F, 2]`` after placement (NaN off contact)."""
    gap = np.full((len(G), 2), np.nan)
    for k, side in enumerate(("left", "right")):
        w = ground.lock_weights(contact[:, k], fps) if contact[:, k].any() else np.zeros(len(G))
        up, arm, fore, hand, knuckles = arms[side]
        pc = 0.5 * P[:, hand] + 0.5 * P[:, knuckles].mean(1)  # the palm's centre
        local = np.einsum("fji,fj->fi", G[:, chest], pc - P[:, chest])
        surf = surface.front(local)
        want = np.where(np.isfinite(surf), surf + HAND_THICKNESS_M, local[:, 2])
        inside = np.isfinite(surf) & (local[:, 2] < surf)
        w = np.maximum(w, np.where(inside, 1.0, 0.0))
        on = w > 0
        if not on.any():
            continue
        shift = np.zeros_like(pc)
        dz_local = np.where(on, want - local[:, 2], 0.0)
        # along the world's z by the amount that brings the chest-frame depth to the surface
        zc = G[:, chest][:, 2, 2]
        shift[:, 2] = w * dz_local / np.where(np.abs(zc) > 0.3, zc, 1.0)
        wrist = P[:, hand] + shift
        off_f, off_h = np.linalg.norm(rest[fore] - rest[arm]), np.linalg.norm(rest[hand] - rest[fore])
        sh, el = P[on, arm], P[on, fore]
        new_el = two_bone(sh, wrist[on], off_f, off_h, el - sh)
        Gh = G[on, hand].copy()
        Ga = aim(G[on, up], rest[fore] - rest[arm], new_el - sh)
        Gf = aim(Ga, rest[hand] - rest[fore], wrist[on] - new_el)
        G[on, arm], G[on, fore], G[on, hand] = Ga, Gf, Gh
        after = local[:, 2] + dz_local * w
        gap[contact[:, k], k] = np.abs(after - want + HAND_THICKNESS_M)[contact[:, k]]
    return gap
