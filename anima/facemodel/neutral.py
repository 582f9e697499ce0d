"""A speaker's rest face, so that a neutral face reads neutral. Pure functions.

The face fit explains a person's face by an identity (their shape) and an expression; whatever of a face's
shape the identity basis cannot hold lands in the expression, so some speakers read a smile or a frown at rest
(a neutral CREMA-D clip read browDown_L 0.29, a LivePortrait speaker mouthSmile 0.2 on every frame). Each
captured clip's rest face is estimated from the clip itself: per channel of :data:`REST_CHANNELS` (the
expressions a face shape can imitate), the :data:`REST_PERCENTILE`-th percentile of its tracked frames, at most
:data:`MAX_REST` (a clip-long smile keeps most of itself), on clips of at least :data:`MIN_SECONDS`; the
channel is then measured from it: ``(w - rest) / (1 - rest)``, clipped to [0, 1].

A clip-long expression (an angry take's lowered brows) is eaten by that estimate; a clip of the same person at
rest names the rest instead (``anima capture CLIP --neutral REST``): each channel's median over the rest clip's
tracked frames (:func:`reference_rest`), stored in the sequence's ``meta["rest_face"]`` and taken in place of
the clip's own estimate.

``capture.npz`` keeps the fit as it is (the dataset's detectors measure their own baselines); every animation
made from a capture (the character, ``arkit.csv``, ``face.glb``, Live Link, VMC, FBX) is made from the face
measured from its rest (:func:`presented`), and ``info.json`` says the rest it took.
"""

from __future__ import annotations

import numpy as np

REST_CHANNELS = tuple(
    f"{base}_{s}"
    for base in (
        "mouthSmile",
        "mouthFrown",
        "browDown",
        "browInnerUp",
        "browOuterUp",
        "cheekSquint",
        "noseSneer",
        "mouthDimple",
        "mouthPress",
        "mouthStretch",
        "eyeSquint",
    )  # fmt: skip
    for s in ("L", "R")
)
FADE_S = 0.25
"""Where the face is lost, the animation eases from the last seen face to the rest face over this long, and back
from the rest face to the next seen one (a short drop-out never reaches the rest: it holds)."""
REST_PERCENTILE = 10.0
MAX_REST = 0.15
"""What a clip's own rest can take out of a channel. With the expression reader (:mod:`anima.facemodel.reader`)
no development clip's rest came near it (CREMA-D's six takes and MEAD's six read the same with 0.35 and 0.15, and
0.08 cut into the disgusted take), so a clip-long expression keeps all of itself above it (0.35 before the reader,
when the fit read up to 0.36 on a neutral face)."""
MIN_SECONDS = 2.0


def rest_face(expression: np.ndarray, names: list[str], tracked: np.ndarray, fps: float) -> dict[str, float]:
    """``{channel: rest value}`` of a captured clip (see the module docstring); empty for a short clip."""
    tracked = np.asarray(tracked, bool)
    if tracked.sum() < MIN_SECONDS * fps:
        return {}
    out = {}
    for n in REST_CHANNELS:
        if n in names:
            r = float(np.percentile(expression[tracked, names.index(n)], REST_PERCENTILE))
            if r > 0.01:
                out[n] = round(min(r, MAX_REST), 4)
    return out


def reference_rest(expression: np.ndarray, names: list[str], tracked: np.ndarray) -> dict[str, float]:
    """``{channel: rest value}`` from a clip of the person at rest: each :data:`REST_CHANNELS` channel's median
    over the tracked frames (values over 0.01 kept; no cap: the clip is the rest by the user's word)."""
    tracked = np.asarray(tracked, bool)
    out = {}
    for n in REST_CHANNELS:
        if n in names and tracked.any():
            r = float(np.median(expression[tracked, names.index(n)]))
            if r > 0.01:
                out[n] = round(min(r, 0.95), 4)
    return out


MAX_NEUTRAL = 0.25
"""A ``--neutral`` take whose face holds a :data:`REST_CHANNELS` channel at or over this (its median) is not at
rest, and is refused. As the expression reader reads them, CREMA-D actor 1001's neutral take holds up to 0.18
(browDown_L), his angry, sad and fearful takes up to 0.23 (not told apart from a rest this way), his disgusted take
0.28 (browDown_L) and his happy take 0.41 (mouthSmile_R), which are refused. Chosen on those six takes
(development)."""


def not_neutral(rest: dict[str, float]) -> list[tuple[str, float]]:
    """The channels of a reference rest (:func:`reference_rest`) that say the take was not at rest, strongest
    first: ``[(channel, value), ...]`` at or over :data:`MAX_NEUTRAL`."""
    return sorted(((n, v) for n, v in rest.items() if v >= MAX_NEUTRAL), key=lambda x: -x[1])


def stored_rest(meta: dict) -> dict[str, float] | None:
    """The rest face a sequence's ``meta`` names (``meta["rest_face"]["channels"]``, set by ``--neutral``), or
    None; channels outside :data:`REST_CHANNELS` and values outside [0, 0.95] are not taken."""
    rf = meta.get("rest_face")
    if not isinstance(rf, dict) or not isinstance(rf.get("channels"), dict):
        return None
    ok = {n: float(v) for n, v in rf["channels"].items()
          if n in REST_CHANNELS and isinstance(v, (int, float)) and 0.0 <= v <= 0.95}  # fmt: skip
    return ok


def from_rest(expression: np.ndarray, names: list[str], rest: dict[str, float]) -> np.ndarray:
    """The expression measured from ``rest`` (a copy)."""
    out = np.array(expression, np.float32, copy=True)
    for n, r in rest.items():
        k = names.index(n)
        out[:, k] = np.clip((out[:, k] - r) / (1.0 - r), 0.0, 1.0)
    return out


def is_captured(meta: dict) -> bool:
    """Whether a sequence was captured from a video or a camera (its face fitted), not generated."""
    return "tracker" in meta or meta.get("recorded_by") == "anima live"


def presented(seq) -> tuple[np.ndarray, dict[str, float]]:
    """The face an animation shows for a tracked sequence ``seq``: a captured clip's expression measured from its
    rest face (the one ``--neutral`` stored, else the clip's own estimate), a generated one's as it is. Returns
    (``[F, E]``, the rest taken)."""
    if not is_captured(seq.meta):
        return np.asarray(seq.expression, np.float32), {}
    rest = stored_rest(seq.meta)
    if rest is None:
        rest = rest_face(seq.expression, list(seq.expr_names), seq.tracked, seq.fps)
    return from_rest(seq.expression, list(seq.expr_names), rest), rest


def faded(W: np.ndarray, tracked: np.ndarray, fps: float) -> np.ndarray:
    """Weights ``[F, K]`` with the frames where no face was seen eased to the rest (zeros) and back: the nearest
    seen frame's weights, scaled down over :data:`FADE_S` of distance from it (zeros where nothing was seen)."""
    tracked = np.asarray(tracked, bool)
    out = np.zeros_like(W)
    if not tracked.any():
        return out
    seen = np.flatnonzero(tracked)
    i = np.arange(len(W))
    pos = np.clip(np.searchsorted(seen, i), 1, len(seen)) - 1
    left, right = seen[pos], seen[np.minimum(pos + 1, len(seen) - 1)]
    nearest = np.where(np.abs(i - left) <= np.abs(right - i), left, right)
    gap = np.abs(i - nearest).astype(np.float64)
    fade = np.clip(1.0 - gap / max(FADE_S * fps, 1.0), 0.0, 1.0)
    return W[nearest] * fade[:, None].astype(W.dtype)
