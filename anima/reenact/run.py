"""``anima reenact``: offline (actor video -> output video) and live (camera index, stream or a file paced at
its real frame rate) re-enactment on a target database."""

from __future__ import annotations

import dataclasses
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_face
from anima.errors import InputError
from anima.io import owned
from anima.io.atomic import write_json
from anima.io.outdir import check_out_file
from anima.io.owned import record_of
from anima.io.validate import input_file, read_json
from anima.io.video import VideoWriter, iter_frames, probe_video
from anima.reenact.config import ReenactConfig
from anima.reenact.database import build_database, read_database, write_database
from anima.reenact.pipeline import Reenactor, Smoother, actor_expressions

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


def check_run(targets: list[str], out: str | None, actor: str | None = None, live: str | None = None,
              db_path: str | None = None) -> None:  # fmt: skip
    """Every input and output of a re-enactment checked before any work (offline or live): the videos, ``out``
    (a video anima wrote, or a new name; never an input) and its record, the database path."""
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
    inputs = [*targets, actor, db_path] if actor else [*targets, db_path]
    if out:  # a video anima wrote (its record names its sha256) or a new name; the record likewise
        check_out_file(out, inputs=inputs, suffixes=VIDEO_SUFFIXES, ours=owned.video, what="a video")
        check_out_file(record_of(out), "--out (its record)", inputs=inputs, ours=_is_record, what="a record")
    if db_path:  # read when it exists (an anima database), else written
        check_out_file(db_path, "--db", inputs=[*targets, actor, out], suffixes=(".npz",), ours=DB_NPZ,
                       what="a re-enactment database")  # fmt: skip


def write_record(out: str, actor: str, targets: list[str], cfg: ReenactConfig, result: dict, sbs: bool = False,
                 live: bool = False) -> None:  # fmt: skip
    """``OUT.json`` beside the video: what made it, and the video's sha256 (what lets a later run replace it)."""
    write_json(
        record_of(out),
        {
            "schema": RECORD_SCHEMA,
            "version": 1,
            "actor": str(actor),
            "live": live,
            "targets": [str(t) for t in targets],
            "side_by_side": sbs,
            "config": dataclasses.asdict(cfg),
            "result": result,
            "video_sha256": owned.sha256(Path(out)),
        },
    )


def run(
    targets: list[str],
    out: str,
    cfg: ReenactConfig,
    actor: str,
    sbs: bool = False,
    db_path: str | None = None,
    progress: bool = True,
) -> dict:
    """``anima reenact --actor``: check every input, then re-enact the actor video on the targets; the video and
    its record (``OUT.json``)."""
    check_run(targets, out, actor=actor, db_path=db_path)
    r = reenact_video(actor, targets, out, cfg, sbs, db_path, progress=progress)
    write_record(out, actor, targets, cfg, r, sbs)
    return r
