"""``anima dataset build``: videos -> filtered, annotated (text, motion) and (audio, motion) pairs, on Ray.

One Ray task per video (a local Ray instance by default; ``address`` joins a cluster). Each task captures
the video (face, body, hands, speech), detects attributes (or uses imported annotations), cuts and filters
clips, writes descriptions and windows, and writes its two Parquet shards atomically, then
``videos/<id>.json`` last: that file marks the video as done. A long video (over 1.5 x ``chunk_s``) is
tracked by one task per chunk of about ``chunk_s`` seconds (each decodes only its frames, plus a warm-up
second); a last task joins the chunks and does the rest on the whole video, so its clips and windows are cut
exactly as in one task. Only tracking is split: it is ~97 % of a video's time (the fit 3 %).

Rerunning a build skips done videos, so a killed build resumes without recomputation and without duplicate
rows (one shard per video, replaced atomically; a video's tracked chunks live only in Ray's object store, so an
unfinished video is tracked again). A failing video is recorded in ``errors/<id>.json`` (and retried on the
next run) and does not stop the build. Splits are by source (speaker, actor, recording) and key path, never by
absolute path (:mod:`anima.dataset.splits`; the table is in the manifest). Normalisation statistics come from
the training split only.
"""

from __future__ import annotations

import contextlib
import dataclasses
import glob
import hashlib
import json
import os
import secrets
import sys
import time
import traceback
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima import __version__
from anima.audio.features import NoAudio, read_audio, speech_features
from anima.capture.config import FIT_FOR_DETECTORS, CaptureConfig
from anima.capture.pipeline import Tracked, capture_video, join_chunks, track_holistic_range
from anima.core.contract import BODY_DIM, FACE_DIM, GESTURE_FPS, SPEECH_DIM, TEXT_FPS
from anima.dataset import ray_guard, splits
from anima.dataset.annotations import emotion_from_path
from anima.dataset.attributes import detect
from anima.dataset.config import RULES, BuildConfig
from anima.dataset.describe import fitting_descriptions, segment_timeline
from anima.dataset.filters import clip_rejection, cut_clips
from anima.dataset.pairs import audio_motion_windows, text_motion_clip
from anima.dataset.storage import SCHEMA, VERSION, read_table, write_shard
from anima.errors import InputError, SchemaError
from anima.io.atomic import write_json
from anima.io.video import VideoInfo, frame_times, probe_video

VIDEO_EXT = (".mp4", ".mov", ".mkv", ".webm", ".avi", ".m4v", ".flv")


RETRIES = 3  # times Ray runs a task again whose worker or node was lost


def video_id(path: str | Path) -> str:
    p = Path(path).resolve()
    return f"{p.stem}-{hashlib.sha1(str(p).encode()).hexdigest()[:8]}"


def expand_videos(inputs: list[str]) -> list[Path]:
    out: list[Path] = []
    for s in inputs:
        p = Path(s)
        if p.is_dir():
            out += sorted(q for q in p.rglob("*") if q.suffix.lower() in VIDEO_EXT and q.is_file())
        elif any(ch in s for ch in "*?["):
            out += sorted(Path(q) for q in glob.glob(s, recursive=True) if Path(q).suffix.lower() in VIDEO_EXT)
        else:
            out.append(p)  # missing files are reported per video, not here
    seen, uniq = set(), []
    for p in out:
        r = p.resolve()
        if r not in seen:
            seen.add(r)
            uniq.append(p)
    return uniq


def paired_audio(path: str | Path) -> Path:
    """The audio of a video: its own track, or, for a video without one, a WAV of the same name beside it or
    in a sibling ``wav/`` folder (the layout of talking-head sets that ship speech separately)."""
    p = Path(path)
    try:
        read_audio(p, sr=8000)  # cheap probe; raises NoAudio without a track
        return p
    except NoAudio:
        for q in (p.with_suffix(".wav"), p.parent.parent / "wav" / f"{p.stem}.wav"):
            if q.is_file():
                return q
        return p
    except Exception:
        return p


