"""Texture synthesis maths (seed 001 §3.2): n nearest target frames by expression, adaptive sigma
(eqs. 3.3-3.4), and the weighted median of their vertex colours (Listing 1). Pure functions, no I/O.
"""

from __future__ import annotations

import numba as nb
import numpy as np


def nearest(db_expr: np.ndarray, x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Squared L2 distances from ``x`` (D,) to every database expression ``(N, D)``, and the indices of the
    ``n`` nearest sorted by distance."""
    d2 = ((db_expr - x[None]) ** 2).sum(1)
    n = min(n, len(d2))
    idx = np.argpartition(d2, n - 1)[:n]
    return idx[np.argsort(d2[idx], kind="stable")], d2


def adaptive_sigma(d2: np.ndarray, idx: np.ndarray, a: float = 0.9, iters: int = 60, tol: float = 1e-6) -> float:
    """sigma such that the ``n = len(idx)`` nearest frames carry the fraction ``a`` of the total weight
    (eq. 3.4), by bisection on log sigma. The fraction falls monotonically from 1 (sigma -> 0) to n/N
    (sigma -> inf); when n/N >= a every sigma satisfies it and the largest is returned."""
    N, n = len(d2), len(idx)
    if n >= N or n / N >= a:
        return float(np.sqrt(max(d2.max(), 1e-12)) * 1e3)
    d0 = d2 - d2[idx].min()  # shift: weights relative to the best frame (the ratio is unchanged)
    top = np.zeros(N, bool)
    top[idx] = True
    scale = np.sqrt(max(np.median(d0), 1e-12))
    lo, hi = np.log(scale * 1e-4), np.log(scale * 1e4)
    for _ in range(iters):
        if hi - lo < tol:  # log sigma known to 1e-6 relative: the weights cannot change any further
            break
        mid = 0.5 * (lo + hi)
        w = np.exp(-d0 / (2 * np.exp(2 * mid)))
        frac = w[top].sum() / w.sum()
        if frac > a:
            lo = mid  # too peaked: widen
        else:
            hi = mid
    return float(np.exp(0.5 * (lo + hi)))


def weights(d2_sel: np.ndarray, sigma: float) -> np.ndarray:
    """eq. 3.3 for the selected frames (shifted by the smallest distance for numerical range; the weighted
    median does not depend on a common factor)."""
    return np.exp(-(d2_sel - d2_sel.min()) / (2 * sigma * sigma)).astype(np.float64)


@nb.njit(parallel=True, cache=True)
def weighted_median_listing1(colrs, weights):
    """Listing 1 of seed 001, verbatim (numba, parallel over vertices). ``colrs`` (n, V, C) float32.
    Kept as the reference implementation (its I = 0 case indexes element -1, as in the listing)."""
    n_frames, n_verts, channels = colrs.shape
    out = np.empty((n_verts, channels), dtype=np.float32)
    for i in nb.prange(n_verts):
        for j in nb.prange(channels):
            data = colrs[:, i, j]
            ind_sorted = np.argsort(data)
            sorted_data = data[ind_sorted]
            sorted_weights = weights[ind_sorted]
            Sn = np.cumsum(sorted_weights)
            Pn = (Sn - 0.5 * sorted_weights) / Sn[-1]
            I = np.searchsorted(Pn, 0.5)
            out[i, j] = ((sorted_data[I] - sorted_data[I - 1]) / (Pn[I] - Pn[I - 1])) * (0.5 - Pn[I - 1]) + sorted_data[
                I - 1
            ]
    return out


@nb.njit(parallel=True, cache=True, fastmath=True, nogil=True)
def _wm_hist(stack, w, out):
    n = stack.shape[0]
    V, C = out.shape
    total = 0.0
    for k in range(n):
        total += w[k]
    half = 0.5 * total
    for v in nb.prange(V):
        hist = np.zeros(256, np.float64)
        for c in range(C):
            lo_v, hi_v = 255, 0
            for k in range(n):
                x = stack[k, v, c]
                hist[x] += w[k]
                if x < lo_v:
                    lo_v = x
                if x > hi_v:
                    hi_v = x
            # Listing 1's definition with equal values merged: each distinct value x sits at
            # P(x) = (S(x) - W(x)/2) / total; interpolate linearly where P crosses 1/2
            s = 0.0
            prev_p = -1.0
            prev_x = lo_v
            res = float(hi_v)
            for x in range(lo_v, hi_v + 1):
                wx = hist[x]
                if wx <= 0.0:
                    continue
                s += wx
                p = s - 0.5 * wx
                if p >= half:
                    if prev_p < 0.0:
                        res = float(x)
                    else:
                        res = prev_x + (x - prev_x) * (half - prev_p) / (p - prev_p)
                    break
                prev_p = p
                prev_x = x
            for x in range(lo_v, hi_v + 1):
                hist[x] = 0.0
            out[v, c] = res


def weighted_median(colors: np.ndarray, idx: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Fast weighted median per vertex and channel of the frames ``idx`` of ``colors`` (uint8 ``(N, V, C)``),
    with the frame weights ``w`` shared by all vertices. The ``n`` chosen frames are gathered into one
    contiguous ``(n, V, C)`` stack (whole frames: sequential reads, 1.7 MB at n = 100), then one weighted
    256-bin histogram per vertex-channel over the used colour range replaces a sort (O(n + range) rather
    than O(n log n)). Same definition as Listing 1 (values ranked by colour, the value at half of the total
    weight, linear interpolation between neighbours), with equal colours merged into one rank."""
    stack = np.ascontiguousarray(colors[np.asarray(idx, np.int64)])
    out = np.empty((stack.shape[1], stack.shape[2]), np.float32)
    _wm_hist(stack, np.ascontiguousarray(w, np.float64), out)
    return out


def expression_mapping(actor: np.ndarray, target: np.ndarray, floor: float = 0.02):
    """Per-person normalisation of expression statistics (seed 001 §4.2, §5.2): returns f(x) that moves
    an actor expression into the target's expression space, ``(x - mu_a) / sd_a * sd_t + mu_t``, clipped
    to the model's [0, 1] range. ``floor`` bounds the standard deviations from below (rarely used
    blendshapes would otherwise be amplified without limit)."""
    mu_a, sd_a = actor.mean(0), np.maximum(actor.std(0), floor)
    mu_t, sd_t = target.mean(0), np.maximum(target.std(0), floor)

    def f(x: np.ndarray) -> np.ndarray:
        return np.clip((x - mu_a) / sd_a * sd_t + mu_t, 0.0, 1.0).astype(np.float32)

    return f


def temporal_mean(x: np.ndarray, T: int) -> np.ndarray:
    """eq. 3.5: centred moving average over ``T`` frames along axis 0 (window shrinks at the ends)."""
    if T <= 1:
        return x
    from scipy.ndimage import uniform_filter1d

    return uniform_filter1d(np.asarray(x, np.float32), size=T, axis=0, mode="nearest")


# ---- colour and lighting per frame --------------------------------------------------------------------------
GAIN_RANGE = (0.5, 2.0)  # per-channel contrast change allowed between two frames' skin


def skin_stats(colors: np.ndarray, skin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel mean and standard deviation of the skin vertices' colours. ``colors`` ``(..., V, 3)``
    (one frame or a stack), ``skin`` a boolean mask over V. Returns two ``(..., 3)`` float32 arrays (the
    deviation floored at 1 colour level)."""
    c = np.asarray(colors)[..., skin, :].astype(np.float32)
    return c.mean(-2), np.maximum(c.std(-2), 1.0)


def color_transfer(colors: np.ndarray, mu_from, sd_from, mu_to, sd_to) -> np.ndarray:
    """Low-order colour transfer (per-channel gain and offset, Reinhard et al. 2001 in RGB): moves colours
    whose skin has statistics (mu_from, sd_from) to a skin with (mu_to, sd_to). Broadcasts over leading
    axes: ``colors`` ``(..., V, 3)``, statistics ``(..., 3)``. The gain is clipped to ``GAIN_RANGE`` so one
    badly sampled frame cannot blow the contrast up. Float32, unclipped."""
    sd_from, sd_to = np.atleast_1d(np.asarray(sd_from, np.float32)), np.atleast_1d(np.asarray(sd_to, np.float32))
    gain = np.clip(sd_to / sd_from, *GAIN_RANGE)
    mu_from, mu_to = np.atleast_1d(np.asarray(mu_from, np.float32)), np.atleast_1d(np.asarray(mu_to, np.float32))
    return (np.asarray(colors, np.float32) - mu_from[..., None, :]) * gain[..., None, :] + mu_to[..., None, :]


def normalized_colors(
    colors: np.ndarray, mu: np.ndarray, sd: np.ndarray, mu_ref, sd_ref, chunk: int = 256
) -> np.ndarray:
    """Every database frame's colours ``(N, V, 3)`` moved to the common reference skin (mu_ref, sd_ref), as
    uint8 ``(N, V, 3)`` for :func:`weighted_median`; in frame chunks (no float copy of the whole database)."""
    N, V, C = colors.shape
    out = np.empty((N, V, C), np.uint8)
    ref_mu = np.broadcast_to(np.asarray(mu_ref, np.float32), (N, C))
    ref_sd = np.broadcast_to(np.asarray(sd_ref, np.float32), (N, C))
    for a in range(0, N, chunk):
        b = min(N, a + chunk)
        c = color_transfer(colors[a:b], mu[a:b], sd[a:b], ref_mu[a:b], ref_sd[a:b])
        out[a:b] = np.clip(np.rint(c), 0, 255).astype(np.uint8)
    return out


def mesh_smoother(tris: np.ndarray, n_vertices: int):
    """The mesh's one-ring average as a sparse ``(V, V)`` operator (each vertex and its neighbours, equal
    weights): applied to per-vertex colours it keeps their low frequencies."""
    from scipy.sparse import coo_matrix, diags

    t = np.asarray(tris, np.int64)
    i = np.concatenate([t[:, 0], t[:, 1], t[:, 2], t[:, 1], t[:, 2], t[:, 0], np.arange(n_vertices)])
    j = np.concatenate([t[:, 1], t[:, 2], t[:, 0], t[:, 0], t[:, 1], t[:, 2], np.arange(n_vertices)])
    A = coo_matrix((np.ones(len(i)), (i, j)), shape=(n_vertices, n_vertices)).tocsr()
    A.data[:] = 1.0  # duplicate edges (shared by two triangles) count once
    return (diags(1.0 / np.asarray(A.sum(1)).ravel()) @ A).tocsr()


def add_detail(median: np.ndarray, best: np.ndarray, smoother, mask: np.ndarray, amount: float, passes: int = 2):
    """``median`` colours ``(V, C)`` plus ``amount`` times the high frequencies of ``best`` (the colours of the
    highest-weight frame minus their ``passes``-times mesh-smoothed version) on the vertices in ``mask``: the
    median's stable low frequencies, one real frame's edges (teeth, lip line) where the median blurs them."""
    if amount <= 0 or not mask.any():
        return median
    b = np.asarray(best, np.float64)
    low = b
    for _ in range(passes):
        low = smoother @ low
    out = np.array(median, np.float64, copy=True)
    out[mask] += amount * (b - low)[mask]
    return np.clip(out, 0, 255).astype(np.asarray(median).dtype)
