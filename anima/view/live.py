"""``anima live SOURCE``: a camera (or a video file, or an allowed stream) drives the character in the browser.

One process: a reader thread delivers the newest frame (:class:`anima.io.live_source.PacedReader`: a slow loop
drops frames, counted, instead of falling behind); each frame is tracked with the capture's models (MediaPipe
Holistic for face, body and hands, or Face Mesh with ``--face-only``) and fitted with the capture's face model
(the person's identity from the first :data:`WARM` frames with a face, then a per-frame fit); the rig's local
rotations come from :func:`anima.core.rig.frame_locals` (no look-ahead: a joint not seen holds). Each frame
goes, as one JSON message, to every page connected to ``/TOKEN/live`` (a WebSocket on the viewer's server,
127.0.0.1 only): the source frame index, its capture time (ms since the epoch, so the page measures glass to
avatar), the 65 joints' local rotations and the 53 expression weights. ``--livelink`` sends the same face as
Live Link Face packets; ``--record DIR`` writes the take as a result folder when it ends."""

from __future__ import annotations

import base64
import json
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
import webbrowser
from array import array
from contextlib import closing
from pathlib import Path

import numpy as np

from anima.capture.body import assemble_frame
from anima.capture.config import CaptureConfig
from anima.capture.fit import LandmarkBasis, choose_keyframes, fit_frames, fit_identity
from anima.capture.holistic import HolisticTracker
from anima.capture.mediapipe_face import FaceMeshTracker
from anima.core import rig
from anima.core.camera import mediapipe_to_camera
from anima.core.contract import EXPR_NAMES, FACE_DIM, N_EXPR, N_JOINTS
from anima.core.filters import gaussian_smooth
from anima.core.rotations import matrix_to_quat, matrix_to_rotvec
from anima.errors import InputError
from anima.export.framing import generated_sequence
from anima.export.livelink import Sender, livelink_rows, parse_target
from anima.export.motion import write_motion_outputs
from anima.export.retarget import LiveRetarget
from anima.export.vrm import write_character_avatar
from anima.facemodel.character import load_character
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.io.atomic import copy_file, write_text
from anima.io.live_source import PacedReader, check_live_source
from anima.io.outdir import OutputFolder, check_out_dir, holds_nothing
from anima.io.validate import input_file
from anima.view.export import _js, viewer_files
from anima.view.serve import open_server, page_url
from anima.view.take import Journal, LiveFrame, part_names, read_parts, remove_parts
from anima.view.ws import Broadcaster

WARM = 10
MIN_CONF = 0.5  # a body joint below this visibility is unseen (the capture's threshold)


TRACKERS = 2
"""Holistic trackers in parallel (``anima live`` without ``--face-only``), each on every other frame: one
Holistic pass takes ~60 ms on a laptop core, two on two cores keep up with 25-30 fps (MediaPipe releases the
GIL); each still sees a continuous (half-rate) video, so its tracking state holds."""


