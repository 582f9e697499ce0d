"""Gesture strokes on the speech's stresses (``anima gesture``; the stresses: :mod:`anima.audio.stress`).

A **stroke** is a peak of the wrists' speed (both wrists' speeds summed, central differences, smoothed over three
frames) that rises at least :data:`MIN_PROMINENCE` above the slowest frame within :data:`SIDE` frames on each side.
Two mechanisms move strokes onto stresses:

* **in the search** (:class:`StrokeTerm`, :func:`anima.gesture.knn.search`): at a step whose 8 frames hold stresses,
  each candidate start is scored by how far its own strokes are from them (frames, capped at :data:`CAP`; the
  mean over the step's stresses), and that score's rank (ties share a rank) is added, times a weight, to the
  seed's audio and pose ranks. A step without a stress is ranked as in the seed;
* **after it** (:func:`place_strokes`): the output is re-timed so that a stroke within ``max_shift`` frames of a
  stress meets it exactly: a piecewise-linear time warp through those (stress, stroke) pairs, whose local rate
  stays within ``1 / MAX_RATE`` .. ``MAX_RATE`` of real time (a pair that would need more is skipped), sampled by a
  cubic through the frames. Only the body is re-timed; the face follows the speech as before.

:func:`alignment` measures it: per stress, the distance to the nearest stroke; per stroke, whether a stress is near.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from anima.core.skeleton import JOINT_NAMES

WRISTS = [JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("right_wrist")]
MIN_PROMINENCE = 0.15  # m/s of summed wrist speed (captured motion at 15 fps: median 0.31, 90th percentile 1.06)
SIDE = 4  # frames each side in which the speed must dip by MIN_PROMINENCE
CAP = 3  # frames: a stroke further than this from a stress counts as missing it
MAX_SHIFT = 2  # frames (at 15 fps) a stroke may be moved to meet a stress
MAX_RATE = 1.35  # the warp's fastest local rate (and 1 / MAX_RATE its slowest)


def wrist_speed(J: np.ndarray, fps: float) -> np.ndarray:
    """Both wrists' speeds summed (m/s) per frame of ``J [..., T, 55, 3]`` (``[..., T]``): central differences
    (one-sided at the ends), smoothed by [1, 2, 1] / 4 over time."""
    w = np.asarray(J, np.float64)[..., WRISTS, :]
    v = np.gradient(w, axis=-3) * fps
    s = np.linalg.norm(v, axis=-1).sum(-1)
    pad = np.concatenate([s[..., :1], s, s[..., -1:]], -1)
    return 0.25 * pad[..., :-2] + 0.5 * pad[..., 1:-1] + 0.25 * pad[..., 2:]


def stroke_frames(speed: np.ndarray, refine: bool = True) -> np.ndarray:
    """The strokes of a speed curve ``[T]`` (see the module docstring), in frames; ``refine``: to a fraction of
    a frame (the vertex of the parabola through the peak and its neighbours)."""
    s = np.asarray(speed, np.float64)
    T = len(s)
    if T < 3:
        return np.zeros(0)
    peak = np.flatnonzero((s[1:-1] > s[:-2]) & (s[1:-1] >= s[2:])) + 1
    out = []
    for q in peak:
        left, right = s[max(0, q - SIDE) : q], s[q + 1 : q + 1 + SIDE]
        if s[q] - left.min() >= MIN_PROMINENCE and s[q] - right.min() >= MIN_PROMINENCE:
            x = float(q)
            if refine:
                a, b, c = s[q - 1], s[q], s[q + 1]
                den = a - 2 * b + c
                x += 0.5 * (a - c) / den if abs(den) > 1e-12 else 0.0
            out.append(x)
    return np.array(out)


def stroke_distance(G: np.ndarray, fps: float, cap: int = CAP) -> np.ndarray:
    """Per database window and frame (``G [M, T, 165]``), the distance in whole frames to the window's nearest
    stroke, at most ``cap`` (``[M, T]`` int8)."""
    M, T = G.shape[:2]
    speed = wrist_speed(np.asarray(G).reshape(M, T, -1, 3), fps)
    out = np.full((M, T), cap, np.int8)
    f = np.arange(T)
    for m in range(M):
        st = np.round(stroke_frames(speed[m], refine=False)).astype(int)
        if len(st):
            out[m] = np.minimum(np.abs(f[:, None] - st[None]).min(1), cap)
    return out


@dataclass
class StrokeTerm:
    """The search's stroke term: ``dist [M, T]`` (:func:`stroke_distance` of the database), ``stresses`` per search
    step (the stresses' frame offsets within the step's 8 frames, whole frames), and the weight of its rank."""

    dist: np.ndarray
    stresses: list[np.ndarray]
    weight: float = 1.0
    cap: int = CAP

    @classmethod
    def of(cls, dist: np.ndarray, stress_frames: np.ndarray, n_steps: int, n_step: int, weight: float) -> StrokeTerm:
        f = np.round(np.asarray(stress_frames, np.float64)).astype(int)
        steps = [np.unique(f[(f >= i * n_step) & (f < (i + 1) * n_step)] - i * n_step) for i in range(n_steps)]
        return cls(np.asarray(dist), steps, weight)

    def ranks(self, step: int, m: np.ndarray, r: np.ndarray) -> np.ndarray | None:
        """The weighted rank of each candidate (window ``m``, start ``r``) at ``step``; None at a step without a
        stress (or weight 0). Integers, so the search's rank sums stay exact."""
        if self.weight <= 0 or step >= len(self.stresses) or not len(self.stresses[step]):
            return None
        T = self.dist.shape[1]
        off = self.stresses[step]
        cols = np.minimum(np.asarray(r)[:, None] + off[None], T - 1)
        cost = self.dist[np.asarray(m)[:, None], cols].astype(np.int64).sum(1)  # the mean, times len(off)
        tie = np.searchsorted(np.sort(cost), cost, side="left")  # ties share the lowest rank
        return np.round(self.weight * tie).astype(np.int64)