def chunk_plan(n_frames: int, fps: float, cfg: BuildConfig) -> list[tuple[int, int]] | None:
    """Frame ranges of a long video's tracking chunks (about ``cfg.chunk_s`` each), or None: track it in one task
    (``chunk_s`` 0, or a video up to 1.5 chunks long)."""
    if cfg.chunk_s <= 0:
        return None
    size = max(1, int(round(cfg.chunk_s * fps)))
    if n_frames <= 1.5 * size:
        return None
    edges = np.linspace(0, n_frames, int(round(n_frames / size)) + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def process_video(
    path: str,
    out_dir: str,
    cfg: BuildConfig,
    annotation: dict | None = None,
    on_progress=None,
    tracked: Tracked | None = None,
    started_at: float | None = None,
    chunk_seconds: float = 0.0,
) -> dict:
    """Everything for one video, stored into ``out_dir`` (:func:`video_payload`, then :func:`store_payload`).
    Returns the video's result."""
    return store_payload(
        Path(out_dir), video_payload(path, cfg, annotation, on_progress, tracked, started_at, chunk_seconds)
    )


def store_payload(out: Path, payload: dict) -> dict:
    """Write what a video's task returned: its shards and ``videos/<id>.json`` (or ``errors/<id>.json``), each
    atomically; written again, the same payload leaves the same files (a retried task changes nothing).
    Returns the video's result."""
    if payload.get("status") == "error":
        _write_json(out / "errors" / f"{payload['video_id']}.json", payload)
        return payload
    vid = payload["result"]["video_id"]
    write_shard(payload["text_motion"], out / "shards" / "text_motion" / f"{vid}.parquet", "text_motion")
    write_shard(payload["audio_motion"], out / "shards" / "audio_motion" / f"{vid}.parquet", "audio_motion")
    _write_json(out / "videos" / f"{vid}.json", payload["result"])
    err = out / "errors" / f"{vid}.json"
    if err.exists():
        err.unlink()
    return payload["result"]


def video_payload(
    path: str,
    cfg: BuildConfig,
    annotation: dict | None = None,
    on_progress=None,
    tracked: Tracked | None = None,
    started_at: float | None = None,
    chunk_seconds: float = 0.0,
    split: str | None = None,
) -> dict:
    """Everything for one video, nothing written: ``{"result": ..., "text_motion": rows, "audio_motion":
    windows}`` (a task returns it through Ray, so a worker needs no access to the output folder).
    ``on_progress(1)`` after each tracked frame. ``tracked``: the video's chunks, tracked by other tasks and
    joined (:func:`~anima.capture.pipeline.join_chunks`), ``started_at`` when the first of them started and
    ``chunk_seconds`` the time they took together; ``split``: the video's split from the build's split table
    (:func:`anima.dataset.splits.table`), else its source's split without grouping."""
    vid = video_id(path)
    t0 = time.perf_counter()
    started_at = started_at or time.time()
    audio = paired_audio(path)
    seq = capture_video(
        path,
        CaptureConfig(max_frames=cfg.max_frames, fit=FIT_FOR_DETECTORS),
        audio=str(audio),
        progress=False,
        on_progress=on_progress,
        tracked=tracked,
    )
    auto = detect(seq, cfg.detector)
    events = annotation["events"] if annotation else auto
    emotion = None if annotation else emotion_from_path(path)
    if emotion:  # an emotion clip: the emotion its file name states holds over the whole clip
        events = sorted(auto + [(emotion, 0.0, seq.n_frames / seq.fps)], key=lambda e: e[1])
    gender = annotation.get("gender") if annotation else None
    split = split or splits.split_for(path)
    prov = json.dumps(
        {
            "tracker": seq.meta.get("tracker"),
            "skeleton_tracker": seq.meta.get("skeleton", {}).get("tracker"),
            "face_model": {k: v for k, v in seq.meta.get("face_model", {}).items() if k != "correspondence"},
            "anima_version": __version__,
            "annotations": "imported" if annotation else "automatic",
            "emotion": f"{emotion} (file name)" if emotion else None,
            "audio": str(audio) if audio != Path(path) else "video track",
            "fps_source": seq.fps,
        }
    )
    counts = {r: 0 for r in RULES}
    filters = cfg.filters
    if emotion:
        filters = dataclasses.replace(filters, min_s=min(filters.min_s, filters.emotion_min_s))
    clips = cut_clips(seq.n_frames, seq.fps, filters)
    if not clips:
        counts["length"] += 1
    rows = []
    n_dropped = 0
    for k, (a, b) in enumerate(clips):
        reason = clip_rejection(seq, a, b, events if annotation else None, filters)
        if reason:
            counts[reason] += 1
            continue
        t0c, t1c = a / seq.fps, b / seq.fps
        rel = [(n, max(s, t0c) - t0c, min(e, t1c) - t0c) for n, s, e in events if s < t1c and e > t0c]
        # seeded by the key path, not the absolute path: the same data elsewhere gets the same descriptions
        seed = int(hashlib.sha1(f"{splits.key_path(path)}/{k}/{cfg.seed}".encode()).hexdigest()[:8], 16)
        segs = segment_timeline(rel, duration=t1c - t0c)
        texts, dropped = fitting_descriptions(segs, cfg.n_descriptions, seed, gender)
        n_dropped += dropped
        motion = text_motion_clip(seq, a, b)
        rows.append(
            {
                "clip_id": f"{vid}/{k:03d}",
                "video_id": vid,
                "split": split,
                "source": str(path),
                "start_s": t0c,
                "end_s": t1c,
                "fps": TEXT_FPS,
                "n_frames": len(motion),
                "motion": motion,
                "texts": texts,
                "attributes": json.dumps(rel),
                "gender": gender,
                "provenance": prov,
            }
        )
    windows = []
    if seq.speech is not None:
        x = read_audio(audio)
        n15 = int(np.floor(seq.n_frames / seq.fps * GESTURE_FPS))
        sp = speech_features(x, GESTURE_FPS, n15)
        for w in audio_motion_windows(seq, sp.features, sp.valid, cfg.window, cfg.hop):
            windows.append(
                {
                    "window_id": f"{vid}/{w['start_frame']:05d}",
                    "video_id": vid,
                    "split": split,
                    "source": str(path),
                    "start_s": w["start_s"],
                    "fps": GESTURE_FPS,
                    "n_frames": cfg.window,
                    "body": w["body"],
                    "face": w["face"],
                    "speech": w["speech"],
                    "provenance": prov,
                }
            )
    result = {
        "video_id": vid,
        "source": str(path),
        "status": "ok",
        "split": split,
        "frames": seq.n_frames,
        "fps": seq.fps,
        "duration_s": seq.n_frames / seq.fps,
        "clips_total": len(clips) or 1,
        "clips_kept": len(rows),
        "removed": counts,
        "windows": len(windows),
        "face_only_windows": int(sum(not np.isfinite(w["body"]).all() for w in windows)),
        "has_body": seq.body_joints is not None,
        "has_speech": seq.speech is not None,
        "auto_events": [[n, round(s, 3), round(e, 3)] for n, s, e in auto],
        "emotion": emotion,
        "descriptions_dropped_too_long": n_dropped,
        "seconds": round(time.perf_counter() - t0 + chunk_seconds, 2),  # compute time (all its tasks)
        "tracking_chunks": tracked.chunks["chunks"] if tracked is not None and tracked.chunks else 1,
        "started_at": started_at,  # wall clock, for the build's task span (start-up excluded)
        "ended_at": time.time(),
        "worker_pid": os.getpid(),
        "node": _node_id(),
    }
    return {"result": result, "text_motion": rows, "audio_motion": windows}


def _node_id() -> str | None:
    """The Ray node this runs on (None outside a Ray task)."""
    ray = sys.modules.get("ray")
    try:
        return ray.get_runtime_context().get_node_id() if ray is not None and ray.is_initialized() else None
    except Exception:
        return None


def _write_json(path: Path, obj) -> None:
    write_json(path, obj, indent=1)


class FrameCounter:
    """Tracked frames per video, counted by the workers (a Ray actor in a build) and read by the driver's
    progress bar, so the bar moves and has an ETA from the first frames instead of per finished video."""

    def __init__(self):
        self.frames: dict[str, int] = {}

    def add(self, vid: str, n: int) -> None:
        self.frames[vid] = self.frames.get(vid, 0) + n

    def get(self) -> dict[str, int]:
        return self.frames


class _Batched:
    """``on_progress`` for a worker: sends the count to the counter every ``every`` frames (fire and forget)."""

    def __init__(self, counter, vid: str, every: int = 10):
        self.counter, self.vid, self.every, self.n = counter, vid, every, 0

    def __call__(self, k: int) -> None:
        self.n += k
        if self.n >= self.every:
            self.counter.add.remote(self.vid, self.n)
            self.n = 0


def _task(path: str, cfg: BuildConfig, annotation: dict | None, counter=None, split: str | None = None) -> dict:
    """Ray task body: the video's payload (the driver stores it); never raises: a failure is the payload."""
    try:
        cb = _Batched(counter, video_id(path)) if counter is not None else None
        return video_payload(path, cfg, annotation, on_progress=cb, split=split)
    except Exception as e:
        return _error(path, e, traceback.format_exc(limit=4))


def _chunk_task(info: VideoInfo, a: int, b: int, warmup: int, times, counter=None) -> dict:
    """Ray task body: track frames ``a`` to ``b - 1`` of one video (``info`` and ``times``: the driver's probe
    and frame timestamps, not read again per chunk); never raises (the video's assembling task records a
    failure)."""
    try:
        started_at = time.time()
        cb = _Batched(counter, video_id(info.path)) if counter is not None else None
        part = track_holistic_range(info, a, b, warmup, times=times, on_progress=cb)
        return {"part": part, "started_at": started_at, "seconds": time.time() - started_at}
    except Exception as e:
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        return {
            "error": f"frames {a}-{b - 1}: {msg}",
            "kind": type(e).__name__,
            "traceback": traceback.format_exc(limit=4),
        }


def _assemble_task(path: str, cfg: BuildConfig, annotation, split, plan, warmup: int, *chunks) -> dict:
    """Ray task body: join a video's tracked chunks and do everything after tracking; never raises."""
    try:
        failed = [c for c in chunks if "error" in c]
        if failed:
            return _error(path, RuntimeError(failed[0]["error"]), failed[0]["traceback"])
        tracked = join_chunks([c["part"] for c in chunks], plan, warmup)
        return video_payload(
            path,
            cfg,
            annotation,
            tracked=tracked,
            started_at=min(c["started_at"] for c in chunks),
            chunk_seconds=sum(c["seconds"] for c in chunks),
            split=split,
        )
    except Exception as e:
        return _error(path, e, traceback.format_exc(limit=4))


def _follow(ray, futs: dict, counter, progress: bool, out: Path) -> dict[str, list[str]]:
    """Wait for the video tasks ``{future: (frames, path)}`` with one bar over all their frames: tracked
    frames as the workers count them, a finished video counting whole (also one that failed). The ETA is the
    average rate since the start (no smoothing: it does not swing with each video's speed)."""
    total = {video_id(p): n for n, p in futs.values()}
    nodes: dict[str, list[str]] = {}
    bar = tqdm(total=sum(total.values()), desc="frames", unit="fr", smoothing=0, disable=not progress)
    finished: set[str] = set()
    remaining = list(futs)
    while remaining:
        done, remaining = ray.wait(remaining, num_returns=1, timeout=1.0)
        for d in done:
            r = store_payload(out, ray.get(d))  # the driver writes: workers need no shared storage
            finished.add(video_id(futs[d][1]))
            nodes.setdefault(str(r.get("node")), []).append(r["video_id"])
            bar.set_postfix_str(f"{len(finished)}/{len(futs)} videos; {r['video_id'][:24]} {r['status']}")
        if bar.disable:
            continue
        counted = ray.get(counter.get.remote())
        now = sum(n if v in finished else min(counted.get(v, 0), n) for v, n in total.items())
        bar.update(now - bar.n)
    bar.close()
    return nodes


def _error(path, e: Exception, tb: str = "") -> dict:
    msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return {
        "video_id": video_id(path),
        "source": str(path),
        "status": "error",
        "error": msg,
        "kind": type(e).__name__,
        "traceback": tb,
        "node": _node_id(),
    }


def _record_error(path, out: Path, e: Exception, tb: str = "") -> dict:
    return store_payload(out, _error(path, e, tb))


def _start_ray(address: str | None, num_workers: int | None):
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    worker_env = {
        "OMP_NUM_THREADS": "1",
        "NUMBA_NUM_THREADS": "1",
        "GLOG_minloglevel": "2",
        "TF_CPP_MIN_LOG_LEVEL": "3",
    }
    if not address:
        # a private local instance (docs/dataset.md, "security"): every Ray server (GCS, raylet, object
        # manager, workers, the driver) listens on 127.0.0.1 only, and every call must carry a token made
        # for this run alone. Settings inherited from a parent process that runs Ray itself (RAY_ADDRESS, its
        # token) would point this instance's workers at another cluster: replaced, for the driver and workers.
        os.environ.pop("RAY_ADDRESS", None)
        os.environ.pop("RAY_AUTH_TOKEN_PATH", None)
        private = {
            "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",  # Ray's switch for a loopback-only node
            "RAY_AUTH_MODE": "token",
            "RAY_AUTH_TOKEN": secrets.token_hex(32),
        }
        os.environ.update(private)
        worker_env.update(private)
    else:
        check_ray_address(address)
    import ray

    started = False  # connected here (a local instance started, or a cluster joined): disconnected here too
    if not ray.is_initialized():
        kw = dict(
            include_dashboard=False, log_to_driver=False, configure_logging=False, runtime_env={"env_vars": worker_env}
        )
        if address:
            ray.init(address=address, **kw)
        else:
            ray_guard.start()  # kills this instance's processes if the driver dies without shutting it down
            ray.init(num_cpus=num_workers or os.cpu_count(), **kw)
        started = True
    return ray, started


def check_ray_address(address: str, timeout_s: float = 4.0) -> None:
    """Refuse, within seconds, an ``--address`` where no Ray cluster answers: Ray's own client waits minutes on
    a port that is closed or speaks something else. The head's GCS is a gRPC (HTTP/2) server: it answers the
    HTTP/2 connection preface with a SETTINGS frame; a closed port, an HTTP/1 server, SSH and the like do not."""
    import socket

    if address in ("auto", "local"):
        return
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise InputError(f"--address {address!r}: expected HOST:PORT of a Ray cluster's head (e.g. 10.0.0.5:6379)")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s) as s:
            s.settimeout(timeout_s)
            s.sendall(b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0]))
            head = b""
            while len(head) < 9:
                chunk = s.recv(9 - len(head))
                if not chunk:
                    break
                head += chunk
    except OSError as e:
        raise InputError(f"--address {address}: no Ray cluster answers there ({e.strerror or e})") from None
    if len(head) < 9 or head[3] != 4:  # frame type 4: SETTINGS
        raise InputError(f"--address {address}: something answers there, but not a Ray cluster's head (GCS)")


