"""``anima reenact``: offline (actor video -> output video) and live (camera index, stream or a file paced at
its real frame rate) re-enactment on a target database."""

from __future__ import annotations

import dataclasses
import threading
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.fit import LandmarkBasis, choose_keyframes, fit_frames, fit_identity
from anima.capture.mediapipe_face import FaceMeshTracker
from anima.capture.pipeline import capture_face
from anima.core.camera import mediapipe_to_camera
from anima.errors import InputError
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io import owned
from anima.io.atomic import write_json
from anima.io.live_source import PacedReader, check_live_source
from anima.io.outdir import check_out_file
from anima.io.owned import record_of
from anima.io.validate import input_file, read_json
from anima.io.video import VideoWriter, iter_frames, probe_video
from anima.reenact.config import ReenactConfig
from anima.reenact.database import build_database, read_database, write_database
from anima.reenact.pipeline import Reenactor, Smoother, actor_expressions
from anima.reenact.synth import expression_mapping

MAX_TARGET_BYTES = 1 << 30


VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv", ".m4v")
RECORD_SCHEMA = "anima.reenact_run"
DB_NPZ = owned.npz("expression", "colors", "vertex_ids", "meta")  # a database `--db` may read or be written to


def _is_record(path: Path) -> bool:
    """Whether ``path`` is a re-enactment record anima wrote (the only file ``--out``'s record may replace)."""
    try:
        d = read_json(path, "record", max_bytes=10_000_000)
    except InputError:
        return False
    return isinstance(d, dict) and d.get("schema") == RECORD_SCHEMA


def pingpong(j: np.ndarray, n: int) -> np.ndarray:
    """Map any frame index onto 0..n-1 going forth and back (no jump when the target is shorter)."""
    if n <= 1:
        return np.zeros_like(j)
    p = 2 * (n - 1)
    j = np.mod(j, p)
    return np.where(j < n, j, p - j)


