"""Tracking a live source frame by frame: :class:`LiveTracker` (the capture's models: MediaPipe Holistic for
face, body and hands, or Face Mesh with ``--face-only``; the capture's face model fitted with the person's
identity from the first :data:`WARM` frames with a face; the rig's local rotations from
:func:`anima.core.rig.frame_locals`, no look-ahead: a joint not seen holds), :func:`tracked` (the trackers in
parallel, each taking the newest frame), :func:`message` (one frame for the page), and :class:`StopOnSignal`
(Ctrl-C ends a take cleanly)."""

from __future__ import annotations

import json
import signal
import threading
import time

import numpy as np

from anima.capture.body import assemble_frame, assemble_legs
from anima.capture.config import CaptureConfig
from anima.capture.fit import LandmarkBasis, choose_keyframes, fit_frames, fit_identity, read_expression
from anima.core import rig
from anima.core.camera import mediapipe_to_camera
from anima.core.contract import JOINT_NAMES, LEG_JOINTS, N_EXPR, N_JOINTS
from anima.core.rotations import matrix_to_quat, matrix_to_rotvec
from anima.export.avatar import LiveCharacterFace
from anima.export.retarget import LiveRetarget
from anima.facemodel.character import load_character, to_arkit
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.facemodel.reader import load_reader
from anima.live.config import TRACKERS
from anima.live.sources import PacedReader
from anima.live.take import LiveFrame
from anima.track import DEFAULT, get

WARM = 10
MIN_CONF = 0.5  # a body joint below this visibility is unseen (the capture's threshold)


class LiveTracker:
    """Per frame: landmarks (:meth:`landmarks`, thread-safe per tracker ``k``), then the face fit and the rig
    (:meth:`frame`, in order on one thread). See the module docstring."""

    def __init__(
        self, face_only: bool = False, trackers: int = TRACKERS, tracker: str = DEFAULT, rest: np.ndarray | None = None
    ):
        self.face_only = face_only
        self.fcfg = CaptureConfig().fit
        self.basis = LandmarkBasis.build(load_face_model(), load_correspondence(), self.fcfg.use_iris)
        self.reader = load_reader() if self.fcfg.reader else None
        t = get(tracker)
        self.trackers = [t.face_mesh(static=False)] if face_only else [t.holistic() for _ in range(trackers)]
        self.warm: list[np.ndarray] = []
        self.warm_frames: list[tuple] = []  # (index, t_capture, body) of each warm-up face
        self.backfill: list[LiveFrame] = []  # the warm-up frames fitted once the identity is known
        self.identity = None
        self.rest = load_character().joints if rest is None else np.asarray(rest, np.float64)  # the build's
        self.idle = rig.idle_body(1, self.rest, 30.0)[0]  # contract: not (one still frame)
        self.held = np.tile(np.eye(3), (rig.N_RIG, 1, 1))
        self.rotation = np.zeros(3)
        self.character = LiveCharacterFace()

    def landmarks(self, rgb: np.ndarray, k: int = 0):
        """``(face landmarks [478, 3] or None, body joints [55, 3] or None, leg joints [8, 3] or None)`` of one
        frame, by tracker ``k``."""
        H, W = rgb.shape[:2]
        if self.face_only:
            return self.trackers[k](rgb), None, None
        hf = self.trackers[k](rgb)
        body = legs = None
        if hf.pose is not None:
            J, C, _ = assemble_frame(hf.pose, hf.pose_world, hf.left_hand, hf.right_hand, W, H)
            J[C < MIN_CONF] = np.nan
            body = J
            legs, lc = assemble_legs(hf.pose_world)
            legs[lc < MIN_CONF] = np.nan
        return hf.face, body, legs

    def frame(self, lm, body, size: tuple[int, int], index: int, t_capture: float, legs=None) -> LiveFrame:
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
                    read = read_expression(Pw[:-1], back, self.basis, self.identity, self.reader)
                    self.backfill = [
                        LiveFrame(i, t, True, np.clip(read[k], 0.0, 1.0), matrix_to_rotvec(back.R[k]), b, None)
                        for k, (i, t, b) in enumerate(self.warm_frames[:-1])
                    ]
            if self.identity is not None:
                fit = fit_frames(P, self.basis, self.identity, self.fcfg)
                read = read_expression(P, fit, self.basis, self.identity, self.reader)
                expr, R, face = np.clip(read[0], 0.0, 1.0), fit.R[0], True
                self.rotation = matrix_to_rotvec(R)
        frame_body = body if body is not None else (self.idle if self.face_only else np.full((N_JOINTS, 3), np.nan))
        leg_dict = None
        if legs is not None and body is not None:
            leg_dict = {n: legs[k] for k, n in enumerate(LEG_JOINTS)}
            leg_dict.update(
                left_hip=body[JOINT_NAMES.index("left_hip")], right_hip=body[JOINT_NAMES.index("right_hip")]
            )
        self.held = rig.frame_locals(frame_body, self.rest, R, self.held, leg_dict)
        character, presented = self.character(expr, lm, size, t_capture) if face else (None, None)
        return LiveFrame(index, t_capture, face, expr, self.rotation.copy(), body, self.held.copy(), legs,
                         self.standing_root(self.held), character, presented)  # fmt: skip

    def standing_root(self, L: np.ndarray) -> np.ndarray:
        """The hips' position ``[3]`` that stands this frame's legs on the floor (the lowest foot point at its
        rest height above it): a crouch lowers the hips, straight legs stand."""
        _, P = rig.forward(L[None], self.rest, self.rest[rig.HIPS][None])
        low = min(P[0, rig.IX[f"{S}{n}"], 1] - self.rest[rig.IX[f"{S}{n}"], 1]
                  for S in ("Left", "Right") for n in ("Foot", "ToeBase", "Toe_End"))  # fmt: skip
        return self.rest[rig.HIPS] - np.array([0.0, low, 0.0])

    def __call__(self, rgb: np.ndarray, index: int, t_capture: float) -> LiveFrame:
        lm, body, legs = self.landmarks(rgb)
        return self.frame(lm, body, rgb.shape[:2], index, t_capture, legs)

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
                lm, body, legs = tracker.landmarks(rgb, k)
                out.put((i, t_perf, rgb.shape[:2], lm, (body, legs), None))
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
    (x, y, z, w)], ``w`` [52]: the character's face (:class:`anima.export.avatar.LiveCharacterFace`: from the
    rest, by geometry, the lids from the landmarks) where a face was seen, else the fit's weights, as its ARKit
    morphs' weights (:func:`anima.facemodel.character.to_arkit`, the page's ``expr`` names); with
    ``--avatar``, ``a``: the avatar's own node rotations, hips and morph weights from the ARKit weights measured
    from the rest face (:attr:`LiveFrame.shown`, :meth:`anima.export.retarget.LiveRetarget.frame`))."""
    q = np.round(matrix_to_quat(f.local), 4)
    m = {
        "i": f.index,
        "t_cap": round(f.t_capture * 1e3, 1),
        "face": f.face,
        "body": f.body is not None,
        "q": q.tolist(),
        "w": np.round(to_arkit((f.expression if f.character is None else f.character)[None])[0], 3).tolist(),
    }
    if avatar is not None:
        m["a"] = avatar.frame(f.local, f.shown, f.face)
    m["t_sent"] = round(time.time() * 1e3, 1)
    return json.dumps(m, separators=(",", ":"))