def build_summary(m: dict) -> dict:
    """The lines ``anima dataset build`` prints of a manifest."""
    keys = [
        "videos",
        "videos_done",
        "clips_total",
        "clips_kept",
        "removed_by_rule",
        "windows",
        "frames",
        "seconds_of_video",
        "compute_s",
        "last_run",
    ]
    return (
        {k: m[k] for k in keys}
        | {"videos_failed": len(m["videos_failed"])}
        | ({"content_groups": m["content_groups"]} if m.get("content_groups") else {})
    )


def build_videos(videos, out: Path, cfg: BuildConfig, ann: dict, address, num_workers, progress, command) -> dict:
    todo = [p for p in videos if not (out / "videos" / f"{video_id(p)}.json").exists()]
    table = splits.table(videos)  # by source and content, before any task: a task gets its video's split
    _write_json(out / "manifest.json", _manifest(out, videos, cfg, "building", table))
    t0 = time.perf_counter()
    pending = []
    for p in todo:  # unreadable videos are recorded here, before any worker starts
        try:
            info = probe_video(p)
            n = info.n_frames if cfg.max_frames is None else min(info.n_frames, cfg.max_frames)
            # a variable-frame-rate video is resampled as it decodes: it has no frame numbers to cut at
            plan = None if info.variable_frame_rate else chunk_plan(n, info.fps, cfg)
            pending.append((n, p, plan, round(cfg.chunk_warmup_s * info.fps), info))
        except InputError as e:
            _record_error(p, out, e)
    # longest first (LPT scheduling): a long video started last would leave the other workers idle at the end;
    # a long video's chunks go first, spread over the workers
    pending.sort(key=lambda x: -x[0])
    nodes: dict[str, list[str]] = {}
    if pending:
        ray, started = _start_ray(address, num_workers)
        quiet = contextlib.redirect_stdout(sys.stderr)  # Ray's messages (a retried task...) are not the result
        quiet.__enter__()
        try:
            # a task lost with its node (or its worker process) runs again elsewhere: the tasks write nothing,
            # so a rerun is harmless; an exception inside a task is not retried (it becomes the video's error)
            from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

            task = ray.remote(num_cpus=1, max_retries=RETRIES)(_task)
            chunk_task = ray.remote(num_cpus=1, max_retries=RETRIES)(_chunk_task)
            assemble_task = ray.remote(num_cpus=1, max_retries=RETRIES)(_assemble_task)
            here = NodeAffinitySchedulingStrategy(ray.get_runtime_context().get_node_id(), soft=False)
            counter = ray.remote(num_cpus=0, scheduling_strategy=here)(FrameCounter).remote()  # beside the driver
            cfg_ref = ray.put(cfg)
            futs = {}
            for n, p, plan, warm, info in pending:
                times = frame_times(p) if plan is not None else None
                if plan is None or len(times) < n:  # (no timestamps to seek by: one task)
                    split = table[str(p.resolve())]["split"]
                    futs[task.remote(str(p), cfg_ref, ann.get(p.stem), counter, split)] = (n, p)
                    continue
                times = ray.put(times)
                info_ref = ray.put(info)
                parts = [chunk_task.remote(info_ref, a, b, warm, times, counter) for a, b in plan]
                split = table[str(p.resolve())]["split"]
                futs[assemble_task.remote(str(p), cfg_ref, ann.get(p.stem), split, plan, warm, *parts)] = (n, p)
            nodes = _follow(ray, futs, counter, progress, out)
        finally:
            # on success, error or interrupt: our own local instance is shut down; from a cluster the driver
            # disconnects (the cluster runs on), so that Ray's message thread, which would print a node's
            # death on stdout after the summary, ends here
            if started:
                ray.shutdown()
            quiet.__exit__(None, None, None)
    wall = time.perf_counter() - t0
    stats = compute_stats(out)
    _write_json(out / "stats.json", stats)
    manifest = _manifest(out, videos, cfg, "complete", table)
    manifest["last_run"] = {
        "videos_processed": len(todo),
        "wall_s": round(wall, 2),
        "workers": num_workers or os.cpu_count(),
        "address": address,
        "command": command,
        "videos_per_node": nodes,  # which Ray node's task made each video (a retried one: where it finished)
    }
    _write_json(out / "manifest.json", manifest)
    if manifest["videos_done"] == 0:
        first = manifest["videos_failed"][0] if manifest["videos_failed"] else {"source": "?", "error": "?"}
        raise InputError(f"no video could be used: {first['source']}: {first['error']}")
    return manifest


