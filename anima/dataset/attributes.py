"""Automatic, timestamped attribute detectors on tracked motion (seed 000 ch. 8: annotate from the motion).

Each detector turns a per-frame signal of the tracked sequence (ICT expression weights, head pose from the
fit, speech energy) into events ``(attribute, start_s, end_s)`` with hysteresis thresholds and minimum
durations. Thresholds live in :class:`DetectorConfig`; they were calibrated on shared clips against frame
labels made by watching them (``anima/eval/labels/attributes/*.json``, ``anima eval annotations``, which
reports them out of sample: thresholds chosen leave-one-clip-out).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter, uniform_filter1d

from anima.core.events import (
    BLINK,
    DETECTED,
    FROWN,
    LIPS,
    MOUTH_OPEN,
    NOD,
    RAISE_BROWS,
    SHAKE_HEAD,
    SMILE,
    SQUINT,
    SURPRISE,
    TALK,
    TURN,
    YAWN,
)  # fmt: skip
from anima.core.filters import prominent_peaks, valid_runs
from anima.core.rotations import matrix_to_euler, rotvec_to_matrix
from anima.dataset.config import DetectorConfig

ATTRIBUTES = list(DETECTED)  # the events the detectors label, in this order (anima.core.events)


def _mean(seq, names):
    idx = [seq.expr_names.index(n) for n in names]
    return seq.expression[:, idx].mean(1)


def hysteresis_events(
    x: np.ndarray,
    on: float,
    off: float,
    fps: float,
    min_s: float = 0.0,
    max_s: float | None = None,
    valid: np.ndarray | None = None,
) -> list[tuple[int, int]]:
    """Frame runs ``[a, b)`` where x rises above ``on`` and lasts until it falls below ``off``."""
    active = np.zeros(len(x), bool)
    state = False
    for i, v in enumerate(x):
        if valid is not None and not valid[i]:
            state = False
        elif not state and v >= on:
            state = True
        elif state and v < off:
            state = False
        active[i] = state
    runs = []
    for a, b in valid_runs(active):
        # extend the start back while above the off threshold (hysteresis on both sides)
        while a > 0 and x[a - 1] >= off and (valid is None or valid[a - 1]):
            a -= 1
        d = (b - a) / fps
        if d >= min_s and (max_s is None or d <= max_s):
            runs.append((a, b))
    return runs


def head_angles_deg(seq) -> np.ndarray:
    """(yaw, pitch, roll) in degrees ``[F, 3]`` from the fitted head rotation."""
    return np.rad2deg(matrix_to_euler(rotvec_to_matrix(seq.rotation)))


def _oscillation_events(
    sig: np.ndarray, fps: float, prominence: float, min_swings: int, max_gap_s: float = 0.8
) -> list[tuple[int, int]]:
    """Runs of alternating peaks/troughs (detrended signal) with the given prominence."""
    trend = uniform_filter1d(sig, size=max(3, int(1.5 * fps)), mode="nearest")
    d = sig - trend
    pk = prominent_peaks(d, prominence)
    tr = prominent_peaks(-d, prominence)
    ext = sorted([(i, 1) for i in pk] + [(i, -1) for i in tr])
    events = []
    cur = []
    for i, s in ext:
        if cur and (s == cur[-1][1] or (i - cur[-1][0]) / fps > max_gap_s):
            if len(cur) >= min_swings + 1:
                events.append((cur[0][0], cur[-1][0] + 1))
            cur = [(i, s)]
        else:
            cur.append((i, s))
    if len(cur) >= min_swings + 1:
        events.append((cur[0][0], cur[-1][0] + 1))
    return events


def detect(seq, cfg: DetectorConfig | None = None) -> list[tuple[str, float, float]]:
    """All attribute events of a tracked sequence, ``(attribute, start_s, end_s)`` sorted by start."""
    cfg = cfg or DetectorConfig()
    fps = seq.fps
    valid = seq.tracked
    h = cfg.hysteresis
    ev: list[tuple[str, int, int]] = []

    def add(name, runs):
        ev.extend((name, a, b) for a, b in runs)

    blink = np.minimum(_mean(seq, ["eyeBlink_L"]), 1) * 0.5 + _mean(seq, ["eyeBlink_R"]) * 0.5
    lid = blink
    if cfg.blink_baseline_s:
        lid = blink - median_filter(blink, size=max(3, int(cfg.blink_baseline_s * fps) | 1), mode="nearest")
    add(BLINK, hysteresis_events(lid, cfg.blink_on, cfg.blink_on * h, fps, 0.04, cfg.blink_max_s, valid))
    smile = _mean(seq, ["mouthSmile_L", "mouthSmile_R"])
    add(SMILE, hysteresis_events(smile, cfg.smile_on, cfg.smile_on * h, fps, cfg.min_s, None, valid))

    def rel(x):  # brows and lids sit differently on every face: measure against the clip's own baseline
        return x - (np.percentile(x[valid], cfg.baseline_pct) if valid.any() else 0.0)

    up = _mean(seq, ["browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R"])
    frown = rel(_mean(seq, ["browDown_L", "browDown_R"]) - up)
    add(FROWN, hysteresis_events(frown, cfg.frown_on, cfg.frown_on * h, fps, cfg.min_s, None, valid))
    squint = rel(_mean(seq, ["eyeSquint_L", "eyeSquint_R"])) * (lid < cfg.blink_on)
    add(SQUINT, hysteresis_events(squint, cfg.squint_on, cfg.squint_on * h, fps, cfg.min_s, None, valid))
    brow = rel(_mean(seq, ["browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R"]))
    add(RAISE_BROWS, hysteresis_events(brow, cfg.brow_on, cfg.brow_on * h, fps, cfg.min_s, None, valid))
    jaw = _mean(seq, ["jawOpen"])
    wide = _mean(seq, ["eyeWide_L", "eyeWide_R"])
    surprise = np.minimum(brow / cfg.brow_on, np.maximum(jaw / cfg.mouth_open_on, wide / 0.3))
    add(SURPRISE, hysteresis_events(surprise, 1.0, h, fps, cfg.min_s, None, valid))
    add(MOUTH_OPEN, hysteresis_events(jaw, cfg.mouth_open_on, cfg.mouth_open_on * h, fps, cfg.min_s, None, valid))
    add(YAWN, hysteresis_events(jaw, cfg.yawn_jaw, cfg.yawn_jaw * h, fps, cfg.yawn_min_s, None, valid))
    # talk: lip motion, gated by voice activity where there is audio
    lips = LIPS[:12]  # the lips and jaw, rolls and shrugs left out
    idx = [seq.expr_names.index(n) for n in lips]
    speed = np.abs(np.diff(seq.expression[:, idx], axis=0, prepend=seq.expression[:1, idx])).sum(1) * fps
    motion = uniform_filter1d(speed, size=max(3, int(0.5 * fps)), mode="nearest")
    lip_motion = motion / cfg.talk_motion
    # speech opens and closes the mouth several times a second; a smile or a yawn moves the lips once
    v = np.diff(_mean(seq, ["jawOpen", "mouthLowerDown_L", "mouthLowerDown_R"]), prepend=0.0) * fps
    moving = np.abs(v) > 0.15
    flips = np.zeros(len(v))
    flips[1:] = (np.sign(v[1:]) != np.sign(v[:-1])) & moving[1:] & moving[:-1]
    rate = uniform_filter1d(flips, size=max(3, int(1.0 * fps)), mode="nearest") * fps  # reversals / s
    talk = np.where(rate >= cfg.talk_reversals_per_s, lip_motion, 0.0)
    if seq.speech is not None:
        voiced = (
            uniform_filter1d(
                (seq.speech[:, 13] > cfg.talk_voice_log_energy).astype(float),
                size=max(3, int(0.5 * fps)),
                mode="nearest",
            )
            > 0.3
        )
        voiced &= seq.speech_valid
        # where the voice is heard it tells speech from a smile or a yawn: lip motion decides, no reversal count
        talk = np.where(voiced, lip_motion if cfg.talk_voice_decides else talk, 0.0)
    add(TALK, hysteresis_events(talk, 1.0, h, fps, 0.5, None, valid))
    ypr = head_angles_deg(seq)
    add(NOD, _oscillation_events(ypr[:, 1], fps, cfg.nod_deg, 2))
    add(SHAKE_HEAD, _oscillation_events(ypr[:, 0], fps, cfg.shake_deg, 3))
    yaw_dev = np.abs(ypr[:, 0] - np.median(ypr[valid, 0])) if valid.any() else np.zeros(len(ypr))
    add(TURN, hysteresis_events(yaw_dev, cfg.turn_deg, cfg.turn_deg * h, fps, cfg.min_s, None, valid))
    out = [(n, a / fps, b / fps) for n, a, b in ev]
    return sorted(out, key=lambda e: (e[1], ATTRIBUTES.index(e[0])))


def frame_mask(events: list[tuple[str, float, float]], attribute: str, n_frames: int, fps: float) -> np.ndarray:
    """Per-frame boolean of an attribute from its events (frame i covers time i / fps)."""
    m = np.zeros(n_frames, bool)
    t = np.arange(n_frames) / fps
    for name, s, e in events:
        if name == attribute:
            m |= (t >= s - 1e-9) & (t < e - 1e-9)
    return m
