"""The re-enactment loop (seed 001 §4.1.1 steps 1-7): per actor frame, the n nearest target frames by
expression, adaptive sigma, weighted-median vertex colours, the target's identity with the actor's
expression under the target's pose and camera, rasterization, Laplacian blend, optional smoothing."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from anima.core.rotations import rotvec_to_matrix
from anima.facemodel.ict import load_face_model
from anima.io.sequence import FLAG_NO_FACE
from anima.reenact.config import ReenactConfig
from anima.reenact.database import INTERIOR, ReenactDB, sample_colors, skin_ring
from anima.reenact.render import composite, posed_uvz
from anima.reenact.synth import (
    adaptive_sigma,
    add_detail,
    color_transfer,
    expression_mapping,
    mesh_smoother,
    nearest,
    normalized_colors,
    skin_stats,
    weighted_median,
    weights,
)


@dataclass
class StageTimes:
    texture_ms: list = field(default_factory=list)
    geometry_ms: list = field(default_factory=list)
    blend_ms: list = field(default_factory=list)  # rasterize + blend


class Reenactor:
    """Stateless per-frame operations on one database (the smoothing window lives in :class:`Smoother`)."""

    def __init__(self, db: ReenactDB, cfg: ReenactConfig | None = None, model=None):
        self.db, self.cfg = db, cfg or ReenactConfig()
        model = model or load_face_model()
        self.sub = model.subset(db.vertex_ids.astype(np.int64))
        self.tris = np.ascontiguousarray(self.sub.triangles(), np.int64)  # as the rasterizer takes them
        self.deltas = np.ascontiguousarray(self.sub.expr_deltas.reshape(len(self.sub.expr_deltas), -1))
        self._shapes = {}
        self.times = StageTimes()
        self.skin = skin_ring(model, db.vertex_ids)
        self.interior = np.isin(db.vertex_ids, np.concatenate([model.region(r) for r in INTERIOR]))
        self._smoother = None
        if self.cfg.color_transfer:  # the median runs on a normalised copy (made only if used)
            mu, sd = skin_stats(db.colors, self.skin)
            self.ref = (mu.mean(0), sd.mean(0))  # the common reference: the database's average skin
            self.colors = normalized_colors(db.colors, mu, sd, *self.ref)
        else:
            self.colors = db.colors

    def frame_skin(self, frame: np.ndarray, uvz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Skin statistics of a target frame under its own fitted geometry ``uvz`` (where the output goes)."""
        return skin_stats(sample_colors(frame, uvz[:, :2]), self.skin)

    def shape(self, identity: np.ndarray) -> np.ndarray:
        key = identity.tobytes()
        if key not in self._shapes:
            self._shapes[key] = self.sub.vertices(identity)
        return self._shapes[key]

    def texture(self, x: np.ndarray, n: int | None = None, skin=None) -> np.ndarray:
        """Weighted-median colours ``(V, 3)`` for expression ``x`` (seed eqs. 3.3-3.4, Listing 1). With colour
        transfer on, the median is taken over colours moved to the common reference and moved to ``skin``
        (the output frame's :meth:`frame_skin`; without it the result stays at the reference)."""
        t0 = time.perf_counter()
        idx, d2 = nearest(self.db.expression, x, n or self.cfg.n)
        sigma = adaptive_sigma(d2, idx, self.cfg.a)
        w = weights(d2[idx], sigma)
        out = weighted_median(self.colors, idx, w)
        if self.cfg.detail > 0:
            if self._smoother is None:
                self._smoother = mesh_smoother(self.tris, len(self.db.vertex_ids))
            best = self.colors[idx[int(np.argmax(w))]]
            out = add_detail(out, best, self._smoother, self.interior, self.cfg.detail)
        if self.cfg.color_transfer and skin is not None:
            out = np.clip(color_transfer(out, *self.ref, *skin), 0, 255)
        self.times.texture_ms.append(1e3 * (time.perf_counter() - t0))
        return out

    def geometry(
        self, x: np.ndarray, identity: np.ndarray, scale: float, rotation: np.ndarray, translation: np.ndarray
    ) -> np.ndarray:
        """The target's identity with expression ``x`` under the target frame's pose and camera -> uvz."""
        t0 = time.perf_counter()
        uvz = self._posed(x, identity, scale, rotation, translation)
        self.times.geometry_ms.append(1e3 * (time.perf_counter() - t0))
        return uvz

    def _posed(self, x, identity, scale, rotation, translation) -> np.ndarray:
        V = self.shape(identity) + (np.asarray(x, np.float32) @ self.deltas).reshape(-1, 3)
        return posed_uvz(V, float(scale), rotvec_to_matrix(np.asarray(rotation, np.float64)), translation)

    def target_skin(self, frames, seq, j: int, identity: np.ndarray):
        """The skin statistics of target frame ``j`` (``frames[j]`` under ``seq``'s own fit of that frame;
        a badly tracked frame takes its nearest well-tracked one's), cached per frame; None when colour
        transfer is off or nothing is tracked."""
        if not self.cfg.color_transfer:
            return None
        cache = self.__dict__.setdefault("_skin_cache", {})
        if id(seq) != cache.get("seq"):
            cache.clear()
            cache["seq"] = id(seq)
            cache["good"] = np.flatnonzero(seq.flags[: len(frames)] == 0)
        good = cache["good"]
        if not len(good):
            return None
        k = int(good[np.argmin(np.abs(good - j))])
        if k not in cache:
            uvz = self._posed(seq.expression[k], identity, seq.scale[k], seq.rotation[k], seq.translation[k])
            cache[k] = self.frame_skin(frames[k], uvz)
        return cache[k]

    def blend(self, target: np.ndarray, uvz: np.ndarray, colors: np.ndarray, alpha: float = 1.0) -> np.ndarray:
        t0 = time.perf_counter()
        c = self.cfg
        out = composite(target, uvz, self.tris, colors, c.levels, c.erode, c.blur, alpha)
        self.times.blend_ms.append(1e3 * (time.perf_counter() - t0))
        return out


