"""The timeline method of ``anima text2face``: a prompt's events synthesised from captured motion.

The seed's model (cVQ-VAE + FaceFormer decoder) needs hours of data; on the shared minutes its prompts
collapse onto a few codebook entries. This method works on minutes and improves with more:

1. :func:`anima.text2face.prompt.parse` turns the prompt into events (attribute or emotion, count,
   intensity, side) grouped into clauses that follow one another.
2. Every event is taken from the **captured motion segments the dataset's detectors labelled with it**
   (``Library``: the (text, motion) clips of the training videos and their events). Emotions have no
   detector, so their segments are found by motion matching in ARKit space: the frames of the corpus whose
   offsets from their clip's rest face best match the emotion's action units (``EMOTION_AUS``, after
   EMFACS: Friesen & Ekman 1983; the channel sets of the issue).
3. A segment contributes its offsets from its own clip's rest face (``Library.rest``: the 20th percentile
   of each expression weight, the median head rotation), only on the channels of its event (``CHANNELS``),
   faded in and out with a raised cosine over its margins, added to the face model's neutral (every weight
   0, the head straight: a rest face that is neutral and symmetric). Held events (a smile "for a while", an
   emotion) stretch the middle of their segment; talk is tiled from several talk segments; counted events
   repeat with different segments.
4. Actions no detector labels (gaze, eye rolls, cheek puff, pout, lip press, ...) and the one-sided versions
   of blinks (winks), raised brows and smiles are keyframed on their channels (:mod:`anima.text2face.poses`).
5. The result is checked with the same detectors; an event they do not find is made stronger (x1.35, at
   most 4 times, clipped to the weights' range), so "slightly" is the weakest version that still reads.

Pure: the library is built from arrays (``Library.from_clips``); reading a dataset is ``from_dataset``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d

from anima.core.contract import EXPR_NAMES, FACE_DIM, N_EXPR, TEXT_FPS
from anima.core.events import (
    BLINK,
    CLOSE_EYES,
    FROWN,
    HEAD,
    LIPS,
    NEUTRAL,
    NOD,
    SHAKE_HEAD,
    TALK,
    TURN,
    VOCABULARY,
    both_sides,
)  # fmt: skip
from anima.dataset.attributes import ATTRIBUTES, detect
from anima.dataset.windows import read_clips
from anima.errors import InputError
from anima.export.framing import generated_sequence
from anima.library import builtin
from anima.text2face.poses import POSES, natural_frames, nod_track, pose_track, shake_track
from anima.text2face.prompt import FAINT, Plan

_IX = {n: i for i, n in enumerate(EXPR_NAMES)}
# the vocabulary's (anima.core.events) views the composer reads: the channels each event moves (the rest of a
# captured segment is left out: a blink taken from a talking clip must not bring the talking along), emotions
# as action units in ARKit weights (EMFACS prototypes; positive weights pull the match towards the channel,
# negative ones away from it), the events that can be held
CHANNELS: dict[str, tuple[str, ...]] = {n: e.channels for n, e in VOCABULARY.items() if e.channels}
EMOTION_AUS: dict[str, dict[str, float]] = {n: e.action_units for n, e in VOCABULARY.items() if e.action_units}
HOLDABLE = {n for n, e in VOCABULARY.items() if e.holdable} | set(EMOTION_AUS)
HEAD_AXIS = {NOD: 0, SHAKE_HEAD: 1, TURN: 1}  # rotation-vector component (x: pitch, y: yaw)
SHAKE_MAX_RAD = 0.3  # 17 degrees either way (the turn detector fires at 20 degrees from the clip's median)
SHAKE_RAD = {0.6: 0.15, 1.0: 0.25, 1.4: 0.3}
"""A head shake's peak yaw (radians) by stated intensity: a plain shake swings 14 degrees either way. Shakes
are keyframed (:func:`anima.text2face.poses.shake_track`): the captured ones of the shared data (6 in the
training videos) are slow, one-sided wanders of the head that a viewer does not read as "no"."""
NOD_RAD = {0.35: 0.14, 0.6: 0.2, 1.0: 0.26, 1.4: 0.33}
"""A nod's bob (radians, the chin down) by stated intensity: 8, 11.5, 15 and 19 degrees. Nods are keyframed
(:func:`anima.text2face.poses.nod_track`): one bob each, so "nods twice" is two bobs (the
captured ones bob two to six times); a single 0.8-s bob of 15 degrees is what the dataset's nod detector reads
as one nod (a shallower or quicker one it misses)."""
# Longer holds read as other events to the detectors, which measure against the clip's own rest: an open
# mouth held over 1 s is a yawn, a raise or a turn held over a quarter of the clip shifts the rest.
MAX_HOLD_S = {n: e.max_hold_s for n, e in VOCABULARY.items() if e.max_hold_s}
HOLD_MIN_S = 0.8  # a held event's segment is sped up to this (plus margins) when time is short
NATURAL_S = {TALK: 1.5, NEUTRAL: 0.8, CLOSE_EYES: 1.0}
GAP_S = {BLINK: 0.3, NOD: 0.9, SHAKE_HEAD: 0.9}  # between repeats (a nod within 0.8 s is the same nod)
REPEAT_GAP_S = 0.5  # between repeats of the other events: the weight falls back below the detectors' "off"
LEAD_S, BETWEEN_S = 0.25, 0.3
LIP_SMOOTH_S = 0.2  # sigma of the low-pass on a non-talk event's lip weights (speech moves them at 3-6 Hz)
MARGIN_S = 0.2


@dataclass
class Segment:
    clip: int
    a: int  # first frame, margin included
    b: int  # end frame (exclusive), margin included
    attribute: str
    margin: int
    peak: float = 0.0


@dataclass
class Library:
    """Captured clips (``motion [F, 56]`` each, 30 fps), their rest faces, and the labelled segments."""

    motion: list[np.ndarray]
    rest: np.ndarray  # [C, 56]
    segments: dict[str, list[Segment]]
    sources: list[str]
    fps: float = TEXT_FPS
    neutral: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self):
        if self.neutral is None:  # the face model's own neutral: every weight 0, the head straight
            self.neutral = np.zeros(FACE_DIM, np.float32)

    @property
    def counts(self) -> dict[str, int]:
        return {k: len(v) for k, v in self.segments.items()}

    @classmethod
    def from_clips(cls, motions, events, sources, fps: float = TEXT_FPS, n_emotion: int = 12) -> Library:
        """``motions[i] [F, 56]``, ``events[i]`` = ``[(attribute, start_s, end_s)]`` (the detectors')."""
        motions = [np.asarray(m, np.float32) for m in motions]
        if not motions:
            raise InputError("the timeline method needs captured clips: the dataset has no (text, motion) clip")
        rest = np.stack([_rest(m) for m in motions])
        margin = int(round(MARGIN_S * fps))
        segs: dict[str, list[Segment]] = {a: [] for a in ATTRIBUTES}
        for c, (m, evs) in enumerate(zip(motions, events)):
            for attr, s, e in evs:
                if attr not in segs:
                    continue
                a0, b0 = int(round(s * fps)), int(round(e * fps))
                a, b = max(0, a0 - margin), min(len(m), b0 + margin)
                if b0 - a0 < 1 or a0 - a < margin // 2 or b - b0 < margin // 2:
                    continue  # cut off at the clip's edge: no rest on one side to fade from
                segs[attr].append(Segment(c, a, b, attr, margin, _peak(m[a:b] - rest[c], attr)))
        for emo in EMOTION_AUS:
            labelled = {c for c, evs in enumerate(events) if any(a == emo for a, _, _ in evs)}
            segs[emo] = _emotion_segments(motions, rest, emo, fps, n_emotion, labelled)
        return cls(motions, rest, segs, list(sources), fps)

    @classmethod
    def from_dataset(cls, folder, splits=("train",)) -> Library:
        """The (text, motion) clips of the dataset's training videos (the held-out ones stay unseen)."""
        clips = [c for c in read_clips(folder) if c.split in splits]
        if not clips:
            raise InputError(f"{folder}: no (text, motion) clip in split(s) {', '.join(splits)}")
        if abs(clips[0].fps - TEXT_FPS) > 1e-6:
            raise InputError(f"{folder}: clips at {clips[0].fps} fps; the timeline method works at {TEXT_FPS}")
        return cls.from_clips(
            [c.motion for c in clips], [c.events for c in clips], [f"{c.clip_id}" for c in clips], clips[0].fps
        )

    @classmethod
    def from_builtin(cls) -> Library:
        """The built-in motion library's clips (:mod:`anima.library.builtin`)."""
        b = builtin.load()
        return cls.from_clips(b.face_motion, b.face_events, b.face_clip, b.face_fps)


def _rest(m: np.ndarray) -> np.ndarray:
    r = np.zeros(FACE_DIM, np.float32)
    r[:N_EXPR] = np.percentile(m[:, :N_EXPR], 20, axis=0)
    r[N_EXPR:] = np.median(m[:, N_EXPR:], axis=0)
    return r


def _channel_idx(attr: str) -> tuple[list[int], bool]:
    chans = CHANNELS.get(attr) or [k for k, w in EMOTION_AUS.get(attr, {}).items() if w > 0]
    return [_IX[c] for c in chans if c != HEAD], HEAD in chans


def _peak(off: np.ndarray, attr: str) -> float:
    idx, head = _channel_idx(attr)
    if head:
        return float(np.abs(off[:, N_EXPR:] - off[:1, N_EXPR:]).max())
    return float(np.abs(off[:, idx]).max()) if idx else 0.0


def _emotion_score(m: np.ndarray, rest: np.ndarray, emo: str) -> np.ndarray:
    s = np.zeros(len(m), np.float32)
    for ch, w in EMOTION_AUS[emo].items():
        s += w * (m[:, _IX[ch]] - rest[_IX[ch]])
    return s


def _emotion_segments(motions, rest, emo, fps, n, labelled=frozenset()) -> list[Segment]:
    """Motion matching in ARKit space: the best-scoring 1.2 s stretch of each clip, the top ``n`` clips. Clips
    labelled with the emotion (an emotion clip's file name, imported annotations) come first; when there are
    fewer than ``n``, the best of the other clips fill up."""
    half = int(round(0.6 * fps))
    margin = int(round(MARGIN_S * fps))
    cands = []
    for c, m in enumerate(motions):
        if len(m) < 2 * half + 2 * margin:
            continue
        sc = np.convolve(_emotion_score(m, rest[c], emo), np.ones(2 * half) / (2 * half), mode="same")
        lo, hi = half + margin, len(m) - half - margin
        t = lo + int(np.argmax(sc[lo:hi]))
        cands.append((float(sc[t]), Segment(c, t - half - margin, t + half + margin, emo, margin, float(sc[t]))))
    cands.sort(key=lambda x: (x[1].clip not in labelled, -x[0]))
    return [s for v, s in cands[:n] if v > 0 or s.clip in labelled]


def _window(n: int, margin: int) -> np.ndarray:
    w = np.ones(n, np.float32)
    k = min(margin, n // 2)
    if k > 0:
        ramp = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, k + 2)[1:-1])
        w[:k] = ramp
        w[n - k :] = ramp[::-1]
    return w


