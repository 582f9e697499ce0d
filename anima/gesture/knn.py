"""Audio-to-gesture k-NN search with control (seed 004 §5.3.1.3, Algorithm 1, §5.3.2.1).

Database: M windows of T_MATCH = 64 frames, each with audio features F (64, 112), pose features P (64, 96)
and gestures G (64, 165). Every N = 8 frames: per database window, the frame r whose pose feature is closest
(Euclidean) to the previous pose feature among the frames allowed by the control mask ("pose pre-selected");
then the M candidates are ranked by audio (cosine distance of f at r to the input f_t) and by pose, the two
ranks are added, and the k-th best candidate (0 = best) gives the next N frames.

Two readings of the algorithm's text are made explicit here (both implementations follow them):
* a window can only start where N frames fit (r <= T_MATCH - N), so that N output frames exist;
* a database window with no frame allowed by the control is not a candidate (Algorithm 1 would keep its
  frame 0, which breaks the control).
Control masks look at the first and the last frame of each N-frame window (§5.3.2.1).

:func:`search_literal` is Algorithm 1 with its loops; :func:`search` is the fast version (all windows and
frames at once, float64 like the literal one) and returns identical output.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numba as nb
import numpy as np

from anima.gesture.features import N_STEP, T_MATCH


@dataclass
class MatchDB:
    F: np.ndarray  # (M, T, 112)
    P: np.ndarray  # (M, T, 96)
    G: np.ndarray  # (M, T, 165)
    source: list = field(default_factory=list)  # per window: (video, start_s)
    S: np.ndarray | None = None  # (M, T, 28) per-frame speech features (for the cGAN refiner)

    _layout: tuple | None = None

    @property
    def M(self) -> int:
        return len(self.F)

    def audio_norms(self) -> np.ndarray:
        """|f| per database frame, computed as the literal search computes it (float64, per row)."""
        if getattr(self, "_fnorm", None) is None:
            F = self.F.astype(np.float64)
            self._fnorm = np.sqrt((F * F).sum(-1))
        return self._fnorm

    def search_layout(self) -> tuple:
        """Made once for the fast search: the pose features with their dimensions reordered by decreasing
        variance (the partial distance search stops early while reading rows sequentially), and their
        centred projection on the 32 leading principal directions quantised to int16 per direction, split in
        two arrays: directions 1-16, stored [M, 16, T] (a lower bound read for every frame: 32 bytes per frame, so a
        600,000-frame database's bounds stay in a 32 MB cache) and 17-32 (a tighter bound, read only for the
        frames the first one keeps). ``delta16`` / ``delta32``: the largest distance between a dequantised
        projection and the exact one, which keeps both bounds rigorous."""
        if self._layout is None:
            sample = self.P.reshape(-1, self.P.shape[-1])[:: max(1, self.P.shape[0] * self.P.shape[1] // 20000)]
            sample = sample.astype(np.float64)
            dims = np.argsort(-sample.var(0), kind="stable")
            mu = sample.mean(0)
            _, _, Vt = np.linalg.svd(sample - mu, full_matrices=False)
            U = np.ascontiguousarray(Vt[:48].T)  # (96, 48) orthonormal columns
            Q = (self.P.astype(np.float64) - mu) @ U
            flat = Q.reshape(-1, Q.shape[-1])
            lo, hi = flat.min(0), flat.max(0)
            scale = np.maximum(hi - lo, 1e-12) / 65535.0
            Qi = np.round((Q - lo) / scale - 32768).clip(-32768, 32767).astype(np.int16)
            err2 = ((Qi.astype(np.float64) + 32768) * scale + lo - Q) ** 2
            delta16 = float(np.sqrt(err2[..., :16].sum(-1)).max())
            delta32 = float(np.sqrt(err2[..., :32].sum(-1)).max())
            delta48 = float(np.sqrt(err2.sum(-1)).max())
            # q' = (q - lo) / scale - 32768 in the search, so that the bound is sum(scale^2 (Qi - q')^2)
            self._layout = (np.ascontiguousarray(self.P[..., dims]), dims,
                            np.ascontiguousarray(Qi[..., :16].transpose(0, 2, 1)),
                            np.ascontiguousarray(Qi[..., 16:]), U, mu, (delta16, delta32, delta48), lo, scale)
        return self._layout

    def start_mask(self, frame_mask: np.ndarray | None) -> np.ndarray:
        """(M, T) frame eligibility -> (M, T) window-start eligibility: first and last frame of the N-frame
        window allowed, and the window inside the database window."""
        M, T = self.P.shape[:2]
        ok = np.zeros((M, T), bool)
        ok[:, 1:T - N_STEP + 1] = True  # s = 1 .. T - N (Algorithm 1 starts at s = 1)
        if frame_mask is not None:
            last = np.zeros_like(frame_mask)
            last[:, :T - N_STEP + 1] = frame_mask[:, N_STEP - 1:]
            ok &= frame_mask & last
        return ok


def _relrank(d: np.ndarray) -> np.ndarray:
    r = np.empty(len(d), np.int64)
    r[np.argsort(d, kind="stable")] = np.arange(len(d))
    return r


def _cosine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    na = np.sqrt((a * a).sum(-1))
    nb = np.sqrt((b * b).sum(-1))
    return 1.0 - (a * b).sum(-1) / np.maximum(na * nb, 1e-12)


def search_literal(db: MatchDB, F_in: np.ndarray, k: int, p_init: np.ndarray,
                   control: list | None = None) -> tuple[np.ndarray, list]:
    """Algorithm 1 as written (Python loops). ``control``: per search step a (M, T) window-start mask or
    None. Returns the gestures (T, 165) and the chosen (window, frame) per step."""
    T = len(F_in)
    G, picks = [], []
    p_prev = np.asarray(p_init, np.float64)
    t = 0
    step = 0
    while t < T:
        mask = db.start_mask(None) if control is None or control[step] is None else control[step]
        cand, pd, fd = [], [], []
        for m in range(db.M):
            r, pdist = -1, np.inf
            for s in range(1, T_MATCH):
                if mask[m, s]:
                    d = float(np.sqrt(((db.P[m, s].astype(np.float64) - p_prev) ** 2).sum()))
                    if d < pdist:
                        pdist, r = d, s
            if r < 0:
                continue
            cand.append((m, r))
            pd.append(pdist)
            fd.append(float(_cosine(db.F[m, r].astype(np.float64), F_in[t].astype(np.float64))))
        if not cand:
            raise ValueError("no database window satisfies the control")
        comb = _relrank(np.array(fd)) + _relrank(np.array(pd))
        order = np.argsort(comb, kind="stable")
        m, r = cand[int(order[min(k, len(order) - 1)])]
        n = min(N_STEP, T - t)
        G.append(db.G[m, r:r + n])
        p_prev = db.P[m, r + N_STEP - 1].astype(np.float64)
        picks.append((m, r))
        t += N_STEP
        step += 1
    return np.concatenate(G), picks


@nb.njit(parallel=True, cache=True)
def _preselect(P, Q, Q2, mask, p, q, scale2, delta16, delta32, delta48, lb, r_out, d_out):
    """Per window m: the allowed frame s closest to ``p`` (squared Euclidean, float64), exactly, ties to the
    smallest s (as the literal loop's strict ``<``). ``Q`` / ``Q2`` are the centred features projected on the
    principal directions 1-16 / 17-32 (orthonormal, so a projected distance is a lower bound of the true
    one), stored quantised (int16, per-direction ``scale2`` = step^2, ``q`` in the same units); ``delta16`` /
    ``delta32`` bound the rounding, so |q - Q_s| - delta is still a lower bound. The frame with the smallest
    16-direction bound is measured first; frames whose 16- or 32-direction bound exceeds the best distance
    so far are skipped, and full sums (dimensions stored largest-variance first) stop once they exceed it.
    None of this can change the result. ``lb`` is an (M, T) work array."""
    M, T, D = P.shape
    K = Q.shape[1]
    K2 = Q2.shape[2]
    for m in nb.prange(M):
        # Q is stored direction-major per window ([M, 16, T]): the bound of all T frames is accumulated
        # one direction at a time, a loop over contiguous frames that the compiler vectorises
        for s in range(T):
            lb[m, s] = 0.0
        for j in range(K):
            qj = q[j]
            sj = scale2[j]
            for s in range(T):
                diff = np.float64(Q[m, j, s]) - qj
                lb[m, s] += sj * diff * diff
        s0 = -1
        for s in range(T):
            if mask[m, s] and (s0 < 0 or lb[m, s] < lb[m, s0]):
                s0 = s
        if s0 < 0:
            r_out[m] = -1
            d_out[m] = np.inf
            continue
        best = 0.0
        for j in range(D):
            diff = np.float64(P[m, s0, j]) - p[j]
            best += diff * diff
        r = s0
        # skip s when sqrt(lb) - delta > sqrt(best), i.e. lb > (sqrt(best) + delta)^2 (with a margin for
        # the float64 arithmetic)
        sb = np.sqrt(best)
        cut16 = (sb + delta16) ** 2 * (1.0 + 1e-9) + 1e-12
        cut32 = (sb + delta32) ** 2 * (1.0 + 1e-9) + 1e-12
        cut48 = (sb + delta48) ** 2 * (1.0 + 1e-9) + 1e-12
        for s in range(T):
            if s == s0 or not mask[m, s] or lb[m, s] > cut16:
                continue
            acc = lb[m, s]  # the 32- then the 48-direction bound: directions 17-32, then 33-48 added
            half = K2 // 2
            for j in range(half):
                diff = np.float64(Q2[m, s, j]) - q[K + j]
                acc += scale2[K + j] * diff * diff
            if acc > cut32:
                continue
            for j in range(half, K2):
                diff = np.float64(Q2[m, s, j]) - q[K + j]
                acc += scale2[K + j] * diff * diff
            if acc > cut48:
                continue
            acc = 0.0
            for j in range(D):
                diff = np.float64(P[m, s, j]) - p[j]
                acc += diff * diff
                if acc > best:
                    break
            if acc < best or (acc == best and s < r):
                best = acc
                r = s
                sb = np.sqrt(best)
                cut16 = (sb + delta16) ** 2 * (1.0 + 1e-9) + 1e-12
                cut32 = (sb + delta32) ** 2 * (1.0 + 1e-9) + 1e-12
                cut48 = (sb + delta48) ** 2 * (1.0 + 1e-9) + 1e-12
        r_out[m] = r
        d_out[m] = np.sqrt(best)


@nb.njit(inline="always")
def _pairwise_dot(F, m, r, b):
    """sum_j float64(F[m, r, j]) * b[j], added in numpy's pairwise order for rows of 8 to 128 values (eight
    running sums, combined as ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7)), then the remainder), so the
    result is bit-identical to the literal search's ``(a * b).sum(-1)``."""
    n = b.shape[0]
    acc = np.empty(8)
    for j in range(8):
        acc[j] = np.float64(F[m, r, j]) * b[j]
    i = 8
    stop = n - (n % 8)
    while i < stop:
        for j in range(8):
            acc[j] += np.float64(F[m, r, i + j]) * b[i + j]
        i += 8
    res = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    while i < n:
        res += np.float64(F[m, r, i]) * b[i]
        i += 1
    return res