def load_target_frames(path: str) -> tuple[np.ndarray, float]:
    info = probe_video(path)
    cap = max(1, MAX_TARGET_BYTES // (info.width * info.height * 3))
    frames = []
    for i, f in enumerate(iter_frames(info)):
        if i >= cap:
            warnings.warn(f"target background limited to its first {cap} frames (memory)", stacklevel=2)
            break
        frames.append(f)
    return np.stack(frames), info.fps


def side_by_side(actor: np.ndarray, out: np.ndarray) -> np.ndarray:
    h = out.shape[0]
    a = cv2.resize(actor, (max(2, int(round(actor.shape[1] * h / actor.shape[0]))), h))
    return np.concatenate([a, out], 1)


def prepare(targets: list[str], db_path: str | None, progress: bool, max_frames: int | None = None):
    """Database (built from ``targets``, or read from ``db_path`` if it exists) and the first target's
    sequence (its pose per frame drives the background)."""
    if db_path and Path(db_path).exists():
        db = read_database(db_path)
        if Path(db.meta["videos"][0]["path"]).resolve() != Path(targets[0]).resolve():
            raise InputError(
                f"{db_path} was built from {db.meta['videos'][0]['path']}, not {targets[0]}: use another --db path"
            )
        seq0 = capture_face(str(targets[0]), CaptureConfig(max_frames=max_frames), progress=progress)
        return db, seq0
    db, seqs = build_database([str(t) for t in targets], max_frames, progress)
    if db_path:
        write_database(db, db_path)
    return db, seqs[0]


def single_thread_blas():
    """The per-frame maths are small matrices: multi-threaded BLAS only fights numba's threads for the two
    cores (it made the per-frame fit 12x slower). One BLAS thread during the loop."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(1, user_api="blas")


def reenact_video(
    actor: str,
    targets: list[str],
    out: str,
    cfg: ReenactConfig | None = None,
    sbs: bool = False,
    db_path: str | None = None,
    progress: bool = True,
) -> dict:
    with single_thread_blas():
        return _reenact_video(actor, targets, out, cfg, sbs, db_path, progress)


def _reenact_video(actor, targets, out, cfg, sbs, db_path, progress) -> dict:
    from tqdm import tqdm

    cfg = cfg or ReenactConfig()
    ainfo = probe_video(actor)
    db, tseq = prepare(targets, db_path, progress)
    aseq = capture_face(actor, progress=progress)
    x, alpha = actor_expressions(aseq, db, cfg)
    tframes, tfps = load_target_frames(targets[0])
    n_t = min(len(tframes), tseq.n_frames)
    j_of_i = pingpong(np.round(np.arange(aseq.n_frames) / aseq.fps * tfps).astype(int), n_t)
    rx = Reenactor(db, cfg)
    vi0 = 0
    identity = db.identity[vi0]
    audio = actor if ainfo.has_audio else None
    notes = [] if audio else ["the actor video has no audio track: the output is silent"]
    if abs(ainfo.fps - tfps) > 0.01:
        notes.append(
            f"frame rates differ (actor {ainfo.fps:.2f}, target {tfps:.2f}): target frames are "
            "picked by time at the actor's rate"
        )
    H, W = tframes.shape[1:3]
    size = (W + (int(round(ainfo.width * H / ainfo.height)) if sbs else 0), H)
    sm = Smoother(cfg.smooth)
    t0 = time.perf_counter()
    n_out = 0
    with VideoWriter(out, aseq.fps, size, audio_path=audio) as vw:

        def emit(items):
            nonlocal n_out
            for uvz, col, (j, a_rgb, al) in items:
                frame = rx.blend(tframes[j], uvz, col, al)
                vw.write(side_by_side(a_rgb, frame) if sbs else frame)
                n_out += 1

        for i, a_rgb in enumerate(
            tqdm(iter_frames(ainfo), total=aseq.n_frames, disable=not progress, desc="re-enact", unit="frame")
        ):
            if i >= aseq.n_frames:
                break
            j = int(j_of_i[i])
            col = rx.texture(x[i], skin=rx.target_skin(tframes, tseq, j, identity))
            uvz = rx.geometry(x[i], identity, tseq.scale[j], tseq.rotation[j], tseq.translation[j])
            emit(sm.push(uvz, col, (j, a_rgb if sbs else None, float(alpha[i]))))
        emit(sm.flush())
    wall = time.perf_counter() - t0
    return {
        "output": str(out),
        "frames": n_out,
        "fps": aseq.fps,
        "size": list(size),
        "audio": bool(audio),
        "database_frames": db.n,
        "render_wall_s": round(wall, 2),
        "notes": notes,
        "mean_ms": {k: float(np.mean(v)) for k, v in vars(rx.times).items() if v},
    }


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

    def __init__(self, db, cfg: ReenactConfig, warm: int = 10):
        self.db, self.cfg, self.warm_n = db, cfg, warm
        self.fcfg = CaptureConfig().fit
        self.basis = LandmarkBasis.build(load_face_model(), load_correspondence(), self.fcfg.use_iris)
        self.tracker = FaceMeshTracker(static_image_mode=False)
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
    reader = PacedReader(source)
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
    targets: list[str],
    out: str | None,
    cfg: ReenactConfig,
    actor: str | None = None,
    live: str | None = None,
    sbs: bool = False,
    db_path: str | None = None,
    max_seconds: float | None = None,
    progress: bool = True,
    allow_network: bool = False,
) -> dict:
    """``anima reenact``: check every input, then re-enact an actor video (or a live source) on the targets.
    ``out`` must be a video name that is none of the inputs; its record (``OUT.json``) may only replace an
    earlier record."""
    if not actor and live is None:
        raise InputError("give --actor VIDEO or --live SOURCE")
    if actor and live is not None:
        raise InputError("give --actor or --live, not both")
    if actor and not out:
        raise InputError("give --out OUT.mp4")
    for t in targets:
        probe_video(input_file(t, "target video"))
    if actor:
        probe_video(input_file(actor, "actor video"))
    if live is not None:
        live = check_live_source(live, allow_network)
    inputs = [*targets, actor, db_path] if actor else [*targets, db_path]
    if out:  # a video anima wrote (its record names its sha256) or a new name; the record likewise
        check_out_file(out, inputs=inputs, suffixes=VIDEO_SUFFIXES, ours=owned.video, what="a video")
        check_out_file(record_of(out), "--out (its record)", inputs=inputs, ours=_is_record, what="a record")
    if db_path:  # read when it exists (an anima database), else written
        check_out_file(db_path, "--db", inputs=[*targets, actor, out], suffixes=(".npz",), ours=DB_NPZ,
                       what="a re-enactment database")  # fmt: skip
    if live is not None:
        r = reenact_live(live, targets, out, cfg, db_path, max_seconds, progress=progress)
    else:
        r = reenact_video(actor, targets, out, cfg, sbs, db_path, progress=progress)
    if out and Path(out).is_file():
        write_json(
            record_of(out),
            {
                "schema": RECORD_SCHEMA,
                "version": 1,
                "actor": str(actor if actor else live),
                "live": live is not None,
                "targets": [str(t) for t in targets],
                "side_by_side": sbs,
                "config": dataclasses.asdict(cfg),
                "result": r,
                "video_sha256": owned.sha256(Path(out)),  # what lets a later run replace this video
            },
        )
    return r
