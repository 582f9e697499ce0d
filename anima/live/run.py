"""``anima live SOURCE``: a camera (or a video file, or an allowed stream) drives the character in the browser.

One process: a reader thread delivers the newest frame (:mod:`anima.live.sources`: a slow loop drops frames,
counted, instead of falling behind); each frame is tracked and fitted (:class:`anima.live.tracker.LiveTracker`)
and goes, as one JSON message, to every page connected to ``/TOKEN/live`` (a WebSocket on the viewer's server,
127.0.0.1 only): the source frame index, its capture time (ms since the epoch, so the page measures glass to
avatar), the 65 joints' local rotations and the character's 52 ARKit morph weights; and to the outputs the
config asks for (:data:`anima.live.sinks.SINKS`: Live Link Face, the VMC protocol). ``record`` writes the take as a
result folder when it ends (:mod:`anima.live.take`)."""

from __future__ import annotations

import base64
import os
import shutil
import sys
import tempfile
import threading
import time
import webbrowser
from array import array
from contextlib import closing
from pathlib import Path

import numpy as np

from anima.core import rig
from anima.errors import InputError
from anima.export.retarget import LiveRetarget, avatar_front
from anima.export.vrm import write_character_avatar
from anima.facemodel.character import DEFAULT_BUILD, build_coeffs, load_character
from anima.io.arkit import ARKIT_NAMES
from anima.io.atomic import copy_file, write_text
from anima.io.outdir import OutputFolder, check_out_dir, holds_nothing
from anima.io.validate import input_file
from anima.live.config import LiveConfig
from anima.live.sinks import check_sinks, open_sinks
from anima.live.sources import check_live_source, open_source
from anima.live.take import Journal, part_names, read_parts, recover, write_take
from anima.live.tracker import LiveTracker, StopOnSignal, message, tracked
from anima.track import get
from anima.view.export import js_global, viewer_files
from anima.view.serve import open_server, page_url
from anima.view.ws import Broadcaster

__all__ = ["check", "recover", "run"]


def _page(
    root: Path, title: str, fps: float, avatar: str | None = None, front: list | None = None, body: str = DEFAULT_BUILD
) -> None:
    """The live page in ``root``: anima's character, or ``avatar`` as it is (``front``: its forward at rest)."""
    data = {
        "schema": "anima.view", "version": 1, "kind": "live", "live": True, "title": title, "fps": fps,
        "frames": 1, "videos": [], "audio": None, "curves": {}, "marks": [], "ranges": [], "joints": {},
        "summary": {}, "notes": [], "rig": list(rig.NAMES), "expr": ARKIT_NAMES,
    }  # fmt: skip
    if avatar is not None:  # the user's file as it is: the page moves its own bones (LiveRetarget)
        vrm = Path(avatar).suffix.lower() == ".vrm"
        data["avatar"] = {"avatar": Path(avatar).name, "as": "retargeted live, frame by frame", "vrm": vrm,
                          "front": front}  # fmt: skip
        write_text(root / "view-data.js", js_global("ANIMA_VIEW", data))
        write_text(root / "avatar-glb.js", js_global("ANIMA_GLB", base64.b64encode(Path(avatar).read_bytes()).decode()))
        for f in viewer_files():
            copy_file(f, root / f.name)
        return
    write_text(root / "view-data.js", js_global("ANIMA_VIEW", data))
    with tempfile.TemporaryDirectory(prefix="anima-live-") as tmp:
        glb = write_character_avatar(Path(tmp) / "character.glb", shape=body, preset="anima")
        write_text(root / "avatar-glb.js", js_global("ANIMA_GLB", base64.b64encode(Path(glb).read_bytes()).decode()))
    for f in viewer_files():
        copy_file(f, root / f.name)


def _rss_mb() -> float:
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):
        return float("nan")


def check(cfg: LiveConfig) -> tuple[str, dict]:
    """Everything checked before a model loads: the source, the output addresses, the record folder, the
    avatar. Returns the source spec and the outputs' addresses."""
    if cfg.source is None:
        raise InputError("give a SOURCE (a camera index, a video file or a stream URL), or --recover DIR")
    src = check_live_source(cfg.source, cfg.allow_network)
    targets = check_sinks(cfg)
    if cfg.record is not None:
        check_out_dir(cfg.record, "--record", inputs=[cfg.source, cfg.avatar])
        if part_names(cfg.record):
            raise InputError(
                f"--record {cfg.record}: it holds an unfinished take (a killed `anima live`): "
                f"`anima live --recover {cfg.record}` writes it; or record into another folder"
            )
        if not holds_nothing(cfg.record):  # a take never touches what it did not start: a result stays whole
            raise InputError(f"--record {cfg.record} already holds files (a result?); a take records into a new "
                             "or empty folder: give another folder")  # fmt: skip
    if cfg.avatar is not None:
        input_file(cfg.avatar, "--avatar")
    get(cfg.tracker)  # an unknown name: one line, before any model loads
    return src, targets