@nb.njit(parallel=True, cache=True)
def _audio_distance(F, F_norm, m_ok, r_ok, b, b_norm, out):
    """Cosine distance of each pre-selected frame's audio feature to ``b``, as the literal search computes
    it (``1 - a.b / max(|a| |b|, 1e-12)``, float64)."""
    for i in nb.prange(len(m_ok)):
        m, r = m_ok[i], r_ok[i]
        out[i] = 1.0 - _pairwise_dot(F, m, r, b) / max(F_norm[m, r] * b_norm, 1e-12)


@nb.njit(parallel=True, cache=True)
def _rank_sum(a, b, out):
    """``out = relrank(a) + relrank(b)``: positions in the stable orders of ``a`` and ``b`` (both sorted at
    once, one per core)."""
    n = len(a)
    ra = np.empty(n, np.int64)
    rb = np.empty(n, np.int64)
    for w in nb.prange(2):
        x = a if w == 0 else b
        order = np.argsort(x, kind="mergesort")
        dst = ra if w == 0 else rb
        for i in range(n):
            dst[order[i]] = i
    for i in range(n):
        out[i] = ra[i] + rb[i]


def search(db: MatchDB, F_in: np.ndarray, k: int, p_init: np.ndarray,
           control: list | None = None) -> tuple[np.ndarray, list]:
    """The same search, fast: a numba pass over all windows and frames per step (partial distance search),
    then the ranking on the M pre-selected candidates. Identical output to :func:`search_literal`."""
    T = len(F_in)
    Fdb = db.F
    base = db.start_mask(None)
    P, dims, Q, Q2, U, mu, (delta16, delta32, delta48), q_lo, q_scale = db.search_layout()
    scale2 = q_scale ** 2
    F_norm = db.audio_norms()
    lb = np.empty(P.shape[:2])
    G, picks = [], []
    p_prev = np.asarray(p_init, np.float64)
    t = 0
    step = 0
    rows = np.arange(db.M)
    r = np.empty(db.M, np.int64)
    pdist = np.empty(db.M, np.float64)
    fd_buf = np.empty(db.M, np.float64)
    comb_buf = np.empty(db.M, np.int64)
    while t < T:
        mask = base if control is None or control[step] is None else control[step]
        q = ((p_prev - mu) @ U - q_lo) / q_scale - 32768
        _preselect(P, Q, Q2, np.ascontiguousarray(mask), p_prev[dims], q, scale2, delta16, delta32, delta48, lb,
                   r, pdist)
        keep = np.isfinite(pdist)
        if keep.all():
            m_ok, r_ok, pd = rows, r, pdist
        elif keep.any():
            m_ok, r_ok, pd = rows[keep], r[keep], pdist[keep]
        else:
            raise ValueError("no database window satisfies the control")
        b = F_in[t].astype(np.float64)
        fd = fd_buf[:len(m_ok)]
        _audio_distance(Fdb, F_norm, m_ok, r_ok, b, float(np.sqrt((b * b).sum(-1))), fd)
        comb = comb_buf[:len(m_ok)]
        _rank_sum(fd, pd, comb)
        key = comb * len(comb) + np.arange(len(comb))  # the stable order of comb, as unique keys
        kk = min(k, len(key) - 1)
        j = int(np.argpartition(key, kk)[kk])
        m, rr = int(m_ok[j]), int(r_ok[j])
        n = min(N_STEP, T - t)
        G.append(db.G[m, rr:rr + n])
        p_prev = db.P[m, rr + N_STEP - 1].astype(np.float64)
        picks.append((m, rr))
        t += N_STEP
        step += 1
    return np.concatenate(G), picks