def content_groups(videos: list[Path], table: dict) -> list[str]:
    """One line per video that shares content with a video of another source (one recording under two names,
    a re-cropped or re-encoded copy): they take one split, and the build's report says so."""
    out = []
    for p in videos:
        row = table[str(p.resolve())]
        for other, how in row.get("grouped_with", {}).items():
            out.append(
                f"{row['key_path']} ({row['source']}) is one recording with {other}: {how}; split {row['split']}"
            )
    return out


def _record(path: Path) -> dict:
    """A video's record (``videos/ID.json``, ``errors/ID.json``) of a build into this folder; one that is not
    anima's (not JSON, nested too deeply, not an object) is a :class:`SchemaError`."""
    why = "not a JSON object"
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as e:
        d, why = None, "nested too deeply" if isinstance(e, RecursionError) else str(e).splitlines()[0][:80]
    if not isinstance(d, dict):
        raise SchemaError(f"{path}: not a video record of anima's ({why}): remove it and build again")
    return d


def _manifest(out: Path, videos: list[Path], cfg: BuildConfig, status: str, table: dict) -> dict:
    """The dataset's manifest. ``splits`` lists the videos of each split as their rows carry it; ``split_table``
    says why (key path, source, group; :mod:`anima.dataset.splits`); a video whose rows were made under
    another rule (a build resumed after the rule changed) is listed in ``split_stale``."""
    results, errors = [], []
    for p in videos:
        vid = video_id(p)
        r = out / "videos" / f"{vid}.json"
        e = out / "errors" / f"{vid}.json"
        if r.exists():
            results.append(_record(r))
        elif e.exists():
            errors.append(_record(e))
    removed = {k: sum(r["removed"].get(k, 0) for r in results) for k in RULES}  # older videos lack newer rules
    return {
        "schema": SCHEMA,
        "version": VERSION,
        "status": status,
        "anima_version": __version__,
        "config": dataclasses.asdict(cfg),
        "videos": len(videos),
        "videos_done": len(results),
        "videos_failed": [{"source": e["source"], "error": e["error"]} for e in errors],
        "clips_total": sum(r["clips_total"] for r in results),
        "clips_kept": sum(r["clips_kept"] for r in results),
        "removed_by_rule": removed,
        "windows": sum(r["windows"] for r in results),
        "splits": {s: sorted(r["video_id"] for r in results if r["split"] == s) for s in ("train", "val", "test")},
        "split_rule": splits.rule(),
        "split_table": {video_id(p): table[str(p.resolve())] for p in videos},
        "split_stale": sorted(r["video_id"] for r in results if r["split"] != split_of_result(r, table)),
        "content_groups": content_groups(videos, table),
        "frames": sum(r["frames"] for r in results),
        "seconds_of_video": round(sum(r["duration_s"] for r in results), 2),
        "compute_s": round(sum(r["seconds"] for r in results), 2),
        "emotion_clips": {r["video_id"]: r.get("emotion") for r in results if r.get("emotion")},
        "descriptions_dropped_too_long": sum(r.get("descriptions_dropped_too_long", 0) for r in results),
    }


