"""Monocular face capture: decode -> the tracker's face mesh or holistic model (video mode, :mod:`anima.track`)
-> ICT fit -> smoothing -> artifact."""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from anima import __version__
from anima.audio.features import NoAudio, read_audio, speech_features
from anima.capture.body import assemble, clean
from anima.capture.camera_motion import BackgroundMotion
from anima.capture.config import CaptureConfig
from anima.capture.fit import (
    FrameFit,
    LandmarkBasis,
    choose_keyframes,
    fit_frames,
    fit_identity,
    landmark_error,
    read_expression,
    to_model_space,
)
from anima.core.camera import mediapipe_to_camera
from anima.core.contract import N_FACE_LANDMARKS as N_LANDMARKS
from anima.core.filters import gaussian_smooth
from anima.core.rotations import matrix_to_rotvec
from anima.core.skeleton import JOINT_NAMES, PARENTS
from anima.errors import InputError
from anima.facemodel.correspondence import load_correspondence
from anima.facemodel.ict import load_face_model
from anima.facemodel.reader import landmark_offsets, load_reader
from anima.io.sequence import FLAG_LOW_CONFIDENCE, FLAG_NO_FACE, TrackedSequence
from anima.io.video import VideoInfo, iter_frame_range, iter_frames, probe_video
from anima.pose3d.config import default_checkpoint
from anima.pose3d.infer import lift_frames, replace_body
from anima.track import DEFAULT, get

MIN_SIZE = 32  # px; smaller videos cannot hold a trackable face
NO_FACE = np.full((N_LANDMARKS, 3), np.nan, np.float32)  # a frame's landmarks where no face was found


@dataclass
class Timings:
    decode_track_s: float = 0.0
    fit_s: float = 0.0
    frames: int = 0


def _each_frame(info: VideoInfo, tracker, max_frames, progress: bool, warnings_out, on_progress):
    """``(image, tracker(image))`` for each decoded frame of ``info`` (at most ``max_frames``), with a progress
    bar and ``on_progress(1)`` after the caller has used each; the decoder's warnings go to ``warnings_out``."""
    total = info.n_frames if max_frames is None else min(info.n_frames, max_frames)
    errs: list[str] = []
    with tqdm(total=total, desc="track", unit="fr", disable=not progress, leave=False) as bar:
        for i, image in enumerate(iter_frames(info, errors=errs)):
            if max_frames is not None and i >= max_frames:
                break
            yield image, tracker(image)
            if on_progress is not None:
                on_progress(1)
            bar.update(1)
    if warnings_out is not None:
        warnings_out.extend(errs)


def track_landmarks(
    info: VideoInfo,
    max_frames: int | None = None,
    progress: bool = True,
    warnings_out: list[str] | None = None,
    on_frame=None,
    on_progress=None,
    tracker: str = DEFAULT,
) -> np.ndarray:
    """Run the ``tracker``'s face mesh over the video; ``[F, 478, 3]`` normalised landmarks, NaN where no face.
    ``on_frame(landmarks)`` is called after each frame (used to fit while tracking), ``on_progress(1)`` too
    (a build's frame counter)."""
    out = []
    with get(tracker).face_mesh(static=False) as model:
        for _, lm in _each_frame(info, model, max_frames, progress, warnings_out, on_progress):
            out.append(NO_FACE.copy() if lm is None else lm)
            if on_frame is not None:
                on_frame(out[-1])
    if not out:
        raise InputError(f"no frame could be decoded from {info.path}")
    return np.stack(out)


