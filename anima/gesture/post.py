"""Post-processing of generated gestures so an animator can use them (pure functions on ``[T, 55, 3]`` metres):

* :func:`blend_joins`: the k-NN output is a chain of N-frame windows; at each join where the output switches
  to another place of the database, the jump in position and velocity is carried as an offset that decays to
  zero over the next window (inertialization: a cubic Hermite from the offset and its velocity to zero with
  zero velocity). The chosen frames' content is kept: only the offset is added, and it is zero where a
  window continues the previous one.
* :func:`one_skeleton`: every frame re-posed with one set of bone lengths (each bone keeps its direction), so
  the output does not change size when it switches between speakers.
* :func:`smooth`: the seed's temporal filter of the learned generators' output (Gaussian, sigma 1.5 frames,
  seed 004 §4.5).
* :func:`to_rate`: the motion at the character's frame rate (the models work at 15 frames a second; the
  character plays at 30), a cubic through the frames, so a turn is spread over the frames between them.
"""

from __future__ import annotations

import numpy as np

from anima.core.filters import gaussian_smooth
from anima.core.skeleton import PARENTS, bone_lengths, fix_bone_lengths


def joins_of(picks: list[tuple[int, int]], n_step: int) -> list[int]:
    """Output frames where the search switched place: step i starts at frame i * n_step, and is a join unless
    it continues the previous step's window (same window, start ``r + n_step``)."""
    out = []
    for i in range(1, len(picks)):
        (m0, r0), (m1, r1) = picks[i - 1], picks[i]
        if not (m1 == m0 and r1 == r0 + n_step):
            out.append(i * n_step)
    return out


def blend_joins(J: np.ndarray, joins: list[int], length: int) -> np.ndarray:
    """Inertialized joins (see the module docstring) over ``length`` frames after each join."""
    out = np.array(J, np.float64, copy=True)
    T = len(out)
    for t in joins:
        if t < 2 or t >= T:
            continue
        prev_v = out[t - 1] - out[t - 2]
        new_v = (J[t + 1] - J[t]) if t + 1 < T else prev_v
        o0 = out[t - 1] + prev_v - J[t]  # where the motion was heading minus where the new window starts
        v0 = prev_v - new_v
        n = min(length, T - t)
        u = np.arange(n) / length
        h00 = 2 * u**3 - 3 * u**2 + 1
        h10 = u**3 - 2 * u**2 + u
        out[t : t + n] = J[t : t + n] + h00[:, None, None] * o0 + (h10 * length)[:, None, None] * v0
    return out.astype(np.asarray(J).dtype)


def skeleton_lengths(J: np.ndarray) -> np.ndarray:
    """Per-bone median length over every frame of ``J [..., T, 55, 3]`` (one skeleton for an output)."""
    L = bone_lengths(np.asarray(J, np.float64).reshape(-1, *np.shape(J)[-2:]))
    return np.nan_to_num(np.nanmedian(L, axis=0))


def one_skeleton(J: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Every frame with the bone ``lengths`` (directions kept, from the root outwards)."""
    return fix_bone_lengths(np.asarray(J, np.float64), lengths, PARENTS).astype(np.asarray(J).dtype)


def smooth(x: np.ndarray, sigma: float = 1.5) -> np.ndarray:
    """Zero-phase Gaussian smoothing over time (axis 0)."""
    shape = np.shape(x)
    return (
        gaussian_smooth(np.asarray(x, np.float64).reshape(shape[0], -1), sigma)
        .reshape(shape)
        .astype(np.asarray(x).dtype)
    )


def finish_knn(
    G: np.ndarray,
    picks: list[tuple[int, int]],
    lengths: np.ndarray,
    n_step: int,
    blend: bool = True,
    raw_steps: set | None = None,
) -> np.ndarray:
    """The k-NN search's raw output ``G [T, 165]`` -> joints ``[T, 55, 3]``: joins blended over one step,
    then one skeleton (``lengths``, e.g. :attr:`MatchDB.bone_lengths`). Joins at the steps in ``raw_steps``
    stay as searched (a wrist-speed control: the blend's decaying offset would add the motion the control
    asked away)."""
    J = np.asarray(G).reshape(len(G), -1, 3)
    if blend:
        joins = [t for t in joins_of(picks, n_step) if t // n_step not in (raw_steps or set())]
        J = blend_joins(J, joins, n_step)
    return one_skeleton(J, lengths)


def to_rate(x: np.ndarray, fps: float, new_fps: float) -> np.ndarray:
    """``x [F, ...]`` sampled at ``fps`` -> the same span at ``new_fps`` (a cubic spline through the frames, not
    past the last one; unchanged when the rates match). ``F`` frames become ``floor((F - 1) * new_fps / fps) + 1``."""
    from scipy.interpolate import CubicSpline

    x = np.asarray(x)
    if abs(new_fps - fps) < 1e-9 or len(x) < 2:
        return x.copy()
    t = np.arange(len(x)) / fps
    new = np.arange(int(np.floor((len(x) - 1) * new_fps / fps + 1e-6)) + 1) / new_fps
    if len(x) < 4:
        return np.stack([np.interp(new, t, c) for c in x.reshape(len(x), -1).T], -1).reshape((len(new),) + x.shape[1:])
    return CubicSpline(t, x, axis=0, bc_type="natural")(new).astype(x.dtype)