class LiveTracker:
    """Per frame: landmarks (:meth:`landmarks`, thread-safe per tracker ``k``), then the face fit and the rig
    (:meth:`frame`, in order on one thread). See the module docstring."""

    def __init__(self, face_only: bool = False, trackers: int = TRACKERS):
        self.face_only = face_only
        self.fcfg = CaptureConfig().fit
        self.basis = LandmarkBasis.build(load_face_model(), load_correspondence(), self.fcfg.use_iris)
        self.trackers = (
            [FaceMeshTracker(static_image_mode=False)] if face_only else [HolisticTracker() for _ in range(trackers)]
        )
        self.warm: list[np.ndarray] = []
        self.warm_frames: list[tuple] = []  # (index, t_capture, body) of each warm-up face
        self.backfill: list[LiveFrame] = []  # the warm-up frames fitted once the identity is known
        self.identity = None
        self.rest = load_character().joints
        self.idle = rig.idle_body(1, self.rest, 30.0)[0]  # contract: not (one still frame)
        self.held = np.tile(np.eye(3), (rig.N_RIG, 1, 1))
        self.rotation = np.zeros(3)

    def landmarks(self, rgb: np.ndarray, k: int = 0):
        """``(face landmarks [478, 3] or None, body joints [55, 3] or None)`` of one frame, by tracker ``k``."""
        H, W = rgb.shape[:2]
        if self.face_only:
            return self.trackers[k](rgb), None
        hf = self.trackers[k](rgb)
        body = None
        if hf.pose is not None:
            J, C, _ = assemble_frame(hf.pose, hf.pose_world, hf.left_hand, hf.right_hand, W, H)
            J[C < MIN_CONF] = np.nan
            body = J
        return hf.face, body

    def frame(self, lm, body, size: tuple[int, int], index: int, t_capture: float) -> LiveFrame:
        """The face fit (the identity from the first :data:`WARM` faces) and the rig of one tracked frame."""
        H, W = size
        expr, R, face = np.zeros(N_EXPR), None, False
        if lm is not None:
            P = mediapipe_to_camera(lm[self.basis.index][None], W, H)
            if self.identity is None:
                self.warm.append(P[0])
                self.warm_frames.append((index, t_capture, body))
                if len(self.warm) >= WARM:
                    Pw = np.stack(self.warm)
                    key = choose_keyframes(Pw, self.basis, min(self.fcfg.n_keyframes, len(Pw)))
                    self.identity = fit_identity(Pw[key], self.basis, self.fcfg)
                    # the warm-up faces streamed without a fit: fitted now for the recorded take
                    back = fit_frames(Pw[:-1], self.basis, self.identity, self.fcfg)
                    self.backfill = [
                        LiveFrame(i, t, True, np.clip(back.expr[k], 0.0, 1.0), matrix_to_rotvec(back.R[k]), b, None)
                        for k, (i, t, b) in enumerate(self.warm_frames[:-1])
                    ]
            if self.identity is not None:
                fit = fit_frames(P, self.basis, self.identity, self.fcfg)
                expr, R, face = np.clip(fit.expr[0], 0.0, 1.0), fit.R[0], True
                self.rotation = matrix_to_rotvec(R)
        frame_body = body if body is not None else (self.idle if self.face_only else np.full((N_JOINTS, 3), np.nan))
        self.held = rig.frame_locals(frame_body, self.rest, R, self.held)
        return LiveFrame(index, t_capture, face, expr, self.rotation.copy(), body, self.held.copy())

    def __call__(self, rgb: np.ndarray, index: int, t_capture: float) -> LiveFrame:
        lm, body = self.landmarks(rgb)
        return self.frame(lm, body, rgb.shape[:2], index, t_capture)

    def close(self) -> None:
        for t in self.trackers:
            t.close()


class StopOnSignal:
    """Ctrl-C or SIGTERM during a take sets ``requested``, which the loop reads after each frame, instead of
    raising KeyboardInterrupt wherever the main thread happens to be: raised inside a numba kernel's call (the
    per-frame fit) it comes out as a SystemError, and the take would end as an internal error. A second signal
    raises at once (a source that delivers no frame). Installed only in the main thread."""

    def __init__(self):
        self.requested = False
        self._old: dict = {}

    def __enter__(self) -> StopOnSignal:
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                self._old[s] = signal.signal(s, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)


def tracked(reader: PacedReader, tracker: LiveTracker, deadline: float | None, max_frames: int | None = None):
    """``(index, arrival perf_counter, size, face landmarks, body)`` of the frames the trackers took, in arrival
    order of their results (one worker thread per tracker, each taking the newest frame not yet taken; a result
    older than one already yielded is dropped: the stream never goes back in time). Stops at the source's end
    or ``deadline`` (perf_counter)."""
    import queue

    lock = threading.Lock()
    state = {"last": -1, "done": False}
    out: queue.Queue = queue.Queue(maxsize=1)  # a result waits for the fit at most one frame: latency stays bounded

    def work(k: int) -> None:
        try:
            while not state["done"]:
                with lock:
                    got = reader.get(state["last"])
                    if got is not None:
                        state["last"] = got[0]
                if (
                    got is None
                    or (deadline and time.perf_counter() > deadline)
                    or (max_frames and got[0] >= max_frames)
                ):
                    break
                i, t_perf, rgb = got
                lm, body = tracker.landmarks(rgb, k)
                out.put((i, t_perf, rgb.shape[:2], lm, body, None))
        except BaseException as e:  # handed to the consumer
            out.put((None, None, None, None, None, e))
        out.put(None)

    threads = [threading.Thread(target=work, args=(k,), daemon=True) for k in range(len(tracker.trackers))]
    for t in threads:
        t.start()
    ended, emitted = 0, -1
    try:
        while ended < len(threads):
            item = out.get()
            if item is None:
                ended += 1
                continue
            if item[5] is not None:
                raise item[5]
            if item[0] > emitted:
                emitted = item[0]
                yield item[:5]
    finally:
        state["done"] = True
        while any(t.is_alive() for t in threads):
            try:
                out.get_nowait()
            except Exception:
                pass
            for t in threads:
                t.join(0.01)