def place_strokes(
    J: np.ndarray,
    stress_frames: np.ndarray,
    fps: float,
    max_shift: float = MAX_SHIFT,
    max_rate: float = MAX_RATE,
    keep: list[tuple[float, float]] = (),
) -> tuple[np.ndarray, dict]:
    """``J [T, 55, 3]`` re-timed so strokes within ``max_shift`` frames of a stress meet it (module docstring).
    ``keep``: frame ranges left as they are (a wrist-speed control's: re-timing would change the speed it asks
    for). Returns the motion and a report (strokes found, moved, their mean shift in frames)."""
    J = np.asarray(J)
    T = len(J)
    stresses = np.sort(np.asarray(stress_frames, np.float64))
    report = {"strokes": 0, "moved": 0, "mean_shift_frames": 0.0}
    if max_shift <= 0 or T < 4 or not len(stresses):
        return J.copy(), report
    strokes = stroke_frames(wrist_speed(J, fps))
    report["strokes"] = len(strokes)
    fixed = {0.0, float(T - 1)}
    for a, b in keep:  # identity anchors around a kept range, no stroke moved into or out of it
        fixed |= {float(np.clip(a, 0, T - 1)), float(np.clip(b, 0, T - 1))}
    fixed = sorted(fixed)

    def kept(x: float) -> bool:
        return any(a - max_shift <= x <= b + max_shift for a, b in keep)

    pairs = []
    for p in strokes:
        s = stresses[np.argmin(np.abs(stresses - p))]
        if abs(s - p) <= max_shift and 0 < s < T - 1 and not kept(s) and not kept(p):
            pairs.append((float(s), float(p)))

    def rate_ok(a, b) -> bool:
        return b[0] > a[0] and 1 / max_rate <= (b[1] - a[1]) / (b[0] - a[0]) <= max_rate

    anchors = [(fixed[0], fixed[0])]
    moved = []
    for s, p in sorted(pairs):  # output time s shows the motion of time p
        while len(fixed) > 1 and fixed[1] <= s:  # passed a fixed anchor: it is the previous one now
            fixed.pop(0)
            anchors.append((fixed[0], fixed[0]))
        nxt = (fixed[1], fixed[1]) if len(fixed) > 1 else None
        if rate_ok(anchors[-1], (s, p)) and (nxt is None or rate_ok((s, p), nxt)):
            anchors.append((s, p))
            moved.append(abs(s - p))
    for f in fixed[1:]:
        anchors.append((f, f))
    a = np.array(sorted(set(anchors)))
    report["moved"] = len(moved)
    report["mean_shift_frames"] = round(float(np.mean(moved)), 3) if moved else 0.0
    if not moved:
        return J.copy(), report
    from scipy.interpolate import CubicSpline  # as anima.gesture.post.to_rate

    u = np.interp(np.arange(T, dtype=np.float64), a[:, 0], a[:, 1])
    out = CubicSpline(np.arange(T), J.reshape(T, -1).astype(np.float64), axis=0)(u)
    return out.reshape(J.shape).astype(J.dtype), report


def alignment(J: np.ndarray, stress_s: np.ndarray, fps: float, near_s: float = 0.1, cap_s: float = 0.5) -> dict:
    """How strokes meet stresses in ``J [T, 55, 3]``: ``stress_to_stroke_s`` the mean over stresses of the distance
    to the nearest stroke (capped at ``cap_s``), ``stresses_hit`` the share of stresses with a stroke within
    ``near_s``, ``strokes_on_stress`` the share of strokes within ``near_s`` of a stress, ``strokes_per_s``."""
    strokes = stroke_frames(wrist_speed(J, fps)) / fps
    st = np.asarray(stress_s, np.float64)
    st = st[(st >= 0) & (st <= (len(J) - 1) / fps)]
    out = {"stresses": int(len(st)), "strokes": int(len(strokes)), "strokes_per_s": len(strokes) / (len(J) / fps)}
    if not len(st) or not len(strokes):
        return out | {"stress_to_stroke_s": cap_s if len(st) else float("nan"), "stresses_hit": 0.0,
                      "strokes_on_stress": 0.0}  # fmt: skip
    d = np.abs(st[:, None] - strokes[None])
    out["stress_to_stroke_s"] = float(np.minimum(d.min(1), cap_s).mean())
    out["stresses_hit"] = float((d.min(1) <= near_s).mean())
    out["strokes_on_stress"] = float((d.min(0) <= near_s).mean())
    return out