def _fill_gaps(x: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Linear interpolation over invalid frames, holding the nearest value at the ends."""
    idx = np.flatnonzero(valid)
    out = x.copy()
    if len(idx) == len(x) or len(idx) == 0:
        return out
    flat = out.reshape(len(x), -1)
    for j in range(flat.shape[1]):
        flat[:, j] = np.interp(np.arange(len(x)), idx, flat[idx, j])
    return flat.reshape(x.shape)


def _smooth_rotations(R: np.ndarray, sigma: float, valid: np.ndarray) -> np.ndarray:
    Rs = gaussian_smooth(R.reshape(len(R), 9), sigma, valid).reshape(-1, 3, 3)
    U, _, Vt = np.linalg.svd(Rs)
    d = np.sign(np.linalg.det(U @ Vt))
    U[:, :, 2] *= d[:, None]
    return U @ Vt


class StreamingPrefit:
    """Fit while tracking: a worker thread fits chunks of frames as MediaPipe produces them, with an
    identity estimated from the first chunk's keyframes. Numpy releases the GIL and MediaPipe waits on its
    own threads, so on 2 cores the fit mostly hides behind tracking. :func:`fit_landmark_sequence` then
    re-estimates the identity from keyframes over the whole clip and keeps these per-frame fits only if the
    identity shape moved by less than ``identity_tolerance_cm``; otherwise it refits, warm-started."""

    def __init__(self, width: int, height: int, cfg: CaptureConfig, chunk: int = 100):
        from concurrent.futures import ThreadPoolExecutor

        self.width, self.height, self.cfg, self.chunk = width, height, cfg, chunk
        self.basis = LandmarkBasis.build(load_face_model(), load_correspondence(), cfg.fit.use_iris)
        self.frames: list[np.ndarray] = []
        self.submitted = 0
        self.identity = None
        self.pool = ThreadPoolExecutor(max_workers=1)
        self.jobs = []  # (start, end, future)

    def __call__(self, lm: np.ndarray) -> None:
        self.frames.append(lm)
        if len(self.frames) - self.submitted >= self.chunk:
            self._submit(len(self.frames))

    def _submit(self, end: int) -> None:
        start = self.submitted
        block = np.stack(self.frames[start:end])
        self.submitted = end
        self.jobs.append((start, end, self.pool.submit(self._fit_block, block)))

    def _fit_block(self, block: np.ndarray):
        found = np.isfinite(block).all(axis=(1, 2))
        if not found.any():
            return None
        P = mediapipe_to_camera(block[found][:, self.basis.index], self.width, self.height)
        if self.identity is None:
            key = choose_keyframes(P, self.basis, self.cfg.fit.n_keyframes)
            self.identity = fit_identity(P[key], self.basis, self.cfg.fit)
        return found, fit_frames(P, self.basis, self.identity, self.cfg.fit)

    def result(self, n_frames: int):
        """Per-frame fits ``(identity, expr [F,53], s, R, t)`` over the found frames of the first
        ``n_frames``, or None when nothing usable was fitted."""
        if self.submitted < n_frames:
            self._submit(n_frames)
        parts = []
        for start, end, fut in self.jobs:
            parts.append((start, end, fut.result()))
        self.pool.shutdown()
        if self.identity is None or any(r is None for *_, r in parts):
            return None
        fits = [r[1] for *_, r in parts]
        return (
            self.identity,
            np.concatenate([f.expr for f in fits]),
            np.concatenate([f.scale for f in fits]),
            np.concatenate([f.R for f in fits]),
            np.concatenate([f.t for f in fits]),
        )


def fit_landmark_sequence(
    lm: np.ndarray, width: int, height: int, fps: float, cfg: CaptureConfig, meta: dict | None = None, prefit=None
) -> TrackedSequence:
    """Fit identity (keyframes), per-frame pose/camera/expression, smooth, flag. ``lm [F, 478, 3]``.
    ``prefit``: the result of :meth:`StreamingPrefit.result` for these frames, reused when its identity
    agrees with the whole-clip identity."""
    model = load_face_model()
    corr = load_correspondence()
    basis = LandmarkBasis.build(model, corr, cfg.fit.use_iris)
    F = lm.shape[0]
    found = np.isfinite(lm).all(axis=(1, 2))
    if not found.any():
        raise InputError("no face found in any frame")
    P_all = mediapipe_to_camera(lm[:, basis.index], width, height)
    P = P_all[found]
    key = choose_keyframes(P, basis, cfg.fit.n_keyframes)
    identity = fit_identity(P[key], basis, cfg.fit)
    reused = False
    if prefit is not None and len(prefit[1]) == len(P):
        shift = np.abs(basis.shape(identity) - basis.shape(prefit[0])).mean()
        if shift < cfg.identity_tolerance_cm:
            fit = FrameFit(prefit[2], prefit[3], prefit[4], prefit[1])
            identity, reused = prefit[0], True
        else:
            fit = fit_frames(P, basis, identity, cfg.fit, e0=prefit[1])
    else:
        fit = fit_frames(P, basis, identity, cfg.fit)

    expr = np.zeros((F, basis.expr.shape[-1]))
    R = np.tile(np.eye(3), (F, 1, 1))
    s = np.ones(F)
    t = np.zeros((F, 3))
    expr[found], R[found], s[found], t[found] = fit.expr, fit.R, fit.scale, fit.t
    expr, s, t = _fill_gaps(expr, found), _fill_gaps(s, found), _fill_gaps(t, found)
    R = _fill_gaps(R, found)
    if cfg.smooth_sigma > 0:
        s = gaussian_smooth(s, cfg.smooth_sigma)
        t = gaussian_smooth(t, cfg.smooth_sigma)
        R = _smooth_rotations(R, cfg.smooth_sigma, np.ones(F, bool))
    else:
        U, _, Vt = np.linalg.svd(R)
        R = U @ Vt
    fitted = expr
    reader = load_reader() if cfg.fit.reader else None
    if reader is not None:  # the weights as the reader reads each frame's posed landmarks, as anima live does
        read = expr.copy()
        read[found] = read_expression(P, fit, basis, identity, reader)
        expr = _fill_gaps(read, found)
    expr = with_seen_blinks(expr, list(model.expr_names), lm, found, width, height)
    if cfg.smooth_sigma > 0:
        expr = np.clip(gaussian_smooth(expr, cfg.smooth_sigma), 0, 1)
        fitted = np.clip(gaussian_smooth(fitted, cfg.smooth_sigma), 0, 1)
    # error of the final (smoothed) fit against the tracked landmarks: the model's own weights
    err = np.full(F, np.nan)
    nme = np.full(F, np.nan)
    V = basis.points(identity, fitted[found])
    err[found], nme[found] = landmark_error(P, V, s[found], R[found], t[found])
    uv = P[..., :2]
    face_px = np.full(F, np.nan)
    wh = uv.max(1) - uv.min(1)
    face_px[found] = np.sqrt(np.abs(wh[:, 0] * wh[:, 1]))
    flags = np.zeros(F, np.uint8)
    flags[~found] |= FLAG_NO_FACE
    low = found & ((nme > cfg.low_conf_nme) | (face_px < cfg.min_face_px))
    flags[low] |= FLAG_LOW_CONFIDENCE
    meta = dict(meta or {})
    meta.update(
        tracker=get(cfg.tracker).face_provenance(),
        face_model={
            "name": "ICT-FaceKit light",
            "n_identity": int(basis.ident.shape[-1]),
            "n_expression": int(basis.expr.shape[-1]),
            "correspondence": corr.meta,
        },
        fit={k: getattr(cfg.fit, k) for k in cfg.fit.__dataclass_fields__},
        expression_from="the expression reader (anima.facemodel.reader)" if reader is not None else "the fit",
        smoothing={"filter": "gaussian", "sigma_frames": cfg.smooth_sigma},
        keyframes=np.flatnonzero(found)[key].tolist(),
        identity_from=(
            "first-chunk keyframes (within tolerance of the whole-clip identity)"
            if reused
            else "keyframes over the whole clip"
        ),
        anima_version=__version__,
    )
    return TrackedSequence(
        fps=fps,
        width=width,
        height=height,
        identity=identity,
        expression=expr,
        rotation=matrix_to_rotvec(R),
        scale=s,
        translation=t,
        fit_error_px=err,
        fit_nme=nme,
        flags=flags,
        landmarks=lm.astype(np.float32),
        expr_names=list(model.expr_names),
        meta=meta,
    )


def landmark_offsets_of(seq: TrackedSequence) -> np.ndarray:
    """A captured sequence's landmark offsets ``[F, 478, 3]`` as the expression reader reads them
    (:func:`anima.facemodel.reader.landmark_offsets`): each seen frame's landmarks posed by that frame's own fit
    (with the sequence's identity, as capture and ``anima live`` pose them) into the face model's space, less the
    identity's neutral shape; NaN where no face was seen."""
    cfg = CaptureConfig()
    basis = LandmarkBasis.build(load_face_model(), load_correspondence(), cfg.fit.use_iris)
    found = seq.tracked
    D = np.full((seq.n_frames, 478, 3), np.nan)
    if found.any():
        P = mediapipe_to_camera(np.asarray(seq.landmarks, np.float64)[found][:, basis.index], seq.width, seq.height)
        fit = fit_frames(P, basis, seq.identity, cfg.fit)
        D[found] = landmark_offsets(to_model_space(P, fit.scale, fit.R, fit.t), basis.index, basis.shape(seq.identity))
    return D


_EYES = ((159, 145, 33, 133), (386, 374, 362, 263))  # MediaPipe: (upper lid, lower lid, corner, corner) of each eye
BLINK_OPEN, BLINK_SHUT = 0.8, 0.2
"""A blink as the landmarks see it: the eye's opening (lids' distance over the eye's width) under
``BLINK_OPEN`` of the clip's open eye (its 90th percentile) starts to close the lid, at ``BLINK_SHUT`` of it
the lid is shut."""


def with_seen_blinks(expr: np.ndarray, names: list[str], lm: np.ndarray, found: np.ndarray, width: int,
                     height: int) -> np.ndarray:  # fmt: skip
    """The fitted expression with each eyeBlink at least what the landmarks' eye opening shows (the face
    model's fit under-closes fast or small blinks: a read-back of Andrew Ng's clip counted 4 of its 16). Which
    eye is the person's left is read off the picture (the one on the picture's right)."""
    if found.sum() < 10 or "eyeBlink_L" not in names:
        return expr
    out = expr.copy()
    px = lm[..., :2] * [width, height]
    opening = []
    for up, lo, a, b in _EYES:
        o = np.linalg.norm(px[:, up] - px[:, lo], axis=-1) / np.maximum(
            np.linalg.norm(px[:, a] - px[:, b], axis=-1), 1e-6
        )
        opening.append(np.where(found, o, np.nan))
    right_side = np.nanmean(px[found][:, _EYES[1][2], 0]) > np.nanmean(px[found][:, _EYES[0][2], 0])
    for eye, o in enumerate(opening):
        open_ = np.nanpercentile(o, 90)
        if not np.isfinite(open_) or open_ <= 0:
            continue
        shut = np.clip((BLINK_OPEN * open_ - o) / ((BLINK_OPEN - BLINK_SHUT) * open_), 0.0, 1.0)
        side = "L" if (eye == 1) == right_side else "R"
        k = names.index(f"eyeBlink_{side}")
        out[:, k] = np.where(found, np.maximum(out[:, k], np.nan_to_num(shut)), out[:, k])
    return out


def track_holistic(
    info: VideoInfo,
    max_frames: int | None = None,
    progress: bool = True,
    warnings_out: list[str] | None = None,
    on_face=None,
    on_progress=None,
    tracker: str = DEFAULT,
):
    """Run the ``tracker``'s holistic model over the video. Returns (face landmarks ``[F, 478, 3]`` NaN where no
    face, list of :class:`anima.track.HolisticFrame`). ``on_progress(1)`` is called after each frame."""
    lms, frames = [], []
    background = BackgroundMotion()
    with get(tracker).holistic() as model:
        for image, fr in _each_frame(info, model, max_frames, progress, warnings_out, on_progress):
            fr.camera_step = background(image, fr.pose)
            frames.append(fr)
            lms.append(NO_FACE.copy() if fr.face is None else fr.face)
            if on_face is not None:
                on_face(lms[-1])
    if not frames:
        raise InputError(f"no frame could be decoded from {info.path}")
    return np.stack(lms), frames


@dataclass
class Tracked:
    """What tracking a video gave: face landmarks ``[F, 478, 3]`` (NaN where no face), the holistic frames,
    decoding warnings, and (for a video tracked in chunks) how it was cut."""

    landmarks: np.ndarray
    frames: list
    warnings: list[str]
    chunks: dict | None = None


def track_holistic_range(
    info: VideoInfo,
    start: int,
    stop: int,
    warmup: int = 0,
    times: np.ndarray | None = None,
    on_progress=None,
    tracker: str = DEFAULT,
) -> Tracked:
    """The ``tracker``'s holistic model over frames ``start`` to ``stop - 1`` only (one chunk of a long video, see
    :func:`anima.io.video.iter_frame_range`). Tracking starts ``warmup`` frames earlier and those frames are
    dropped: in video mode MediaPipe carries each frame's regions of interest and its pose smoothing to the next
    frame, so a chunk that started cold would differ from the whole-video run for its first frames.
    ``on_progress(1)`` after each kept frame."""
    lms, frames = [], []
    errs: list[str] = []
    first = max(0, start - warmup)
    background = BackgroundMotion()
    with get(tracker).holistic() as model:
        for k, image in iter_frame_range(info, first, stop, times=times, errors=errs):
            fr = model(image)
            fr.camera_step = background(image, fr.pose)
            if k < start:
                continue
            frames.append(fr)
            lms.append(NO_FACE.copy() if fr.face is None else fr.face)
            if on_progress is not None:
                on_progress(1)
    lm = np.stack(lms) if lms else np.zeros((0, N_LANDMARKS, 3), np.float32)
    return Tracked(lm, frames, errs)


def join_chunks(parts: list[Tracked], plan: list[tuple[int, int]], warmup: int) -> Tracked:
    """The chunks of one video, tracked apart (``plan``: their frame ranges, in order), as one video's tracking.
    A chunk whose decoding stopped early ends the video there, as a decoding error ends a whole-video pass."""
    lm, frames, warns = [], [], []
    for (a, b), part in zip(plan, parts):
        lm.append(part.landmarks)
        frames += part.frames
        warns += part.warnings
        if part.warnings and (a, b) != plan[-1]:  # decoding stopped inside this chunk
            warns.append(f"decoding stopped between frames {a} and {b - 1}: the video ends there")
            break
    out = np.concatenate(lm) if lm else np.zeros((0, N_LANDMARKS, 3), np.float32)
    return Tracked(
        out, frames, warns, {"chunks": len(plan), "frames": [list(ab) for ab in plan], "warmup_frames": warmup}
    )


def empty_face_sequence(n: int, width: int, height: int, fps: float, meta: dict) -> TrackedSequence:
    """A sequence with no face in any frame (body and speech may still be present)."""
    model = load_face_model()
    nan = np.full(n, np.nan)
    return TrackedSequence(
        fps=fps,
        width=width,
        height=height,
        identity=np.zeros(model.id_deltas.shape[0]),
        expression=np.zeros((n, model.expr_deltas.shape[0])),
        rotation=np.zeros((n, 3)),
        scale=np.ones(n),
        translation=np.zeros((n, 3)),
        fit_error_px=nan,
        fit_nme=nan.copy(),
        flags=np.full(n, FLAG_NO_FACE, np.uint8),
        landmarks=np.full((n, N_LANDMARKS, 3), np.nan, np.float32),
        expr_names=list(model.expr_names),
        meta=meta,
    )


def attach_speech(seq: TrackedSequence, audio_path: str) -> None:
    """Speech features at the sequence's frame times, or ``meta.audio`` saying why there are none."""
    try:
        x = read_audio(audio_path)
    except NoAudio as e:
        seq.meta["audio"] = {"present": False, "reason": str(e)}
        return
    except InputError as e:
        seq.meta["audio"] = {"present": False, "reason": f"unreadable: {e}"}
        return
    f = speech_features(x, seq.fps, seq.n_frames)
    seq.speech, seq.speech_valid = f.features, f.valid
    seq.meta["audio"] = {
        "present": True,
        "path": str(audio_path),
        "duration_s": round(f.duration_s, 3),
        "silent": f.silent,
        "gain_db": round(f.gain_db, 2),
        "frames_outside_audio": int((~f.valid).sum()),
        "features": "13 MFCC + log mean energy + first derivatives (anima.audio.features)",
    }


def _lift_body(body, frames, width: int, height: int, checkpoint: str | None) -> str:
    """Replace the body's 3D by the lifter's (in place); returns a provenance string."""
    from anima.pose3d.train import load_checkpoint  # lazy: torch

    path = Path(checkpoint) if checkpoint else default_checkpoint()
    model, _ = load_checkpoint(path)
    px = np.full((len(frames), 33, 2), np.nan)
    vis = np.zeros((len(frames), 33))
    for i, f in enumerate(frames):
        if f.pose is not None:
            px[i] = f.pose[:, :2] * [width, height]
            vis[i] = f.pose[:, 3]
    body.joints = replace_body(body.joints, lift_frames(model, px, vis))
    return f"anima pose lifter {path.name} sha1:{hashlib.sha1(path.read_bytes()).hexdigest()[:12]}"


def capture_video(
    video: str,
    cfg: CaptureConfig | None = None,
    audio: str | None = None,
    progress: bool = True,
    timings: Timings | None = None,
    on_progress=None,
    tracked: Tracked | None = None,
) -> TrackedSequence:
    """One pass over ``video``: face (ICT fit), body and hands (55 joints, cleaned), speech features.
    ``cfg.face_only`` keeps the fast face-mesh path. ``audio``: a separate audio file (default: the
    video's own track). ``on_progress(1)`` after each tracked frame. ``tracked``: Holistic's results made
    elsewhere (the chunks of a long video in a dataset build, :func:`join_chunks`); everything after tracking
    is the same. Raises InputError when neither a face nor a body is found."""
    cfg = cfg or CaptureConfig()
    if cfg.face_only:
        if tracked is not None:
            raise ValueError("tracked chunks come from Holistic: not with face_only")
        seq = capture_face(video, cfg, progress, timings, on_progress)
    else:
        info = probe_video(video)
        if min(info.width, info.height) < MIN_SIZE:
            raise InputError(f"video is {info.width}x{info.height}: too small to find a person (min {MIN_SIZE} px)")
        warns = list(info.warnings)
        t0 = time.perf_counter()
        if tracked is None:
            stream = StreamingPrefit(info.width, info.height, cfg) if cfg.stream else None
            lm, frames = track_holistic(
                info, cfg.max_frames, progress, warns, on_face=stream, on_progress=on_progress, tracker=cfg.tracker
            )
            found = np.isfinite(lm).all(axis=(1, 2))
            prefit = stream.result(len(lm)) if stream is not None and found.any() else None
            if stream is not None and not found.any():
                stream.pool.shutdown()
        else:  # tracked in chunks: fitted here, in the same blocks as while tracking (the same numbers)
            lm, frames, prefit = tracked.landmarks, tracked.frames, None
            warns += tracked.warnings
            if not len(frames):
                raise InputError(f"no frame could be decoded from {video}")
            found = np.isfinite(lm).all(axis=(1, 2))
            if cfg.stream and found.any():
                stream = StreamingPrefit(info.width, info.height, cfg)
                for f in lm:
                    stream(f)
                prefit = stream.result(len(lm))
        t1 = time.perf_counter()
        body = assemble(frames, info.width, info.height, info.fps)
        tracker = get(cfg.tracker).body_provenance()
        if cfg.body_3d == "lifter":
            tracker += " + " + _lift_body(body, frames, info.width, info.height, cfg.pose_model)
        elif cfg.body_3d != "mediapipe":
            raise InputError(f"unknown body_3d {cfg.body_3d!r}: use 'mediapipe' or 'lifter'")
        if not found.any() and not body.valid[:, :13].all(1).any():
            raise InputError(f"no person found in {video} ({len(lm)} frames checked)")
        if info.n_frames and len(lm) < min(info.n_frames, cfg.max_frames or info.n_frames) - 1:
            warns.append(f"only {len(lm)} of {info.n_frames} frames decoded (truncated file?)")
        meta = {"source": {**info.as_dict(), "warnings": warns}}
        if tracked is not None and tracked.chunks:
            meta["source"]["tracked_in_chunks"] = tracked.chunks
        if found.any():
            seq = fit_landmark_sequence(lm, info.width, info.height, info.fps, cfg, meta=meta, prefit=prefit)
        else:
            warns.append("no face found: face arrays are empty (flagged), body and speech are kept")
            seq = empty_face_sequence(len(lm), info.width, info.height, info.fps, meta)
        cleaned = clean(body, cfg.body_min_conf, cfg.max_gap, cfg.body_sigma, cfg.fixed_bones)
        seq.body_joints, seq.body_joints_raw = cleaned.joints, body.joints
        seq.body_conf, seq.body_interpolated = cleaned.conf, cleaned.interpolated
        seq.body_image = body.image
        seq.leg_joints, seq.leg_conf = cleaned.legs, cleaned.leg_conf
        seq.leg_image, seq.camera_step = body.leg_image, body.camera_step
        seq.meta["skeleton"] = {
            "joints": JOINT_NAMES,
            "parents": PARENTS.tolist(),
            "units": "m",
            "origin": "pelvis",
            "tracker": tracker,
            "cleaning": {
                "min_conf": cfg.body_min_conf,
                "max_gap": cfg.max_gap,
                "sigma": cfg.body_sigma,
                "fixed_bones": cfg.fixed_bones,
            },
        }
        if timings is not None:
            timings.decode_track_s += t1 - t0
            timings.fit_s += time.perf_counter() - t1
            timings.frames += len(lm)
    attach_speech(seq, audio or video)
    return seq


def capture_face(
    video: str,
    cfg: CaptureConfig | None = None,
    progress: bool = True,
    timings: Timings | None = None,
    on_progress=None,
) -> TrackedSequence:
    """Track and fit a face in ``video``. Raises InputError for unreadable video or no face at all."""
    cfg = cfg or CaptureConfig()
    info = probe_video(video)
    if min(info.width, info.height) < MIN_SIZE:
        raise InputError(f"video is {info.width}x{info.height}: too small to find a face (min {MIN_SIZE} px)")
    warns = list(info.warnings)
    t0 = time.perf_counter()
    stream = StreamingPrefit(info.width, info.height, cfg) if cfg.stream else None
    lm = track_landmarks(
        info, cfg.max_frames, progress, warns, on_frame=stream, on_progress=on_progress, tracker=cfg.tracker
    )
    found = np.isfinite(lm).all(axis=(1, 2))
    prefit = stream.result(len(lm)) if stream is not None else None
    t1 = time.perf_counter()
    if not found.any():
        raise InputError(f"no face found in {video} ({len(lm)} frames checked)")
    if info.n_frames and len(lm) < min(info.n_frames, cfg.max_frames or info.n_frames) - 1:
        warns.append(f"only {len(lm)} of {info.n_frames} frames decoded (truncated file?)")
    seq = fit_landmark_sequence(
        lm,
        info.width,
        info.height,
        info.fps,
        cfg,
        meta={"source": {**info.as_dict(), "warnings": warns}},
        prefit=prefit,
    )
    if timings is not None:
        timings.decode_track_s += t1 - t0
        timings.fit_s += time.perf_counter() - t1
        timings.frames += len(lm)
    return seq