def message(f: LiveFrame, avatar: LiveRetarget | None = None) -> str:
    """The page's message for one frame (JSON: ``i``, ``t_cap`` ms, ``t_sent`` ms, ``face``, ``q`` [65 x
    (x, y, z, w)], ``w`` [53]; with ``--avatar``, ``a``: the avatar's own node rotations, hips and morph
    weights (:meth:`anima.export.retarget.LiveRetarget.frame`))."""
    q = np.round(matrix_to_quat(f.local), 4)
    m = {
        "i": f.index,
        "t_cap": round(f.t_capture * 1e3, 1),
        "face": f.face,
        "body": f.body is not None,
        "q": q.tolist(),
        "w": np.round(f.expression, 3).tolist(),
    }
    if avatar is not None:
        m["a"] = avatar.frame(f.local, f.expression, f.face)
    m["t_sent"] = round(time.time() * 1e3, 1)
    return json.dumps(m, separators=(",", ":"))


def _page(root: Path, title: str, fps: float, avatar: str | None = None) -> None:
    data = {
        "schema": "anima.view", "version": 1, "kind": "live", "live": True, "title": title, "fps": fps,
        "frames": 1, "videos": [], "audio": None, "curves": {}, "marks": [], "ranges": [], "joints": {},
        "summary": {}, "notes": [], "rig": list(rig.NAMES), "expr": list(EXPR_NAMES),
    }  # fmt: skip
    if avatar is not None:  # the user's file as it is: the page moves its own bones (LiveRetarget)
        vrm = Path(avatar).suffix.lower() == ".vrm"
        data["avatar"] = {"avatar": Path(avatar).name, "as": "retargeted live, frame by frame", "vrm": vrm}
        write_text(root / "view-data.js", _js("ANIMA_VIEW", data))
        write_text(root / "avatar-glb.js", _js("ANIMA_GLB", base64.b64encode(Path(avatar).read_bytes()).decode()))
        for f in viewer_files():
            copy_file(f, root / f.name)
        return
    write_text(root / "view-data.js", _js("ANIMA_VIEW", data))
    with tempfile.TemporaryDirectory(prefix="anima-live-") as tmp:
        glb = write_character_avatar(Path(tmp) / "character.glb", preset="anima")
        write_text(root / "avatar-glb.js", _js("ANIMA_GLB", base64.b64encode(Path(glb).read_bytes()).decode()))
    for f in viewer_files():
        copy_file(f, root / f.name)


def _rss_mb() -> float:
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):
        return float("nan")