def _stretch(x: np.ndarray, n: int, margin: int) -> np.ndarray:
    """``x [L, D]`` to ``n`` frames: onset and release at their own speed, the middle slowed to fill."""
    L = len(x)
    if n == L:
        return x
    core = max(1, L - 2 * margin)
    on = margin + int(0.3 * core)
    off = L - margin - int(0.3 * core)
    if n < L or off <= on:
        src = np.linspace(0, L - 1, n)
    else:
        mid = n - on - (L - off)
        src = np.concatenate([np.arange(on), np.linspace(on, off - 1, mid), np.arange(off, L)])
    i0 = np.floor(src).astype(int)
    i1 = np.minimum(i0 + 1, L - 1)
    f = (src - i0)[:, None]
    return x[i0] * (1 - f) + x[i1] * f


def _offset(lib: Library, seg: Segment, side: str | None, lip_smooth_s: float = 0.2) -> np.ndarray:
    """A segment's contribution ``[L, 56]``: offsets from its clip's rest face on its event's channels."""
    m = lib.motion[seg.clip][seg.a : seg.b]
    out = np.zeros_like(m)
    idx, head = _channel_idx(seg.attribute)
    if idx:
        if side in ("left", "right"):
            keep = "_L" if side == "left" else "_R"
            idx = [i for i in idx if not (EXPR_NAMES[i].endswith(("_L", "_R")) and not EXPR_NAMES[i].endswith(keep))]
        out[:, idx] = m[:, idx] - lib.rest[seg.clip][idx]
        if seg.attribute != TALK:  # an open mouth taken from a talking clip: keep its opening, not the speech
            lip = [i for i in idx if EXPR_NAMES[i] in LIPS]
            if lip:
                out[:, lip] = gaussian_filter1d(out[:, lip], lip_smooth_s * lib.fps, axis=0, mode="nearest")
    if head:  # a nod turns about the x axis (pitch), a shake or turn about y (yaw): the other axes stay still
        ax = N_EXPR + HEAD_AXIS[seg.attribute]
        out[:, ax] = m[:, ax] - m[0, ax]
        if seg.attribute == TURN and side in ("left", "right"):
            j = int(np.abs(out[:, ax]).argmax())
            if np.sign(out[j, ax]) != (1.0 if side == "left" else -1.0):  # +y: the head turns to its left
                out[:, ax] *= -1.0
    return out * _window(len(m), seg.margin)[:, None]