def split_of_result(result: dict, table: dict) -> str | None:
    """The split the table gives a stored video result (None: the video is not in the table)."""
    row = table.get(str(Path(result["source"]).resolve()))
    return row["split"] if row else None


def compute_stats(out: Path) -> dict:
    """Per-dimension mean and std of the training split (text motion; audio-motion body, face, speech)."""
    stats = {}
    if not (out / "manifest.json").exists():
        return stats
    tm = read_table(out, "text_motion", "train")
    if tm.num_rows:
        m = np.concatenate([np.asarray(x, np.float32).reshape(-1, FACE_DIM) for x in tm["motion"].to_pylist()])
        stats["text_motion"] = {
            "mean": m.mean(0).tolist(),
            "std": np.maximum(m.std(0), 1e-6).tolist(),
            "frames": int(len(m)),
        }
    am = read_table(out, "audio_motion", "train")
    if am.num_rows:
        stats["audio_motion"] = {}
        for k, d in (("body", BODY_DIM), ("face", FACE_DIM), ("speech", SPEECH_DIM)):
            x = np.concatenate([np.asarray(v, np.float32).reshape(-1, d) for v in am[k].to_pylist()])
            x = x[np.isfinite(x).all(1)]  # face-only windows have no body
            if not len(x):
                continue
            stats["audio_motion"][k] = {"mean": x.mean(0).tolist(), "std": np.maximum(x.std(0), 1e-6).tolist()}
    return stats