def run(
    source: str,
    face_only: bool = False,
    realtime: bool = False,
    record: str | None = None,
    livelink: str | None = None,
    port: int | None = None,
    browser: bool = True,
    max_seconds: float | None = None,
    allow_network: bool = False,
    announce=print,
    command: str | None = None,
    max_frames: int | None = None,
    trackers: int = TRACKERS,
    loop: bool = False,
    avatar: str | None = None,
) -> dict:
    """``anima live`` (see the module docstring); returns the take's numbers when it ends (the source ends,
    ``max_seconds``, Ctrl-C or SIGTERM)."""
    src = check_live_source(source, allow_network)
    target = parse_target(livelink, "--livelink") if livelink else None
    if record is not None:
        check_out_dir(record, "--record", inputs=[source, avatar])
        if part_names(record):
            raise InputError(
                f"--record {record}: it holds an unfinished take (a killed `anima live`): "
                f"`anima live --recover {record}` writes it; or record into another folder"
            )
        if not holds_nothing(record):  # a take never touches what it did not start: a result stays whole
            raise InputError(f"--record {record} already holds files (a result?); a take records into a new or "
                             "empty folder: give another folder")  # fmt: skip
    if max_seconds is not None and not 0 < max_seconds <= 86_400:
        raise InputError("--max-seconds: more than 0, at most a day")
    if not 1 <= trackers <= 4:
        raise InputError("--trackers: 1 to 4")
    retarget = LiveRetarget(input_file(avatar, "--avatar"), load_character().joints) if avatar is not None else None
    tracker = LiveTracker(face_only, trackers)  # the models load before the first frame is offered
    reader = PacedReader(src, realtime=realtime or not Path(src).exists(), loop=loop)
    root = Path(tempfile.mkdtemp(prefix="anima-live-"))
    server = None
    sender = None
    hub = Broadcaster()
    # the take's counts only: frames go to the journal (on disk) when recording, nowhere otherwise, so memory
    # stays flat however long the take runs
    n = n_face = n_body = 0
    lat = array("f")  # per frame, 4 bytes
    first_sent = last_sent = 0.0
    rss = []
    t0 = time.perf_counter()
    stop = False
    od = OutputFolder(record, kind="capture", command=command).__enter__() if record is not None else None
    journal = Journal(od, reader.fps) if od is not None else None
    try:
        _page(root, f"live: {Path(src).name if Path(src).exists() else src}", reader.fps, avatar)
        server, note = open_server(root, port, live=hub)
        threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.2}, daemon=True).start()
        url = page_url(server)
        if note:
            print(f"anima: note: {note}", file=sys.stderr)
        announce(f"anima live: {src} at {url}  (Ctrl-C to stop)")
        sys.stdout.flush()
        has_screen = sys.platform != "linux" or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        if browser and has_screen:
            threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
        sender = Sender(target) if target else None
        last_rss = 0.0
        deadline = t0 + max_seconds if max_seconds else None
        with StopOnSignal() as signalled, closing(tracked(reader, tracker, deadline, max_frames)) as stream:
            for i, t_perf, size, lm, body in stream:
                if signalled.requested:
                    stop = True
                    break
                t_cap = time.time() - (time.perf_counter() - t_perf)  # the frame's arrival on the epoch clock
                f = tracker.frame(lm, body, size, i, t_cap)
                n, n_face, n_body = n + 1, n_face + f.face, n_body + (f.body is not None)  # counted before it is sent
                if tracker.backfill:  # the warm-up frames fitted: they replace their first versions in the take
                    for b in tracker.backfill if journal is not None else ():
                        journal.add(b)
                    tracker.backfill = []
                if journal is not None:
                    journal.add(f)
                hub.send(message(f, retarget))
                if sender is not None:
                    try:
                        sender.send(
                            i, reader.fps, livelink_rows(f.expression[None], EXPR_NAMES, f.rotation[None], [f.face])[0]
                        )
                    except OSError:
                        pass
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
        if sender is not None:
            sender.close()
        if server is not None:
            server.shutdown()
            server.server_close()
        shutil.rmtree(root, ignore_errors=True)
    wall = time.perf_counter() - t0
    L = np.asarray(lat, np.float64) if len(lat) else np.zeros(1)
    span = (last_sent - first_sent) if n > 1 else 0.0
    out = {
        "source": src,
        "mode": "face" if face_only else "face + body + hands",
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
    }
    if od is not None:
        try:
            journal.flush()  # the last frames too: the take is read back from its parts
            frames = read_parts(od.path)[0] if journal.parts else []
            out["record"] = write_take(frames, reader.fps, od, out, journal)
        except InputError:  # nothing worth recovering (no face, no body): the take's own parts go, nothing else
            journal.discard()
            od.__exit__(*sys.exc_info())
            raise
        except BaseException:
            od.__exit__(*sys.exc_info())
            raise
        od.__exit__(None, None, None)
    return out