class Smoother:
    """eq. 3.5 as a centred window over (uvz, colours), streaming: frame k is emitted, averaged over frames
    k - T//2 .. k + T//2 that exist, once frame k + T//2 has been pushed (latency T//2 frames); ``flush``
    emits the tail. T <= 1 passes frames through (method 1)."""

    def __init__(self, T: int):
        self.half = max(int(T), 1) // 2
        self.buf: deque = deque()  # (index, uvz, colors, payload)
        self.count = 0
        self.next = 0

    def _emit(self, k: int):
        while self.buf and self.buf[0][0] < k - self.half:
            self.buf.popleft()
        items = [b for b in self.buf if b[0] <= k + self.half]
        center = next(b for b in items if b[0] == k)
        if len(items) == 1:
            return center[1], center[2], center[3]
        return np.mean([b[1] for b in items], 0), np.mean([b[2] for b in items], 0), center[3]

    def push(self, uvz, colors, payload) -> list:
        self.buf.append((self.count, uvz, colors, payload))
        self.count += 1
        out = []
        while self.next + self.half < self.count:
            out.append(self._emit(self.next))
            self.next += 1
        return out

    def flush(self) -> list:
        out = []
        while self.next < self.count:
            out.append(self._emit(self.next))
            self.next += 1
        self.buf.clear()
        return out


def actor_expressions(actor_seq, db: ReenactDB, cfg: ReenactConfig) -> tuple[np.ndarray, np.ndarray]:
    """Actor expressions mapped into the target's space (when ``cfg.map_expressions``), and per-frame
    blend alpha: 1 when the face is tracked; held then faded when the actor's face is lost."""
    x = actor_seq.expression.astype(np.float32)
    lost = (actor_seq.flags & FLAG_NO_FACE) > 0
    if cfg.map_expressions:
        f = expression_mapping(x[~lost] if (~lost).any() else x, db.expression)
        x = f(x)
    alpha = np.ones(len(x), np.float32)
    last, run = None, 0
    for i in range(len(x)):
        if not lost[i]:
            last, run = x[i].copy(), 0
            continue
        run += 1
        if last is not None:
            x[i] = last
        if last is None or run > cfg.hold_frames:
            alpha[i] = 0.0 if last is None else max(0.0, 1.0 - (run - cfg.hold_frames) / max(cfg.fade_frames, 1))
    return x, alpha
