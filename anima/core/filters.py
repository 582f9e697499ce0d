"""Temporal filters for tracked signals ``[T, ...]``.

* :func:`gaussian_smooth` - offline, zero-phase (no lag), sigma = 1.5 frames by default as in seed 004
  §4.3.1. Used by ``anima capture``: a symmetric kernel removes jitter without shifting events in time.
* :func:`prominent_peaks` - scipy's ``find_peaks(x, prominence=p)`` without importing ``scipy.signal``
  (which brings ``scipy.stats``: a quarter of a second of a cold ``anima text2face``).
* :class:`OneEuroFilter` - causal, adaptive cutoff (Casiez et al. 2012) for live use, where future frames
  are not available: low cutoff when the signal is still (kills jitter), high when it moves (little lag).
"""

from __future__ import annotations

import numpy as np


def valid_runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """Half-open ``[start, end)`` runs of True in a boolean vector."""
    v = np.concatenate([[False], np.asarray(valid, bool), [False]])
    d = np.diff(v.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def prominent_peaks(x: np.ndarray, prominence: float) -> np.ndarray:
    """Indices of the local maxima of ``x`` whose topographic prominence is at least ``prominence``: the
    same as ``scipy.signal.find_peaks(x, prominence=prominence)[0]`` (a flat peak is reported at the middle
    of its plateau, rounded down; the ends are never peaks; a peak's prominence is its height above the
    higher of the lowest points between it and the nearest higher sample on either side, or the ends)."""
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    peaks = []
    i = 1
    while i < n - 1:
        if x[i - 1] < x[i]:
            ahead = i + 1
            while ahead < n - 1 and x[ahead] == x[i]:
                ahead += 1
            if x[ahead] < x[i]:
                peaks.append((i + ahead - 1) // 2)
                i = ahead
        i += 1
    keep = []
    for p in peaks:
        higher_left = np.flatnonzero(x[:p] > x[p])
        higher_right = np.flatnonzero(x[p + 1 :] > x[p])
        lo = higher_left[-1] + 1 if len(higher_left) else 0
        hi = p + 1 + higher_right[0] if len(higher_right) else n
        if x[p] - max(x[lo : p + 1].min(), x[p:hi].min()) >= prominence:
            keep.append(p)
    return np.asarray(keep, dtype=np.intp)


def gaussian_smooth(x: np.ndarray, sigma: float = 1.5, valid: np.ndarray | None = None) -> np.ndarray:
    """Zero-phase Gaussian smoothing along axis 0, applied separately to each run of valid frames
    (so a face that disappears is not blended with what comes after). Edges use 'nearest' padding."""
    x = np.asarray(x, dtype=np.float64)
    if sigma <= 0 or len(x) < 2:
        return x.copy()
    from scipy.ndimage import gaussian_filter1d  # here: scipy.ndimage costs 0.05 s of every command's start

    out = x.copy()
    if valid is None:
        valid = np.ones(len(x), bool)
    for a, b in valid_runs(valid):
        if b - a >= 2:
            out[a:b] = gaussian_filter1d(x[a:b], sigma, axis=0, mode="nearest")
    return out


class OneEuroFilter:
    """Causal One-Euro filter on arrays of any shape, one call per frame.

    min_cutoff (Hz) sets smoothing when still; beta raises the cutoff with speed; d_cutoff filters the
    derivative estimate.
    """

    def __init__(self, freq: float, min_cutoff: float = 1.0, beta: float = 0.05, d_cutoff: float = 1.0):
        self.freq, self.min_cutoff, self.beta, self.d_cutoff = float(freq), min_cutoff, beta, d_cutoff
        self._x = None
        self._dx = None

    @staticmethod
    def _alpha(cutoff, freq):
        tau = 1.0 / (2 * np.pi * cutoff)
        return 1.0 / (1.0 + tau * freq)

    def reset(self) -> None:
        self._x = None
        self._dx = None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if self._x is None:
            self._x, self._dx = x.copy(), np.zeros_like(x)
            return x.copy()
        dx = (x - self._x) * self.freq
        a_d = self._alpha(self.d_cutoff, self.freq)
        self._dx = a_d * dx + (1 - a_d) * self._dx
        cutoff = self.min_cutoff + self.beta * np.abs(self._dx)
        a = self._alpha(cutoff, self.freq)
        self._x = a * x + (1 - a) * self._x
        return self._x.copy()


def resample_joints(J, conf, interp, fps: float, new_fps: float):
    """Linear resampling of joints to ``new_fps`` (a frame is missing if either neighbour is)."""
    F = len(J)
    t_new = np.arange(int(np.floor((F - 1) / fps * new_fps)) + 1) / new_fps
    x = t_new * fps
    i0 = np.clip(np.floor(x).astype(int), 0, F - 1)
    i1 = np.clip(i0 + 1, 0, F - 1)
    w = (x - i0)[:, None, None]
    Jn = (1 - w) * J[i0] + w * J[i1]
    near = np.where(w[:, 0, 0] < 0.5, i0, i1)
    return Jn, np.minimum(conf[i0], conf[i1]), interp[near]