def recover(folder: str, command: str | None = None) -> dict:
    """``anima live --recover DIR``: the result folder from the parts of a take that was killed."""
    check_out_dir(folder, "--recover")
    frames, fps = read_parts(folder)
    stats = {"recovered": True, "frames_tracked": len(frames), "source_fps": fps}
    with OutputFolder(folder, kind="capture", command=command) as od:
        return {"record": write_take(frames, fps, od, stats, None)}


def take_sequence(frames: list[LiveFrame], fps: float, cfg: CaptureConfig | None = None):
    """The take on the source's frame grid (frames the loop dropped are interpolated from their neighbours;
    frames before the first face hold its first values), smoothed as ``anima capture`` smooths when it is
    written: the take is whole by then, so the zero-phase filters cost the stream nothing (the live messages
    stay unsmoothed, no look-ahead): expression weights and head rotation (axis-angle) by a Gaussian of
    ``cfg.smooth_sigma`` frames, joints by one of ``cfg.body_sigma``."""
    cfg = cfg or CaptureConfig()
    if not frames:
        raise InputError("the take has no frame: nothing to record")
    last = {f.index: f for f in frames}  # a frame written again (a warm-up frame fitted later): the last one
    frames = [last[k] for k in sorted(last)]
    idx = np.array([f.index for f in frames])
    grid = np.arange(idx[0], idx[-1] + 1)
    face = np.stack([np.concatenate([f.expression, f.rotation]) for f in frames])
    ok = np.array([f.face for f in frames])
    F = np.zeros((len(grid), FACE_DIM), np.float32)
    if ok.any():
        for c in range(FACE_DIM):
            F[:, c] = np.interp(grid, idx[ok], face[ok, c])
        F[:, :N_EXPR] = np.clip(gaussian_smooth(F[:, :N_EXPR], cfg.smooth_sigma), 0, 1)
        F[:, N_EXPR:] = gaussian_smooth(F[:, N_EXPR:], cfg.smooth_sigma)
    body = None
    if any(f.body is not None for f in frames):
        B = np.stack([f.body if f.body is not None else np.full((N_JOINTS, 3), np.nan) for f in frames])
        body = np.full((len(grid), N_JOINTS, 3), np.nan, np.float32)
        for j in range(N_JOINTS):
            seen = np.isfinite(B[:, j]).all(-1)
            if seen.sum() >= 2:
                for c in range(3):
                    body[:, j, c] = np.interp(grid, idx[seen], B[seen, j, c])
        seen = np.isfinite(body).all(-1)
        flat = np.where(seen[..., None], body, 0).reshape(len(grid), -1)
        body = np.where(seen[..., None], gaussian_smooth(flat, cfg.body_sigma).reshape(body.shape), np.nan)
        body = body.astype(np.float32)
    return generated_sequence(fps, face=F if ok.any() else None, body=body, meta={"recorded_by": "anima live"}) if (
        ok.any() or body is not None
    ) else None  # fmt: skip


def write_take(frames: list[LiveFrame], fps: float, od: OutputFolder, stats: dict, journal: Journal | None) -> dict:
    """``--record DIR``: the take as a result folder (``capture.npz``, ``avatar.glb``, ``body.bvh``,
    ``arkit.csv``, ``info.json``; the manifest last, when ``od`` closes), written when the take ends; the
    journal's parts (:mod:`anima.view.take`) go once the result is written."""
    seq = take_sequence(frames, fps)
    if seq is None:
        raise InputError("the take never saw a face or a body: nothing to record")
    info = {"live": {k: v for k, v in stats.items() if k != "rss_mb"}, "frames": seq.n_frames, "fps": fps}
    od.info = info
    files = write_motion_outputs(seq, od, "capture.npz", render=False, info=info, progress=False)
    if journal is not None:
        journal.discard()
    remove_parts(od.path, part_names(od.path))  # a recovered take's parts: the result now holds them
    return {"folder": str(od.path), "frames": seq.n_frames, "files": sorted(Path(p).name for p in files.values())}
