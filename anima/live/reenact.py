"""``anima reenact --live SOURCE``: live re-enactment. The actor comes from a live source (:mod:`anima.live.sources`:
a camera, a stream, or a file paced at its frame rate), is tracked frame by frame (:class:`ActorTracker`, one
frame ahead on a worker thread) and re-enacted on the target's database (:mod:`anima.reenact`); frames that
arrive while one is being processed are dropped (reported), so latency stays bounded."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.fit import LandmarkBasis, choose_keyframes, fit_frames, fit_identity
from anima.core.camera import mediapipe_to_camera
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.video import VideoWriter
from anima.live.sources import check_live_source, open_source
from anima.reenact.config import ReenactConfig
from anima.reenact.pipeline import Reenactor, Smoother
from anima.reenact.run import check_run, load_target_frames, pingpong, prepare, single_thread_blas, write_record
from anima.reenact.synth import expression_mapping
from anima.track import DEFAULT, get


def reenact_live(
    source: str,
    targets: list[str],
    out: str | None,
    cfg: ReenactConfig | None = None,
    db_path: str | None = None,
    max_seconds: float | None = None,
    progress: bool = True,
) -> dict:
    with single_thread_blas():
        return _reenact_live(source, targets, out, cfg, db_path, max_seconds, progress)


class ActorTracker:
    """The actor's expression per live frame: MediaPipe face mesh, the actor's identity fitted on its first
    ``warm`` tracked frames, a per-frame fit, and the expression mapping into the target's space from its
    first 30 fitted frames (the actor statistics so far). Call with an RGB frame; returns ``(found, x)``:
    ``found`` False when no face is tracked, ``x`` None while the identity is still being gathered."""

    def __init__(self, db, cfg: ReenactConfig, warm: int = 10, tracker: str = DEFAULT):
        self.db, self.cfg, self.warm_n = db, cfg, warm
        self.fcfg = CaptureConfig().fit
        self.basis = LandmarkBasis.build(load_face_model(), load_correspondence(), self.fcfg.use_iris)
        self.tracker = get(tracker).face_mesh(static=False)
        self.warm, self.seen, self.identity, self.mapping = [], [], None, None

    def __call__(self, rgb: np.ndarray):
        H, W = rgb.shape[:2]
        lm = self.tracker(rgb)
        if lm is None:
            return False, None
        P = mediapipe_to_camera(lm[self.basis.index][None], W, H)
        if self.identity is None:
            self.warm.append(P[0])
            if len(self.warm) < self.warm_n:
                return True, None
            Pw = np.stack(self.warm)
            self.identity = fit_identity(Pw[choose_keyframes(Pw, self.basis, min(8, len(Pw)))], self.basis, self.fcfg)
        xa = fit_frames(P, self.basis, self.identity, self.fcfg).expr[0].astype(np.float32)
        if len(self.seen) < 60:
            self.seen.append(xa)
        if self.mapping is None and self.cfg.map_expressions and len(self.seen) >= 30:
            self.mapping = expression_mapping(np.stack(self.seen), self.db.expression)
        return True, (self.mapping(xa) if self.mapping else xa)

    def close(self):
        self.tracker.close()


def ahead(items, fn, depth: int = 1):
    """Yield ``(item, fn(item))`` in order, with ``fn`` running on a worker thread up to ``depth`` items
    ahead of the consumer: the live loop tracks the next frame (MediaPipe and the fit release the GIL)
    while it re-enacts this one. An exception in the worker is raised here; closing the generator stops
    the worker."""
    import queue

    q: queue.Queue = queue.Queue(maxsize=max(1, depth))
    stop = threading.Event()
    end = object()

    def work():
        try:
            for it in items:
                if stop.is_set():
                    return
                q.put((it, fn(it), None))
        except BaseException as e:  # handed to the consumer
            q.put((None, None, e))
        q.put((end, None, None))

    th = threading.Thread(target=work, daemon=True)
    th.start()
    try:
        while True:
            it, res, err = q.get()
            if err is not None:
                raise err
            if it is end:
                return
            yield it, res
    finally:
        stop.set()
        while th.is_alive():  # unblock a worker waiting on a full queue
            try:
                q.get_nowait()
            except Exception:
                pass
            th.join(0.01)


def _reenact_live(source, targets, out, cfg, db_path, max_seconds, progress) -> dict:
    """Live loop: track the actor frame by frame (:class:`ActorTracker`, one frame ahead on a worker
    thread), re-enact on the target, write what was produced. Frames that arrive while one is being
    processed are dropped (reported), so latency stays bounded."""

    cfg = cfg or ReenactConfig()
    db, tseq = prepare(targets, db_path, progress)
    tframes, tfps = load_target_frames(targets[0])
    n_t = min(len(tframes), tseq.n_frames)
    rx = Reenactor(db, cfg)
    actor = ActorTracker(db, cfg)
    reader = open_source(source)
    writer = None
    last_x, lost_run = None, 0
    sm = Smoother(cfg.smooth)
    latencies, processed, last_i = [], 0, -1
    t_start = time.perf_counter()

    def frames():
        nonlocal last_i
        while True:
            got = reader.get(last_i)
            if got is None or (max_seconds and time.perf_counter() - t_start > max_seconds):
                return
            last_i = got[0]
            yield got

    try:
        for (_, t_cap, _rgb), (found, xa) in ahead(frames(), lambda g: actor(g[2])):
            x, alpha = last_x, 1.0
            if found:
                if xa is not None:
                    x = last_x = xa
                    lost_run = 0
            else:
                lost_run += 1
                if lost_run > cfg.hold_frames:
                    alpha = max(0.0, 1.0 - (lost_run - cfg.hold_frames) / max(cfg.fade_frames, 1))
            j = int(pingpong(np.array([int(round((time.perf_counter() - t_start) * tfps))]), n_t)[0])
            if x is None:
                items = [(None, None, (j, t_cap, 0.0))]
            else:
                col = rx.texture(x, skin=rx.target_skin(tframes, tseq, j, db.identity[0]))
                uvz = rx.geometry(x, db.identity[0], tseq.scale[j], tseq.rotation[j], tseq.translation[j])
                items = sm.push(uvz, col, (j, t_cap, alpha))
            for uvz, col, (jj, tc, al) in items:
                frame = tframes[jj] if uvz is None else rx.blend(tframes[jj], uvz, col, al)
                if out and writer is None:
                    writer = VideoWriter(out, reader.fps, (frame.shape[1], frame.shape[0]))
                if writer:
                    writer.write(frame)
                latencies.append(1e3 * (time.perf_counter() - tc))
                processed += 1
    finally:
        actor.close()
        if writer:
            writer.close()
    received = max(reader.read, last_i + 1)
    lat = np.asarray(latencies) if latencies else np.zeros(1)
    return {
        "source": str(source),
        "frames_received": int(received),
        "frames_processed": int(processed),
        "frames_dropped": int(max(0, received - processed)),
        "source_fps": reader.fps,
        "latency_ms": {"median": float(np.median(lat)), "p95": float(np.percentile(lat, 95)), "max": float(lat.max())},
        "output": out,
    }


def run(
    source: str,
    targets: list[str],
    out: str | None,
    cfg: ReenactConfig,
    db_path: str | None = None,
    max_seconds: float | None = None,
    progress: bool = True,
    allow_network: bool = False,
) -> dict:
    """``anima reenact --live SOURCE``: check every input, then re-enact the live source on the targets until it
    ends (or ``max_seconds``); with ``out``, the video and its record."""
    check_run(targets, out, live=source, db_path=db_path)
    source = check_live_source(source, allow_network)
    r = reenact_live(source, targets, out, cfg, db_path, max_seconds, progress=progress)
    if out and Path(out).is_file():
        write_record(out, source, targets, cfg, r, live=True)
    return r