@dataclass
class Placed:
    attribute: str
    start: int
    end: int
    gain: float
    pieces: list[tuple[Segment, int, int]]  # (segment, output start, output length)
    side: str | None = None
    pose: str | None = None  # a keyframed event (anima.text2face.poses)
    count: int = 1
    level: float = 1.0  # the stated intensity (a captured event's peak is brought into its range)


def pose_of(e) -> str | None:
    """The keyframed pose that makes event ``e``, if any: the actions no detector labels, and the one-sided
    versions of blink (a wink), raised brows and smile, made at full strength on the named side."""
    if e.attribute in POSES:
        return e.attribute
    if e.attribute == SHAKE_HEAD:
        return "shake"
    if e.attribute == NOD:
        return NOD
    if e.side in ("left", "right"):
        return VOCABULARY[e.attribute].one_sided_pose if e.attribute in VOCABULARY else None
    return None


def _holds(e) -> bool:
    """A keyframed event that stretches to its slot (held), rather than one that happens and is over."""
    return bool(pose_of(e)) and pose_of(e) not in ("wink", "shake", NOD) and e.count == 1


def _choose(lib: Library, attr: str, rng: np.random.Generator, k: int, avoid: frozenset = frozenset()) -> list[Segment]:
    pool = lib.segments.get(attr) or []
    if attr == CLOSE_EYES:
        pool = lib.segments.get(BLINK) or []
    if not pool:
        raise InputError(f"the library has no captured '{attr}' segment: build the dataset from more clips")
    pool = [s for s in pool if (s.clip, s.a) not in avoid] or pool  # segments that did not read back
    # the strongest half of the labelled segments (clear examples), duration closest to the slot if asked
    if attr in MAX_HOLD_S:  # an open mouth held too long is a yawn
        short = [s for s in pool if s.b - s.a <= (MAX_HOLD_S[attr] + 2 * MARGIN_S) * lib.fps]
        pool = short or pool
    peaks = np.array([s.peak for s in pool])
    good = [s for s, p in zip(pool, peaks) if p >= np.median(peaks)] or pool
    if k > 1 or attr in GAP_S:  # repeated or oscillating events: the shorter examples, so copies fit
        good.sort(key=lambda s: s.b - s.a)
        good = good[: max(4, len(good) // 2)]
    return [good[i] for i in rng.choice(len(good), size=k, replace=k > len(good))]


class TooShort(InputError):
    """The asked length cannot hold the prompt's events (``need``: the frames they need)."""

    def __init__(self, message: str, need: int):
        super().__init__(message)
        self.need = need


DEFAULT_FRAMES = 90  # contract: not (3 s at the text rate: the shortest clip a prompt gets when no length is asked)


def plan_layout(plan: Plan, lib: Library, n_frames: int, seed: int = 0, avoid: frozenset = frozenset()) -> list[Placed]:
    """Where each event goes in ``n_frames``: clauses in order, events of a clause together, the free time
    shared between held events and the pauses. Raises :class:`InputError` when the events cannot fit."""
    fps = lib.fps
    if not plan.events:  # nothing recognised: the neutral face
        return []
    rng = np.random.default_rng(seed)
    clauses: dict[int, list] = {}
    for e in plan.events:
        clauses.setdefault(e.clause, []).append(e)
    only_talk = all(e.attribute in (TALK, NEUTRAL) for e in plan.events)
    chosen = []  # per clause: [(event, segments, natural length)]
    slot_len = []
    for c in sorted(clauses):
        row = []
        for e in clauses[c]:
            if e.attribute in (TALK, NEUTRAL):
                row.append((e, [], int(NATURAL_S[e.attribute] * fps)))
                continue
            if pose_of(e):
                row.append((e, [], natural_frames(pose_of(e), e.count, fps)))
                continue
            segs = _choose(lib, BLINK if e.attribute == CLOSE_EYES else e.attribute, rng, e.count, avoid)
            if e.attribute == CLOSE_EYES:
                row.append((e, segs[:1], int(NATURAL_S[CLOSE_EYES] * fps)))
                continue
            gap = int(GAP_S.get(e.attribute, REPEAT_GAP_S) * fps)
            nat = sum(s.b - s.a for s in segs) - 2 * segs[0].margin * (len(segs) - 1) + gap * (len(segs) - 1)
            if e.attribute in HOLDABLE and len(segs) == 1:  # a held event can be shown in less time
                nat = min(nat, int((HOLD_MIN_S + 2 * MARGIN_S) * fps))
            row.append((e, segs, nat))
        chosen.append(row)
        lens = [n for e, _, n in row if e.attribute not in (TALK, NEUTRAL)] or [n for _, _, n in row]
        slot_len.append(max(lens))
    lead, between = int(LEAD_S * fps), int(BETWEEN_S * fps)
    need = 2 * lead + sum(slot_len) + between * (len(slot_len) - 1)
    if need > n_frames:
        raise TooShort(
            f"the prompt's events need at least {need} frames ({need / fps:.1f} s) and {n_frames} were asked "
            f"for: ask for --seconds {np.ceil(10 * need / fps) / 10:g} (or leave the length out) or fewer events",
            need,
        )
    slack = n_frames - need
    holdable = [
        any(e.attribute in HOLDABLE or e.attribute in (TALK, NEUTRAL) or _holds(e) for e, _, _ in r) for r in chosen
    ]
    grow = int(slack * 0.6) // max(1, sum(holdable)) if any(holdable) else 0
    cap = [
        min([int((MAX_HOLD_S[e.attribute] + 2 * MARGIN_S) * fps) for e, _, _ in r if e.attribute in MAX_HOLD_S])
        if any(e.attribute in MAX_HOLD_S for e, _, _ in r)
        else 10**9
        for r in chosen
    ]
    slot_len = [max(n, min(n + (grow if h else 0), c)) for n, h, c in zip(slot_len, holdable, cap)]
    rest = n_frames - (sum(slot_len) + between * (len(slot_len) - 1))
    lead = rest // 2
    if only_talk:  # talking (or a still face) fills the clip
        lead = int(LEAD_S * fps) // 2
        free = n_frames - 2 * lead - between * (len(slot_len) - 1)
        slot_len = [free // len(slot_len)] * len(slot_len)
    placed: list[Placed] = []
    t = lead
    for row, L in zip(chosen, slot_len):
        for e, segs, _ in row:
            gain = float(e.intensity)
            level = gain
            if e.attribute not in HEAD_AXIS and e.attribute != TALK and not pose_of(e):
                gain = 1.0  # the stated intensity picks the peak's range (STRENGTH); gain boosts a missed event
            if e.attribute == NEUTRAL:
                continue
            if e.attribute == TALK:
                placed.append(Placed(TALK, t, t + L, gain, []))
                continue
            if pose_of(e):  # a keyframed event: its natural length, or the slot when it is held
                n = L if _holds(e) else min(L, natural_frames(pose_of(e), e.count, fps))
                a = t + (L - n) // 2
                placed.append(Placed(e.attribute, a, a + n, gain, [], e.side, pose_of(e), e.count, level=level))
                continue
            if e.attribute == CLOSE_EYES or (e.attribute in HOLDABLE and len(segs) == 1):
                placed.append(Placed(e.attribute, t, t + L, gain, [(segs[0], t, L)], e.side, level=level))
                continue
            # counted or short events: copies spread over the slot, each at its natural length
            lens = [s.b - s.a for s in segs]
            free = L - sum(lens) + segs[0].margin * 2 * (len(segs) - 1)
            gap = free // max(1, len(segs) - 1) if len(segs) > 1 else 0
            off = (L - sum(lens)) // 2 if len(segs) == 1 else 0
            p, pieces = t + max(0, off), []
            for s, n in zip(segs, lens):
                pieces.append((s, p, n))
                p += n - 2 * s.margin + gap
            placed.append(Placed(e.attribute, t, t + L, gain, pieces, e.side, level=level))
        t += L + between
    return placed


TALK_JAW_STD = 0.05
"""The jaw's motion in captured talk: the median over the built-in library's talk segments of jawOpen's standard
deviation (0.05; a test measures it). A talk track below it is scaled up to it (at most 2x), so a dataset
whose detected talk includes quiet stretches still talks as visibly."""


def talk_energy(lib: Library, seg: Segment) -> float:
    """jawOpen's standard deviation inside one talk segment (its margins left out)."""
    core = lib.motion[seg.clip][seg.a + seg.margin : max(seg.a + seg.margin + 1, seg.b - seg.margin)]
    return float(np.std(core[:, _IX["jawOpen"]]))


def _talk_track(lib: Library, n: int, rng: np.random.Generator, lively: bool = True) -> np.ndarray:
    """``n`` frames of lip offsets tiled from talk segments (crossfaded over their margins): the livelier half of
    the library's talk segments (by :func:`talk_energy`), the track scaled up to :data:`TALK_JAW_STD` where its
    jaw moves less (at most 2x). ``lively=False``: every talk segment, as captured (for
    benchmarks/ablation_talk_energy.py)."""
    pool = lib.segments.get(TALK) or []
    if not pool:
        raise InputError("the library has no captured 'talk' segment")
    if lively:
        energy = [talk_energy(lib, s) for s in pool]
        pool = [s for s, e in zip(pool, energy) if e >= np.median(energy)]
    out = np.zeros((n, FACE_DIM), np.float32)
    t = 0
    while t < n:
        s = pool[int(rng.integers(len(pool)))]
        o = _offset(lib, s, None)
        k = min(len(o), n - t)
        out[t : t + k] += o[:k]
        t += max(1, len(o) - 2 * s.margin)
    jaw = float(np.std(out[:, _IX["jawOpen"]]))
    if lively and 0 < jaw < TALK_JAW_STD:
        lips = [_IX[c] for c in LIPS]
        out[:, lips] *= min(2.0, TALK_JAW_STD / jaw)
    return out * _window(n, int(MARGIN_S * lib.fps))[:, None]


def render(
    placed: list[Placed], lib: Library, n_frames: int, seed: int = 0, lip_smooth_s: float = LIP_SMOOTH_S
) -> np.ndarray:
    """The motion ``[n_frames, 56]`` of a layout: the neutral base plus every event's offsets. Where two
    events move the same expression weight (talk and an open mouth, surprise and an open mouth) the larger
    offset wins instead of the two adding up; head rotations add."""
    rng = np.random.default_rng(seed + 7)
    up = np.zeros((n_frames, FACE_DIM), np.float32)
    down = np.zeros((n_frames, FACE_DIM), np.float32)
    head = np.zeros((n_frames, FACE_DIM - N_EXPR), np.float32)

    def add(o: np.ndarray, a: int, b: int) -> None:
        up[a:b] = np.maximum(up[a:b], o)
        down[a:b] = np.minimum(down[a:b], o)
        head[a:b] += o[:, N_EXPR:]

    for p in placed:
        if p.attribute == TALK:
            add(p.gain * _talk_track(lib, p.end - p.start, rng), p.start, p.end)
            continue
        if p.pose == "shake":
            o = np.zeros((p.end - p.start, FACE_DIM), np.float32)
            peak = min(SHAKE_MAX_RAD, p.gain * SHAKE_RAD[min(SHAKE_RAD, key=lambda k: abs(k - p.level))])
            o[:, N_EXPR + HEAD_AXIS[SHAKE_HEAD]] = shake_track(p.end - p.start, p.count, peak, lib.fps)
            add(o, p.start, p.end)
            continue
        if p.pose == NOD:
            o = np.zeros((p.end - p.start, FACE_DIM), np.float32)
            peak = p.gain * NOD_RAD[min(NOD_RAD, key=lambda k: abs(k - p.level))]
            o[:, N_EXPR + HEAD_AXIS[NOD]] = nod_track(p.end - p.start, p.count, min(peak, 0.4), lib.fps)
            add(o, p.start, p.end)
            continue
        if p.pose:
            o = np.zeros((p.end - p.start, FACE_DIM), np.float32)
            o[:, :N_EXPR] = pose_track(p.pose, p.side, p.end - p.start, p.count, p.gain, lib.fps)
            add(o, p.start, p.end)
            continue
        if p.attribute == TURN and p.side in ("left", "right") and p.pieces:  # the eyes lead the head
            o = np.zeros((p.end - p.start, FACE_DIM), np.float32)
            o[:, :N_EXPR] = pose_track("gaze", p.side, p.end - p.start, 1, 0.6, lib.fps)
            add(o, p.start, p.end)
        for seg, t0, L in p.pieces:
            o = _offset(lib, seg, p.side, lip_smooth_s)
            if p.attribute == CLOSE_EYES:  # the blink's closed middle, held
                o = _stretch(o, L, seg.margin)
                mid = slice(seg.margin, L - seg.margin)
                o[mid] = np.maximum(o[mid], o[mid].max(0, keepdims=True) * 0.95)
            elif len(o) != L:
                o = _stretch(o, L, seg.margin)
            if p.attribute in SYMMETRIC and p.side is None:  # both sides alike (captured ones lean to one)
                for a, b in _PAIRS[p.attribute]:
                    o[:, a] = o[:, b] = (o[:, a] + o[:, b]) / 2
            if p.attribute in CHANNELS and p.attribute not in {*HEAD_AXIS, TALK}:  # emotions: as captured
                o[:, :N_EXPR] *= _strength(o, p.attribute, p.level)
            if p.attribute == FROWN:  # brows drawn down and together wrinkle the nose's root (AU4)
                for d, n in zip(both_sides("browDown"), both_sides("noseSneer")):
                    o[:, _IX[n]] = np.maximum(o[:, _IX[n]], FROWN_SNEER * o[:, _IX[d]])
            o = p.gain * o
            if p.attribute == SHAKE_HEAD:  # made stronger or not, a wider shake reads as a turn
                o[:, N_EXPR:] *= min(1.0, SHAKE_MAX_RAD / max(float(np.abs(o[:, N_EXPR:]).max()), 1e-9))
            a, b = max(0, t0), min(n_frames, t0 + L)
            add(o[a - t0 : b - t0], a, b)
    out = np.repeat(lib.neutral[None].astype(np.float32), n_frames, 0)
    out[:, :N_EXPR] += up[:, :N_EXPR] + down[:, :N_EXPR]
    out[:, N_EXPR:] += head
    out[:, :N_EXPR] = np.clip(out[:, :N_EXPR], 0.0, 1.0)
    return out


STRENGTH = {0.35: (0.15, 0.3), 0.6: (0.3, 0.6), 1.0: (0.6, 0.9), 1.4: (0.85, 1.0)}
"""The peak of a captured event's main channels by stated intensity (two softening words 0.35, "slightly"
0.6, plain 1, "very" 1.4: ``anima.text2face.prompt.FAINT``): a
segment whose peak falls outside the range is scaled into it (captured faces differ in how far they move;
a prompt's "smiles" should not depend on whose smile was drawn). Blinks and closed eyes close the eye."""
STRENGTH_OF = {n: e.strength for n, e in VOCABULARY.items() if e.strength}
"""Per event, its own ranges (the vocabulary's): blinks and closed eyes close the eye; an open mouth is
jawOpen 0.3 (the detector) up to a yawn's 0.45 held a second; a smile and a frown at full strength on their
own channel (mouthSmile 0.6 alone, or browDown 0.6 alone, barely changes the face a viewer sees; the
face model's brows move little, so even a slight frown needs browDown 0.8 to be seen); raised brows on the
brows' mean."""
SYMMETRIC = tuple(n for n, e in VOCABULARY.items() if e.symmetric)
"""Events made alike on both sides when no side is named: a captured segment's left-right difference is
mostly the fit's (head pose) and leaves one brow or one corner weak (a frown at full strength)."""
_PAIRS = {
    a: [(_IX[c], _IX[c[:-2] + "_R"]) for c in CHANNELS[a] if c.endswith("_L") and c[:-2] + "_R" in _IX]
    for a in SYMMETRIC
}
FROWN_SNEER = 0.35
"""A frown's noseSneer at least this fraction of its browDown: the face model's browDown alone lowers the
brows by less than a tracker sees in a captured frown (chosen on the development prompt suite)."""
PEAK_OF_MEAN = {n for n, e in VOCABULARY.items() if e.peak_of_mean}
"""Events whose peak is taken on the mean of their main channels, not the largest: a captured raise lifts
the inner brows well above the outer ones, and the face model's brows rise visibly only with both."""
MAIN = {n: e.main for n, e in VOCABULARY.items() if e.main}
"""The channels whose peak is measured (default: every channel of the event)."""


def _strength(o: np.ndarray, attr: str, level: float) -> float:
    """The factor that brings segment offsets ``o``'s peak on ``attr``'s main channels into its range."""
    idx = [_IX[c] for c in MAIN[attr]] if attr in MAIN else _channel_idx(attr)[0]
    if not idx:
        return 1.0
    peak = float(o[:, idx].mean(1).max() if attr in PEAK_OF_MEAN else o[:, idx].max())
    if peak <= 1e-6:
        return 1.0
    table = STRENGTH_OF.get(attr, STRENGTH)
    lo, hi = table[min(table, key=lambda k: abs(k - level))]
    return float(np.clip(peak, lo, hi) / peak)


def detect_motion(motion: np.ndarray, fps: float = TEXT_FPS, pad_s: float = 1.0) -> list[tuple[str, float, float]]:
    """The dataset's detectors on generated face motion ``[F, 56]``, with its first and last frames held for
    ``pad_s`` on either side: the detectors measure brows and lids against the clip's own rest (a
    percentile), which a 3-s clip that is mostly one held event does not show. Events are returned on the
    motion's own time axis, those wholly inside the padding dropped. The same rule for every method."""
    p = int(round(pad_s * fps))
    padded = np.concatenate([np.repeat(motion[:1], p, 0), motion, np.repeat(motion[-1:], p, 0)])
    n = len(motion) / fps
    out = []
    for a, s, e in detect(generated_sequence(fps, face=padded)):
        s, e = s - pad_s, e - pad_s
        if e > 0 and s < n:
            out.append((a, max(0.0, s), min(n, e)))
    return out


def _found(events, attr: str, start: int, end: int, fps: float) -> int:
    return sum(1 for a, s, e in events if a == attr and s * fps < end and e * fps > start)


def compose(
    plan: Plan,
    lib: Library,
    n_frames: int | None,
    seed: int = 0,
    rounds: int = 3,
    draws: int = 6,
    max_frames: int | None = None,
) -> tuple[np.ndarray, dict]:
    """The prompt's motion ``[n_frames, 56]`` and a record of what made it (segments, gains, checks).
    ``n_frames`` None: as long as the prompt's events need, at least :data:`DEFAULT_FRAMES` (the first
    layout's need; a later draw that would need more is skipped); a given ``n_frames`` that cannot hold the
    events is refused (:class:`TooShort`). ``max_frames``: the longest clip made; events that need more are
    refused (an :class:`InputError`) after their layout, before anything is rendered.

    Up to ``draws`` layouts (other segments), each rendered up to ``rounds`` + 1 times: an event the
    detectors miss is made 1.35x stronger, a mouth that reads as talk when none was asked is smoothed more.
    The first clean rendering is kept, else the one with the fewest misses."""
    best = None
    avoid: set = set()
    fit = n_frames is None
    n_frames = DEFAULT_FRAMES if fit else n_frames
    for draw in range(draws):
        try:
            placed = plan_layout(plan, lib, n_frames, seed + 1009 * draw, frozenset(avoid))
        except TooShort as e:
            if not fit:
                raise
            if best is not None:  # the length is set by the first layout: skip a draw that needs more
                continue
            if max_frames is not None and e.need > max_frames:
                raise InputError(
                    f"the prompt's events need {e.need} frames ({e.need / lib.fps / 60:.1f} min): the timeline "
                    f"method makes at most {max_frames} ({max_frames / lib.fps / 60:g} min); ask for fewer events"
                ) from None
            n_frames = e.need
            placed = plan_layout(plan, lib, n_frames, seed + 1009 * draw, frozenset(avoid))
        detectable = [  # (a faint event, asked for, may stay under the detectors' threshold: not made stronger)
            p
            for p in placed
            if p.attribute in ATTRIBUTES and (p.side is None or p.attribute == TURN) and p.level > FAINT
        ]
        lip_s = LIP_SMOOTH_S
        talking = any(p.attribute == TALK for p in placed)
        for _ in range(rounds + 1):
            motion = render(placed, lib, n_frames, seed, lip_s)
            events = detect_motion(motion, lib.fps)
            missing = [
                p for p in detectable if _found(events, p.attribute, p.start, p.end, lib.fps) < len(p.pieces or [1])
            ]
            false_talk = not talking and any(a == TALK for a, _, _ in events)
            bad = len(missing) + int(false_talk)
            if best is None or bad < best[0]:
                best = (bad, motion, events, [Placed(**vars(p)) for p in placed], lip_s)
            if not bad:
                break
            for p in missing:
                p.gain *= 1.35
            if false_talk:  # an open mouth that reads as speech: smooth its lips more
                lip_s *= 2
        if best[0] == 0:
            break
        avoid |= {(sg.clip, sg.a) for p in missing for sg, _, _ in p.pieces}
    _, motion, events, placed, lip_s = best
    record = {
        "lip_smooth_s": lip_s,
        "events": [
            {
                "attribute": p.attribute,
                "start_s": round(p.start / lib.fps, 3),
                "end_s": round(p.end / lib.fps, 3),
                "gain": round(p.gain, 3),
                "side": p.side,
                "from": [
                    {
                        "clip": lib.sources[s.clip],
                        "start_s": round(s.a / lib.fps, 3),
                        "end_s": round(s.b / lib.fps, 3),
                        "placed_s": round(t0 / lib.fps, 3),
                    }
                    for s, t0, _ in p.pieces
                ],
            }
            for p in placed
        ],
        "detected": [[a, round(s, 3), round(e, 3)] for a, s, e in events],
        "all_found": best[0] == 0,
        "length": "fitted to the events" if fit else "asked",
    }
    return motion, record
