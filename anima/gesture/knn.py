"""Audio-to-gesture k-NN search with control (seed 004 §5.3.1.3, Algorithm 1, §5.3.2.1).

Database: M windows of T_MATCH = 64 frames, each with audio features F (64, 112), pose features P (64, 96)
and gestures G (64, 165). Every N = 8 frames: per database window, the frame r whose pose feature is closest
(Euclidean) to the previous pose feature among the frames allowed by the control mask ("pose pre-selected");
then the M candidates are ranked by audio (cosine distance of f at r to the input f_t) and by pose, the two
ranks are added, and the k-th best candidate (0 = best) gives the next N frames.

Three readings of the algorithm's text are made explicit here (both implementations follow them):
* a candidate start r is matched on the pose feature of frame r - 1 (:attr:`MatchDB.P_match`): the previous
  output's last frame is compared with the frame *before* the start, so a window that continues goes on
  from r + N. Matching frame r itself (the literal reading) made the best candidate repeat the last output
  frame at 20-33 % of the joins;
* a window can only start where N frames fit (r <= T_MATCH - N), so that N output frames exist;
* a database window with no frame allowed by the control is not a candidate (Algorithm 1 would keep its
  frame 0, which breaks the control).
Optionally (``stroke``, :mod:`anima.gesture.strokes`; not in the seed), a third rank is added: how close each
candidate's wrist-speed peaks fall to the speech's stresses in the step.
Control masks require every frame of the N-frame window to satisfy the control (a departure: the seed's
§5.3.2.1 looks at its first and last frame only, ``every_frame=False``; see :meth:`MatchDB.start_mask`).

:func:`search_literal` is Algorithm 1 with its loops; :func:`search` is the fast version (all windows and
frames at once; exact distances in float64 like the literal one, float32 only inside a lower bound with its
error margin) and returns identical output.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numba as nb
import numpy as np

from anima.core.contract import GESTURE_FPS
from anima.gesture.features import N_STEP, T_MATCH
from anima.gesture.post import one_skeleton, skeleton_lengths
from anima.gesture.strokes import StrokeTerm, stroke_distance

MIRROR = "#mirror"  # the source name of a mirrored copy of a video's motion: "video#mirror" (a library's variants)
N_PROJ = 48  # principal directions of the pose feature used for the lower bounds
N_FIRST = 24  # of which the first bound reads the first 24 for every frame


class _Layout(NamedTuple):
    P: np.ndarray  # (M, T, 96) pose features, dimensions in ``dims`` order
    dims: np.ndarray
    U: np.ndarray  # (96, 48) principal directions
    mu: np.ndarray  # (96,) mean pose feature
    Qa: np.ndarray  # (M, 24, T) int8: directions 1-24, value = Qa * step_a[m] + lo_a[m]
    lo_a: np.ndarray  # (M, 24)
    step_a: np.ndarray  # (M, 24)
    err_a: np.ndarray  # (M,) largest rounding distance over directions 1-24 of the window's frames
    Qb: np.ndarray  # (M, T, 24) int8: directions 25-48
    lo_b: np.ndarray
    step_b: np.ndarray
    err: np.ndarray  # (M,) largest rounding distance over directions 1-48


@dataclass
class MatchDB:
    F: np.ndarray  # (M, T, 112)
    P: np.ndarray  # (M, T, 96)
    G: np.ndarray  # (M, T, 165)
    source: list = field(default_factory=list)  # per window: (video, start_s)
    S: np.ndarray | None = None  # (M, T, 28) per-frame speech features (for the cGAN refiner)
    fps: float = GESTURE_FPS  # the windows' frame rate (from the data)
    rate: np.ndarray | None = None  # (M,) source frames per frame: a speed-varied copy's (None: all 1)

    _layout: _Layout | None = None

    @property
    def M(self) -> int:
        return len(self.F)

    def subset(self, idx) -> MatchDB:
        """The windows ``idx`` (indices or a boolean mask) as a new database."""
        idx = np.flatnonzero(idx) if np.asarray(idx).dtype == bool else np.asarray(idx, int)
        return MatchDB(
            self.F[idx],
            self.P[idx],
            self.G[idx],
            [self.source[i] for i in idx] if self.source else [],
            None if self.S is None else self.S[idx],
            self.fps,
            None if self.rate is None else self.rate[idx],
        )

    @property
    def P_match(self) -> np.ndarray:
        """The pose feature each window start is matched on: for a start at frame s, the feature of frame
        s - 1, the frame the output would have come from. The last output frame's feature then matches the
        frame that follows it (distance 0 when the same window continues), so the search continues from
        r + N instead of repeating frame r + N - 1."""
        if getattr(self, "_pm", None) is None:
            self._pm = np.ascontiguousarray(np.concatenate([self.P[:, :1], self.P[:, :-1]], 1))
        return self._pm

    @property
    def video_frames(self) -> tuple[np.ndarray, np.ndarray]:
        """Per window: its video (an index; a mirrored copy, source ``video#mirror``, counts as ``video``) and
        its first frame in that video's timeline (for a speed-varied copy, the source frame of its first frame;
        :attr:`rate` source frames per frame from there)."""
        if getattr(self, "_vf", None) is None:
            key = [v.removesuffix(MIRROR) for v, _ in self.source]
            names = sorted(set(key))
            vid = np.array([names.index(v) for v in key]) if self.source else np.arange(self.M)
            f0 = np.array([round(t * self.fps) for _, t in self.source]) if self.source else np.zeros(self.M, int)
            self._vf = (vid, f0)
        return self._vf

    @property
    def bone_lengths(self) -> np.ndarray:
        """The database's skeleton: each bone's median length over all its frames (``[55]``, metres); every
        output is re-posed on it, so switching between speakers does not change the body's size."""
        if getattr(self, "_lengths", None) is None:
            self._lengths = skeleton_lengths(self.G.reshape(self.M, self.G.shape[1], -1, 3))
        return self._lengths

    @property
    def G_rig(self) -> np.ndarray:
        """The windows' joints re-posed on :attr:`bone_lengths` (``[M, T, 165]``), as every output is: what
        the controls' percentiles and masks are measured on, so a threshold means the same on the database
        and on the output."""
        if getattr(self, "_g_rig", None) is None:
            J = self.G.reshape(self.M * self.G.shape[1], -1, 3)
            self._g_rig = one_skeleton(J, self.bone_lengths).reshape(self.G.shape)
        return self._g_rig

    @property
    def stroke_dist(self) -> np.ndarray:
        """Per window and frame, the distance (frames, capped) to the window's nearest gesture stroke
        (:func:`anima.gesture.strokes.stroke_distance`): the search's stroke term reads it."""
        if getattr(self, "_stroke_dist", None) is None:
            self._stroke_dist = stroke_distance(self.G, self.fps)
        return self._stroke_dist

    def audio_norms(self) -> np.ndarray:
        """|f| per database frame, computed as the literal search computes it (float64, per row)."""
        if getattr(self, "_fnorm", None) is None:
            F = self.F.astype(np.float64)
            self._fnorm = np.sqrt((F * F).sum(-1))
        return self._fnorm

    def search_layout(self) -> _Layout:
        """Made once for the fast search: the pose features with their dimensions reordered by decreasing
        variance (the partial distance search stops early while reading rows sequentially), and their
        centred projection on the 48 leading principal directions, quantised to int8 per window and
        direction (a window's 64 frames span a small part of each direction's range, so 256 levels are
        fine: the rounding moves a frame by about 0.002 where the nearest frame is about 0.9 away). The
        first 24 directions are stored [M, 24, T], a lower bound read for every frame (24 bytes per frame),
        the other 24 [M, T, 24], read only for the frames the first bound keeps."""
        if self._layout is None:
            P = self.P_match
            sample = P.reshape(-1, P.shape[-1])[:: max(1, P.shape[0] * P.shape[1] // 20000)].astype(np.float64)
            dims = np.argsort(-sample.var(0), kind="stable")
            mu = sample.mean(0)
            _, _, Vt = np.linalg.svd(sample - mu, full_matrices=False)
            U = np.ascontiguousarray(Vt[:N_PROJ].T)  # (96, 48) orthonormal columns
            lo = np.empty((self.M, N_PROJ))
            step = np.empty((self.M, N_PROJ))
            Qi = np.empty(P.shape[:2] + (N_PROJ,), np.int8)
            err_a = np.empty(self.M)
            err = np.empty(self.M)
            for c in range(0, self.M, 4096):  # in chunks: the float64 projection of 600,000 frames is 230 MB
                X = (P[c : c + 4096].astype(np.float64) - mu) @ U
                lo_c = X.min(1)
                step_c = np.maximum(X.max(1) - lo_c, 1e-12) / 255
                q = np.round((X - lo_c[:, None]) / step_c[:, None] - 128).clip(-128, 127)
                e2 = ((q + 128) * step_c[:, None] + lo_c[:, None] - X) ** 2
                err_a[c : c + 4096] = np.sqrt(e2[..., :N_FIRST].sum(-1)).max(1)
                err[c : c + 4096] = np.sqrt(e2.sum(-1)).max(1)
                Qi[c : c + 4096] = q
                lo[c : c + 4096] = lo_c + 128 * step_c  # value = integer * step + lo
                step[c : c + 4096] = step_c
            self._layout = _Layout(
                np.ascontiguousarray(P[..., dims]),
                dims,
                U,
                mu,
                np.ascontiguousarray(Qi[..., :N_FIRST].transpose(0, 2, 1)),
                np.ascontiguousarray(lo[:, :N_FIRST]),
                np.ascontiguousarray(step[:, :N_FIRST]),
                err_a,
                np.ascontiguousarray(Qi[..., N_FIRST:]),
                np.ascontiguousarray(lo[:, N_FIRST:]),
                np.ascontiguousarray(step[:, N_FIRST:]),
                err,
            )
        return self._layout

    def start_mask(self, frame_mask: np.ndarray | None, every_frame: bool = True) -> np.ndarray:
        """(M, T) frame eligibility -> (M, T) window-start eligibility: the window inside the database window
        and every one of its N frames allowed (``every_frame=False``: its first and last frame, the seed's
        §5.3.2.1, which lets the frames between them break the control: a wrist-speed control then held on
        about half of the output's frames)."""
        M, T = self.P.shape[:2]
        ok = np.zeros((M, T), bool)
        ok[:, 1 : T - N_STEP + 1] = True  # s = 1 .. T - N (Algorithm 1 starts at s = 1)
        if frame_mask is not None:
            fm = np.asarray(frame_mask, bool)
            if every_frame:  # number of allowed frames in [s, s + N) == N
                c = np.concatenate([np.zeros((M, 1), np.int32), np.cumsum(fm, 1, dtype=np.int32)], 1)
                allowed = np.zeros_like(fm)
                allowed[:, : T - N_STEP + 1] = (c[:, N_STEP:] - c[:, : T - N_STEP + 1]) == N_STEP
                ok &= allowed
            else:
                last = np.zeros_like(fm)
                last[:, : T - N_STEP + 1] = fm[:, N_STEP - 1 :]
                ok &= fm & last
        return ok


def _relrank(d: np.ndarray) -> np.ndarray:
    r = np.empty(len(d), np.int64)
    r[np.argsort(d, kind="stable")] = np.arange(len(d))
    return r


def _cosine(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    na = np.sqrt((a * a).sum(-1))
    nb = np.sqrt((b * b).sum(-1))
    return 1.0 - (a * b).sum(-1) / np.maximum(na * nb, 1e-12)


def recent_mask(db: MatchDB, picks: list, mask: np.ndarray, steps: int) -> np.ndarray:
    """``mask`` without the starts whose N frames would replay source frames output in the last ``steps``
    steps (same video, overlapping frames; a speed-varied copy's frames are mapped back to its source's through
    :attr:`MatchDB.rate`): the output cannot loop over one stretch of motion. A continuation is never affected
    (its frames are new). Where that leaves no candidate, the same over the last half as many steps, and so on
    (at 0, ``mask`` as it was). Not in the seed (its database had hours of windows to choose from); 0 turns it
    off."""
    while steps > 0 and picks:
        out = _without_recent(db, picks[-steps:], mask)
        if out.any():
            return out
        steps //= 2
    return mask


def _without_recent(db: MatchDB, recent: list, mask: np.ndarray) -> np.ndarray:
    vid, f0 = db.video_frames
    out = mask.copy()
    s = np.arange(mask.shape[1])
    if db.rate is None:
        for m, r in recent:
            e = f0[m] + r  # first source frame of that step
            same = vid == vid[m]
            start = f0[same][:, None] + s[None]
            out[same] &= ~((start > e - N_STEP) & (start < e + N_STEP))
        return out
    rate = np.asarray(db.rate, np.float64)
    for m, r in recent:  # source frames [a, b) of that step against each start's [a', b')
        a = f0[m] + r * rate[m]
        b = a + N_STEP * rate[m]
        same = vid == vid[m]
        start = f0[same][:, None] + s[None] * rate[same][:, None]
        out[same] &= ~((start < b) & (start + N_STEP * rate[same][:, None] > a))
    return out


def search_literal(
    db: MatchDB,
    F_in: np.ndarray,
    k: int,
    p_init: np.ndarray,
    control: list | None = None,
    no_repeat_steps: int = 0,
    stroke: StrokeTerm | None = None,
) -> tuple[np.ndarray, list]:
    """Algorithm 1 as written (Python loops). ``control``: per search step a (M, T) window-start mask or
    None; ``no_repeat_steps``: see :func:`recent_mask`; ``stroke``: a third rank, the candidates' stroke
    alignment with the step's stresses (:class:`anima.gesture.strokes.StrokeTerm`; None: the seed's two ranks).
    Returns the gestures (T, 165) and the chosen (window, frame) per step."""
    T = len(F_in)
    G, picks = [], []
    p_prev = np.asarray(p_init, np.float64)
    t = 0
    step = 0
    while t < T:
        mask = db.start_mask(None) if control is None or control[step] is None else control[step]
        mask = recent_mask(db, picks, mask, no_repeat_steps)
        cand, pd, fd = [], [], []
        for m in range(db.M):
            r, pdist = -1, np.inf
            for s in range(1, T_MATCH):
                if mask[m, s]:  # the pose feature of frame s - 1 (MatchDB.P_match): the output continues at s
                    d = float(np.sqrt(((db.P_match[m, s].astype(np.float64) - p_prev) ** 2).sum()))
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
        cm, cr = np.array([c[0] for c in cand]), np.array([c[1] for c in cand])
        extra = None if stroke is None else stroke.ranks(step, cm, cr)
        if extra is not None:
            comb = comb + extra
        order = np.argsort(comb, kind="stable")
        m, r = cand[int(order[min(k, len(order) - 1)])]
        n = min(N_STEP, T - t)
        G.append(db.G[m, r : r + n])
        p_prev = db.P[m, r + N_STEP - 1].astype(np.float64)
        picks.append((m, r))
        t += N_STEP
        step += 1
    return np.concatenate(G), picks


@nb.njit(parallel=True, cache=True)
def _preselect(P, Qa, lo_a, step_a, err_a, Qb, lo_b, step_b, err, mask, p, proj, lb, qb_work, r_out, d_out):
    """Per window m: the allowed frame s closest to ``p`` (squared Euclidean, float64), exactly, ties to the
    smallest s (as the literal loop's strict ``<``). The centred features' projections on orthonormal
    principal directions give lower bounds of the true distance (``proj``: the query's); stored rounded
    (see :meth:`MatchDB.search_layout`), they are still bounds once the rounding distance (``err_a`` over
    directions 1-24, ``err`` over 1-48) is taken off. The frame with the smallest 24-direction bound is
    measured first; frames whose 24- or 48-direction bound exceeds the best distance so far are skipped,
    and full sums (dimensions stored largest-variance first) stop once they exceed it. None of this can
    change the result. ``lb`` (M, T, float32) and ``qb_work`` (M, 2, 24) are work arrays.

    The 24-direction bound, read for every frame, is summed in float32 (twice the SIMD width): the query
    rounded to float32 moves by at most ``eq`` (added to the rounding distance), and the float32 sum of 24
    terms is within a relative 2e-6 of the exact one (taken off with a 1e-5 margin), so it stays a bound."""
    M, T, D = P.shape
    KA = Qa.shape[1]
    KB = Qb.shape[2]
    for m in nb.prange(M):
        # Qa is direction-major per window: the bound of all T frames is accumulated one direction at a
        # time, a loop over contiguous frames that the compiler vectorises
        for s in range(T):
            lb[m, s] = 0.0
        eq = 0.0
        for j in range(KA):
            sj = step_a[m, j]
            qj = (proj[j] - lo_a[m, j]) / sj
            eq += abs(qj) * sj * 6.0e-8  # >= |float32(qj) - qj| * step (2^-24 relative), summed: >= the L2 norm
            qj32 = np.float32(qj)
            sj32 = np.float32(sj * sj)
            for s in range(T):
                diff = np.float32(Qa[m, j, s]) - qj32
                lb[m, s] += sj32 * diff * diff
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
        # skip s when sqrt(bound) - err > sqrt(best), i.e. bound > (sqrt(best) + err)^2 (with a margin for
        # the float64 arithmetic)
        ea, eb = err_a[m] + eq, err[m] + eq
        sb = np.sqrt(best)
        cut_a = (sb + ea) ** 2 * (1.0 + 1e-5) + 1e-12
        cut_b = (sb + eb) ** 2 * (1.0 + 1e-9) + 1e-12
        qb, s2 = qb_work[m, 0], qb_work[m, 1]
        ready = False
        for s in range(T):
            if s == s0 or not mask[m, s] or lb[m, s] > cut_a:
                continue
            if not ready:  # the query in directions 25-48, in this window's units
                for j in range(KB):
                    qb[j] = (proj[KA + j] - lo_b[m, j]) / step_b[m, j]
                    s2[j] = step_b[m, j] * step_b[m, j]
                ready = True
            acc = np.float64(lb[m, s]) * (1.0 - 1e-5)
            for j in range(KB):
                diff = np.float64(Qb[m, s, j]) - qb[j]
                acc += s2[j] * diff * diff
            if acc > cut_b:
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
                cut_a = (sb + ea) ** 2 * (1.0 + 1e-5) + 1e-12
                cut_b = (sb + eb) ** 2 * (1.0 + 1e-9) + 1e-12
        r_out[m] = r
        d_out[m] = np.sqrt(best)


@nb.njit(inline="always")
def _pairwise_dot(F, m, r, b):
    """sum_j float64(F[m, r, j]) * b[j], added in numpy's pairwise order for rows of 8 to 128 values (eight
    running sums, combined as ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7)), then the remainder), so the
    result is bit-identical to the literal search's ``(a * b).sum(-1)``."""
    n = b.shape[0]
    a0 = np.float64(F[m, r, 0]) * b[0]
    a1 = np.float64(F[m, r, 1]) * b[1]
    a2 = np.float64(F[m, r, 2]) * b[2]
    a3 = np.float64(F[m, r, 3]) * b[3]
    a4 = np.float64(F[m, r, 4]) * b[4]
    a5 = np.float64(F[m, r, 5]) * b[5]
    a6 = np.float64(F[m, r, 6]) * b[6]
    a7 = np.float64(F[m, r, 7]) * b[7]
    i = 8
    stop = n - (n % 8)
    while i < stop:
        a0 += np.float64(F[m, r, i]) * b[i]
        a1 += np.float64(F[m, r, i + 1]) * b[i + 1]
        a2 += np.float64(F[m, r, i + 2]) * b[i + 2]
        a3 += np.float64(F[m, r, i + 3]) * b[i + 3]
        a4 += np.float64(F[m, r, i + 4]) * b[i + 4]
        a5 += np.float64(F[m, r, i + 5]) * b[i + 5]
        a6 += np.float64(F[m, r, i + 6]) * b[i + 6]
        a7 += np.float64(F[m, r, i + 7]) * b[i + 7]
        i += 8
    res = ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7))
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


def _stable_argsort(x: np.ndarray) -> np.ndarray:
    """``np.argsort(x, kind="stable")``, faster: numpy's (vectorised) quicksort, whose order differs from the
    stable one only among equal values; those (and NaN) are rare, and then the stable sort is used."""
    order = np.argsort(x)
    v = x[order]
    if len(v) > 1 and ((v[1:] == v[:-1]).any() or np.isnan(v[-1])):
        return np.argsort(x, kind="stable")
    return order


def _rank_sum(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out = relrank(a) + relrank(b)``: positions in the stable orders of ``a`` and ``b``."""
    idx = np.arange(len(a))
    out[_stable_argsort(a)] = idx
    rb = np.empty_like(out)
    rb[_stable_argsort(b)] = idx
    out += rb


def search(
    db: MatchDB,
    F_in: np.ndarray,
    k: int,
    p_init: np.ndarray,
    control: list | None = None,
    no_repeat_steps: int = 0,
    stroke: StrokeTerm | None = None,
) -> tuple[np.ndarray, list]:
    """The same search, fast: a numba pass over all windows and frames per step (partial distance search),
    then the ranking on the M pre-selected candidates. Identical output to :func:`search_literal`."""
    T = len(F_in)
    Fdb = db.F
    base = db.start_mask(None)
    L = db.search_layout()
    qb_work = np.empty((db.M, 2, N_PROJ - N_FIRST))
    F_norm = db.audio_norms()
    lb = np.empty(L.P.shape[:2], np.float32)
    G, picks = [], []
    p_prev = np.asarray(p_init, np.float64)
    t = 0
    step = 0
    rows = np.arange(db.M)
    r = np.empty(db.M, np.int64)
    pdist = np.empty(db.M, np.float64)
    fdist = np.empty(db.M, np.float64)
    comb_buf = np.empty(db.M, np.int64)
    while t < T:
        mask = base if control is None or control[step] is None else control[step]
        mask = recent_mask(db, picks, mask, no_repeat_steps)
        _preselect(
            L.P,
            L.Qa,
            L.lo_a,
            L.step_a,
            L.err_a,
            L.Qb,
            L.lo_b,
            L.step_b,
            L.err,
            np.ascontiguousarray(mask),
            p_prev[L.dims],
            (p_prev - L.mu) @ L.U,
            lb,
            qb_work,
            r,
            pdist,
        )
        keep = r >= 0
        if keep.all():
            m_ok, r_ok, pd = rows, r, pdist
        elif keep.any():
            m_ok, r_ok, pd = rows[keep], r[keep], pdist[keep]
        else:
            raise ValueError("no database window satisfies the control")
        b = F_in[t].astype(np.float64)
        fd = fdist[: len(m_ok)]
        _audio_distance(Fdb, F_norm, m_ok, r_ok, b, float(np.sqrt((b * b).sum(-1))), fd)
        comb = comb_buf[: len(m_ok)]
        _rank_sum(fd, pd, comb)
        extra = None if stroke is None else stroke.ranks(step, m_ok, r_ok)
        if extra is not None:
            comb = comb + extra
        key = comb * len(comb) + np.arange(len(comb))  # the stable order of comb, as unique keys
        kk = min(k, len(key) - 1)
        j = int(np.argpartition(key, kk)[kk])
        m, rr = int(m_ok[j]), int(r_ok[j])
        n = min(N_STEP, T - t)
        G.append(db.G[m, rr : rr + n])
        p_prev = db.P[m, rr + N_STEP - 1].astype(np.float64)
        picks.append((m, rr))
        t += N_STEP
        step += 1
    return np.concatenate(G), picks