def run(cfg: LiveConfig, command: str | None = None, announce=print) -> dict:
    """``anima live`` (see the module docstring); returns the take's numbers when it ends (the source ends,
    ``max_seconds``, ``max_frames``, Ctrl-C or SIGTERM)."""
    src, targets = check(cfg)
    rest = load_character().shaped(build_coeffs(cfg.body))[1]  # the build's joints: the page's character
    retarget = LiveRetarget(cfg.avatar, rest) if cfg.avatar is not None else None
    # the models load before the first frame is offered
    tracker = LiveTracker(cfg.face_only, cfg.trackers, cfg.tracker, rest)
    reader = open_source(src, realtime=cfg.realtime or not Path(src).exists(), loop=cfg.loop)
    root = Path(tempfile.mkdtemp(prefix="anima-live-"))
    server = None
    sinks: list = []
    hub = Broadcaster()
    # the take's counts only: frames go to the journal (on disk) when recording, nowhere otherwise, so memory
    # stays flat however long the take runs
    n = n_face = n_body = 0
    lat = array("f")  # per frame, 4 bytes
    first_sent = last_sent = 0.0
    rss = []
    t0 = time.perf_counter()
    stop = False
    od = (
        OutputFolder(cfg.record, kind="capture", command=command, inputs=[cfg.source], flag="--record").__enter__()
        if cfg.record is not None
        else None
    )
    journal = Journal(od, reader.fps) if od is not None else None
    try:
        front = avatar_front(retarget.g, retarget.hum) if retarget is not None else None
        _page(root, f"live: {Path(src).name if Path(src).exists() else src}", reader.fps, cfg.avatar, front, cfg.body)
        server, note = open_server(root, cfg.port, live=hub)
        threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.2}, daemon=True).start()
        url = page_url(server)
        if note:
            print(f"anima: note: {note}", file=sys.stderr)
        announce(f"anima live: {src} at {url}  (Ctrl-C to stop)")
        sys.stdout.flush()
        has_screen = sys.platform != "linux" or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        if cfg.browser and has_screen:
            threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
        sinks = open_sinks(targets, tracker.rest)
        last_rss = 0.0
        deadline = t0 + cfg.max_seconds if cfg.max_seconds else None
        with StopOnSignal() as signalled, closing(tracked(reader, tracker, deadline, cfg.max_frames)) as stream:
            for i, t_perf, size, lm, body in stream:
                if signalled.requested:
                    stop = True
                    break
                t_cap = time.time() - (time.perf_counter() - t_perf)  # the frame's arrival on the epoch clock
                body, legs = body
                f = tracker.frame(lm, body, size, i, t_cap, legs)
                n, n_face, n_body = n + 1, n_face + f.face, n_body + (f.body is not None)  # counted before it is sent
                if tracker.backfill:  # the warm-up frames fitted: they replace their first versions in the take
                    for b in tracker.backfill if journal is not None else ():
                        journal.add(b)
                    tracker.backfill = []
                if journal is not None:
                    journal.add(f)
                hub.send(message(f, retarget))
                for s in sinks:
                    s.send(f, reader.fps)
                lat.append(1e3 * (time.time() - t_cap))
                last_sent = time.perf_counter()
                first_sent = first_sent or last_sent
                if time.perf_counter() - last_rss >= 1.0:
                    rss.append(round(_rss_mb(), 1))
                    last_rss = time.perf_counter()
    except KeyboardInterrupt:
        stop = True
    except BaseException:
        if od is not None:  # the parts flushed so far stay, for --recover
            od.__exit__(*sys.exc_info())
        raise
    finally:
        offered = reader.read
        reader.close()
        tracker.close()
        hub.close()
        for s in sinks:
            s.close()
        if server is not None:
            server.shutdown()
            server.server_close()
        shutil.rmtree(root, ignore_errors=True)
    wall = time.perf_counter() - t0
    L = np.asarray(lat, np.float64) if len(lat) else np.zeros(1)
    span = (last_sent - first_sent) if n > 1 else 0.0
    out = {
        "source": src,
        "mode": "face" if cfg.face_only else "face + body + hands",
        "source_fps": reader.fps,
        "frames_offered": int(offered),
        "frames_tracked": n,
        "frames_dropped": int(max(0, offered - n)),
        "tracked_fraction": round(n / max(offered, 1), 4),
        "frames_with_face": int(n_face),
        "frames_with_body": int(n_body),
        "fps": round((n - 1) / span, 2) if span > 0 else 0.0,
        "latency_ms": {"median": round(float(np.median(L)), 1), "p95": round(float(np.percentile(L, 95)), 1)},
        "rss_mb": rss,
        "seconds": round(wall, 2),
        "interrupted": stop,
        **{s.name: s.report() for s in sinks},
    }
    if od is not None:
        try:
            journal.flush()  # the last frames too: the take is read back from its parts
            frames = read_parts(od.path)[0] if journal.parts else []
            out["record"] = write_take(frames, reader.fps, od, out, journal, cfg.body)
        except InputError:  # nothing worth recovering (no face, no body): the take's own parts go, nothing else
            journal.discard()
            od.__exit__(*sys.exc_info())
            raise
        except BaseException:
            od.__exit__(*sys.exc_info())
            raise
        od.__exit__(None, None, None)
    return out
