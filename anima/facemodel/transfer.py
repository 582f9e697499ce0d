"""Expression transfer by geometry: the character's face moved as the fitted ICT face moves, not by the names of
their blendshapes. Pure functions.

The 53 weights fitted on the ICT face mean "this much of ICT's jawOpen, of ICT's mouthSmile_L"; the character's
own 53 morphs (MakeHuman's Face Units) carry the same names but move its face differently (its jawOpen parts
the lips less, its smile lifts the corners less, its brows barely move). Applied by name, a man frowning hard
reads as a blank face. Here the character's weights are chosen, per frame, so that twelve points of its face
move as the same twelve points of the fitted face do:

* **The points** (:func:`face_points`), found on each model by what its own morphs do (the same definitions
  on both, so their semantics match): the upper lid's centre of each eye (what eyeBlink moves most) and the
  lower lid's (the still vertex nearest where the blink takes the upper lid), the inner and outer brow of each
  side (browInnerUp, browOuterUp), the mouth's corners (mouthSmile), and the inner edges of the upper and lower
  lip on the midline (mouthUpperUp, mouthLowerDown).
* **The match** (:class:`Transfer`): each point's displacement from the rest face, in units of the face's size
  (the distance between the upper lids), on the ICT face (exact, from the fitted weights and the person's
  identity) and on the character (linear in its weights); the character's weights of :data:`TRANSFERRED` (the
  brows and the lids, where the two models' morphs differ most) minimise the squared difference of the brows'
  and lids' displacements plus :data:`PULL` times their squared difference from the fitted weights, then are
  clipped to [0, 1]; the other channels keep the fitted weights. The mouth is left by name: read back from a
  close-up render by a face tracker (``benchmarks/face_readback.py``), the mouth followed the video better by
  name (r 0.70-0.98 against 0.59-0.94 with the lips in the match, on five clips), the brows better by geometry
  (Obama's r 0.53 by name, 0.74 matched).
* **The lids as the video shows them** (:meth:`Transfer.follow_lids`, for a captured clip): the fitted face's
  lids follow Face Mesh's lid landmarks loosely (read back on d0, the fitted face's eye opening has r 0.23 / 0.43
  with the video's), so the character's lids are set from the landmarks themselves: each eye's opening over the
  clip's open eye (:func:`eye_opening`) is the opening the character's close-up must show, through its own
  calibration (:data:`EYE_SHOWN`, :func:`lid_gap`: a face tracker reads its lids as their gap down to about two
  thirds of the rest gap, then as shut within a tenth more; a risen lower lid moves that cliff to smaller gaps, so
  the calibration is a table over the frame's eyeSquint too), by eyeBlink or eyeWide. Read back on the same five
  clips, the eyes' r rose from 0.37-0.95 to 0.90-0.98 with the gap simply scaled (``benchmarks/face_readback.py``);
  the calibration (and no lash line painted on the lids) brought the blinks the character missed on fresh clips
  (demo 3: 13 of the video's 18, then 16).
* **The lower lids as the video shows them** (:meth:`Transfer.follow_lower_lids`, for a captured clip, before
  the lids' gap): each lower lid's rise above its clip median in the landmarks, a share of the open eye's gap
  (:func:`lower_lid_rise`), lifts the character's lower lid that share of its rest gap by eyeSquint, around
  the fit's clip-long squint; the gap is then set as above, so what the lower lid closes the upper lid no
  longer does. In a blink the lower lid holds its level (:func:`lower_lid_share`): the eyes' calibration was
  measured with the upper lid alone closing. A tracker's brow height is measured to the upper lid, and an
  angry speaker's squint raises the lower lid while the upper lid stays: with the whole gap closed by the upper
  lid, a furious clip's brows read back at 0.53, with the lower lid risen as the video's, 0.84. Chosen on the
  development clips (the nine and CREMA-D's six takes; brows' mean r 0.911 to 0.916, eyes' 0.944 either way, no
  blink count changed); the blink rule after the later-look sets counted five more blink misses without it.
* **The brows as the video shows them** (:meth:`Transfer.follow_brows`, for a captured clip): each brow's height
  above its eye's corners in Face Mesh's landmarks, over the face's height, from the clip's median
  (:func:`brow_raise`), is the height the character's close-up must show: through its own calibration
  (:data:`BROW_SHOWN`: a tracker reads about half of what its brow points move) its brow points rise above their
  level at the clip's median (the fit's, from its rest face); that side's browInnerUp and browOuterUp are solved
  for it (least squares, :data:`BROW_PULL` towards the transferred weights), before the lids are set. A frown
  (the brows lower than those channels at zero leave them) is taken by browDown, whose mean over the clip stays
  the fit's (:func:`keep_mean`): solved freely, every downward move of a talking neutral face became browDown
  (CREMA-D's neutral take read 0.117 at rest, over the issue's 0.1); kept at the fit's mean, a speaker's face
  over the clip reads as before and only the frown's timing comes from the landmarks. Read back on the nine
  development clips, the brows' r rose from 0.82-0.97 (by the transfer) to 0.90-0.97 with the landmarks and to
  0.93-0.97 with the calibration and the frown (the 2.4-s radio clip 0.43, then 0.72), the blinks unchanged.
* **The lips as the video shows them** (:meth:`Transfer.follow_lips`, for a captured clip): the fitted face's lip
  gap follows Face Mesh's inner lips loosely where a speaker talks with nearly closed lips (d9: r 0.75), and the
  character's lips are parted at rest (a dark sliver a face tracker reads as an opening), so the character's lip
  gap is set from the landmarks themselves: the inner lips' distance over the face's height
  (:func:`lip_opening`) is the opening the character's close-up must show, through the character's own
  calibration (:data:`LIP_SHOWN`: what its render shows for a lip gap); an opening smaller than the smallest the
  character shows shuts its lips (:data:`LIP_SHUT`). jawOpen opens and mouthClose closes, undoing each other
  first, the other channels kept. Read back on the five development clips and Reagan's, the mouth's r rose from
  0.74-0.99 to 0.87-1.00 (``benchmarks/face_readback.py``).
"""

from __future__ import annotations

import numpy as np

POINTS = ("upper_lid_L", "lower_lid_L", "upper_lid_R", "lower_lid_R", "brow_in_L", "brow_out_L", "brow_in_R",
          "brow_out_R", "corner_L", "corner_R", "upper_lip", "lower_lip")  # fmt: skip
PULL = 0.01
"""How strongly a character weight stays at the fitted weight (against the points' squared displacement, in
face sizes)."""
TRANSFERRED = tuple(f"{b}_{s}" for b in ("browDown", "browInnerUp", "browOuterUp", "eyeBlink", "eyeSquint", "eyeWide")
                    for s in ("L", "R"))  # fmt: skip
MATCHED = ("upper_lid_L", "lower_lid_L", "upper_lid_R", "lower_lid_R", "brow_in_L", "brow_out_L", "brow_in_R",
           "brow_out_R")  # fmt: skip
"""The points the match uses (the brows' and the lids')."""


EYES = {"L": (386, 374, 362, 263), "R": (159, 145, 33, 133)}
"""MediaPipe Face Mesh's points of each eye, the person's left and right: (upper lid, lower lid, corner, corner)."""


OPEN_PERCENTILE = 90
"""The open eye's opening over a clip: this percentile of its frames (capture's blink rule,
:data:`anima.capture.pipeline.BLINK_OPEN`, takes the same open eye). The median (50) let a clip of long squints
count its open eyes as wide, and the character's lids pinned at their widest read back as extra blinks (d3: 7
against the video's 5; 90: 5); chosen on the five development clips of ``benchmarks/face_readback.py``."""


EYE_SHOWN = (
    (0.0, 0.1, 0.2, 0.3, 0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.8, 0.9, 1.0, 1.1),
    (0.0, 0.125, 0.25, 0.375, 0.5, 0.75, 1.0),
    (
        (0.158, 0.163, 0.164, 0.189, 0.21, 0.219, 0.227, 0.242, 0.52, 0.604, 0.686, 0.794, 0.912, 0.988, 1.041),
        (0.158, 0.163, 0.164, 0.192, 0.21, 0.219, 0.227, 0.302, 0.52, 0.604, 0.692, 0.794, 0.912, 0.988, 1.045),
        (0.158, 0.165, 0.169, 0.192, 0.21, 0.219, 0.256, 0.465, 0.596, 0.639, 0.692, 0.813, 0.912, 0.988, 1.045),
        (0.158, 0.165, 0.182, 0.192, 0.21, 0.219, 0.269, 0.472, 0.596, 0.639, 0.692, 0.824, 0.912, 0.988, 1.045),
        (0.158, 0.165, 0.187, 0.192, 0.21, 0.222, 0.269, 0.472, 0.608, 0.639, 0.704, 0.824, 0.912, 0.988, 1.045),
        (0.158, 0.181, 0.187, 0.192, 0.21, 0.262, 0.498, 0.599, 0.625, 0.668, 0.732, 0.828, 0.912, 0.988, 1.045),
        (0.158, 0.186, 0.187, 0.192, 0.254, 0.449, 0.556, 0.609, 0.634, 0.679, 0.748, 0.841, 0.92, 0.988, 1.045),
    ),
)
"""The character's eyes as its close-up shows them: ``(gaps, squints, reads)``, its lids' gap (over its rest gap,
:meth:`Transfer.lid_gaps`), its eyeSquint weight (the lower lid risen), and ``reads [squints, gaps]``, the eye's
opening Face Mesh reads there (over what it reads at rest with no squint; the reader's measure of
:func:`eye_ratios`), increasing along both. Read back, the closing upper lid reads as its gap down to about 0.65,
then falls fast (0.6 reads 0.52, 0.55 reads 0.24) to a shut eye's 0.16-0.2: a tracker sees the lid's edge meet the
iris and calls the eye shut. With the lower lid risen the cliff comes at smaller gaps (0.55 reads 0.47 at eyeSquint
0.375, 0.61 at 1): the same gap shows more of the iris. Measured on the character alone (no video; three head poses,
both eyes, the lids swept shut and open again at each squint; the eyes drawn anti-aliased as the close-up draws them,
:func:`anima.render.avatar.draw_close_up`): the reads' lower third (their 33rd percentile, so that the gap is chosen
on the open side of the cliff), fitted increasing in the gap and in the squint together: ``python
benchmarks/face_readback.py --calibrate`` (``benchmarks/results/eye_calibration.json``); a test measures it again."""


LIPS = (13, 14, 10, 152)
"""Face Mesh's points of the mouth's opening: (inner upper lip, inner lower lip) on the midline, over the face's
height (forehead, chin): the same measure a face tracker reads back from a render."""

LIP_SHOWN = (0.0082, 0.452)
"""The character's close-up, read back by Face Mesh (the mouth's opening, :data:`LIPS`): ``offset + slope * gap``
for its lip gap ``gap`` above rest (face sizes, :meth:`Transfer.lip_gaps`), the jaw opening from rest to 0.6.
Measured on the character alone (no video): ``python benchmarks/face_readback.py --calibrate``
(``benchmarks/results/lip_calibration.json``); a test measures it again."""

LIP_SHUT = -0.01
"""The character's lip gap (face sizes, from rest) where the person's lips are shut: past touching (its rest
lips are parted by a sliver that reads as an opening; closing them by 0.006 reads as shut in the calibration's
sweep)."""


BROWS = {"L": (334, 362, 263), "R": (105, 33, 133)}
"""Face Mesh's points of each brow, the person's left and right: (the brow, the eye's two corners)."""

BROW_SHOWN = 0.277
"""The character's brows as its close-up shows them: the brows' height Face Mesh reads (:func:`brow_heights`, face
heights, from rest) per face size its brow points rise (:meth:`Transfer.brow_rise`), the brows swept from
browDown 1 through rest to browInnerUp and browOuterUp 1: the reader sees about three fifths of what the points move
(in face heights, the lips' :data:`LIP_SHOWN` slope of 0.45 would be all of it). Measured on the character alone (no
video; three head poses, both brows): ``python benchmarks/face_readback.py --calibrate``
(``benchmarks/results/brow_calibration.json``); a test measures it again."""

BROW_PULL = 0.001
"""How strongly the brows' raise channels stay at the transferred weights (against the brow points' squared miss,
in face sizes); 1e-4 and 1e-2 read back within 0.02 on the development clips."""


def _pixels(landmarks: np.ndarray, width: int, height: int) -> np.ndarray:
    """Face Mesh's landmarks ``[F, 478, 2+]`` (normalised image coordinates) in pixels ``[F, 478, 2]``."""
    return np.asarray(landmarks, np.float64)[..., :2] * [width, height]


def _face_height(px: np.ndarray) -> np.ndarray:
    """The face's height ``[F]`` (forehead to chin, :data:`LIPS`) in pixels ``px [F, 478, 2]``."""
    return np.maximum(np.linalg.norm(px[:, LIPS[2]] - px[:, LIPS[3]], axis=-1), 1e-6)


def _persons_sides(px: np.ndarray, on_left: np.ndarray, on_right: np.ndarray) -> np.ndarray:
    """``[F, 2]``: a measure of the person's left and right, from the same measure taken with Face Mesh's left
    and right points (``on_left``, ``on_right`` ``[F]``). Which is the person's left is read off each frame's
    picture (the eye on the picture's right; a mirrored video swaps them)."""
    mirrored = px[:, EYES["L"][2], 0] < px[:, EYES["R"][2], 0]
    return np.stack([np.where(mirrored, on_right, on_left), np.where(mirrored, on_left, on_right)], -1)


def _from_clip(values: np.ndarray, tracked: np.ndarray) -> np.ndarray | None:
    """The frames ``tracked`` whose ``values [F, 2]`` are finite (``[F]`` bool), or None under ten of them."""
    ok = np.asarray(tracked, bool) & np.isfinite(values).all(-1)
    return ok if ok.sum() >= 10 else None


def brow_heights(landmarks: np.ndarray, width: int, height: int) -> np.ndarray:
    """Each brow's height ``[F, 2]`` (the person's left, right) above its eye's corners over the face's height in
    Face Mesh's landmarks ``[F, 478, 2+]`` (normalised)."""
    px = _pixels(landmarks, width, height)
    face = _face_height(px)
    h = {s: np.linalg.norm((px[:, a] + px[:, b]) / 2 - px[:, p], axis=-1) / face for s, (p, a, b) in BROWS.items()}
    return _persons_sides(px, h["L"], h["R"])


def brow_raise(landmarks: np.ndarray, tracked: np.ndarray, width: int, height: int) -> np.ndarray:
    """Each brow's height ``[F, 2]`` (:func:`brow_heights`) from its median over the frames ``tracked``; NaN
    where no face was seen (or under ten frames seen)."""
    out = brow_heights(landmarks, width, height)
    ok = _from_clip(out, tracked)
    if ok is None:
        return np.full(out.shape, np.nan)
    return np.where(ok[:, None], out - np.median(out[ok], axis=0), np.nan)


def lip_opening(landmarks: np.ndarray, width: int, height: int) -> np.ndarray:
    """The mouth's opening ``[F]`` in Face Mesh's landmarks ``[F, 478, 2+]`` (normalised image coordinates): the
    inner lips' distance over the face's height (:data:`LIPS`)."""
    px = _pixels(landmarks, width, height)
    return np.linalg.norm(px[:, LIPS[0]] - px[:, LIPS[1]], axis=-1) / _face_height(px)


def eye_ratios(landmarks: np.ndarray, width: int, height: int) -> np.ndarray:
    """Each eye's opening ``[F, 2]`` (the person's left, right) in Face Mesh's landmarks ``[F, 478, 2+]``
    (normalised image coordinates): the lids' distance over the eye's width."""
    px = _pixels(landmarks, width, height)
    o = {}
    for s, (up, lo, a, b) in EYES.items():
        w = np.maximum(np.linalg.norm(px[:, a] - px[:, b], axis=-1), 1e-6)
        o[s] = np.linalg.norm(px[:, up] - px[:, lo], axis=-1) / w
    return _persons_sides(px, o["L"], o["R"])


def eye_opening(landmarks: np.ndarray, tracked: np.ndarray, width: int, height: int) -> np.ndarray:
    """Each eye's opening ``[F, 2]`` (left, right; :func:`eye_ratios`) over the clip's open eye (its
    :data:`OPEN_PERCENTILE` over the frames ``tracked``); NaN where no face was seen."""
    ratio = eye_ratios(landmarks, width, height)
    return _over_open_eye(ratio, ratio, _from_clip(ratio, tracked))


def _over_open_eye(x: np.ndarray, ratio: np.ndarray, ok: np.ndarray | None) -> np.ndarray:
    """``x [F, 2]`` over the clip's open eye (the :data:`OPEN_PERCENTILE` of the eyes' ``ratio``
    (:func:`eye_ratios`) over the frames ``ok``); NaN outside them (all, for ``ok`` None) and where it is 0."""
    out = np.full(np.shape(x), np.nan)
    if ok is None:
        return out
    open_eye = np.percentile(ratio[ok], OPEN_PERCENTILE, axis=0)
    good = ok[:, None] & (open_eye > 0)
    out[good] = (x / np.where(open_eye > 0, open_eye, 1.0))[good]
    return out


def lower_lid_depths(landmarks: np.ndarray, width: int, height: int) -> np.ndarray:
    """Each lower lid's depth ``[F, 2]`` (the person's left, right) under its eye's corners in Face Mesh's landmarks
    ``[F, 478, 2+]`` (normalised): the lower lid's distance from the corners' line, across it (so a tilted head
    reads the same), over the eye's width; a squint (the lower lid rising) makes it smaller."""
    px = _pixels(landmarks, width, height)
    o = {}
    for s, (up, lo, a, b) in EYES.items():
        e = px[:, b] - px[:, a]
        w = np.maximum(np.linalg.norm(e, axis=-1), 1e-6)
        across = np.stack([-e[:, 1], e[:, 0]], -1) / w[:, None]  # the corners' line turned a quarter
        side = np.sign(np.nansum((px[:, lo] - px[:, up]) * across))  # pointing from the upper lid to the lower
        o[s] = ((px[:, lo] - (px[:, a] + px[:, b]) / 2) * across).sum(-1) * (side or 1.0) / w
    return _persons_sides(px, o["L"], o["R"])


def lower_lid_rise(landmarks: np.ndarray, tracked: np.ndarray, width: int, height: int) -> np.ndarray:
    """Each lower lid's rise ``[F, 2]`` (left, right) above its median over the frames ``tracked``
    (:func:`lower_lid_depths`), over the clip's open eye (:func:`eye_opening`'s, so it is a share of the open
    eye's lid gap); NaN where no face was seen."""
    depth = lower_lid_depths(landmarks, width, height)
    ok = _from_clip(depth, tracked)
    rise = depth if ok is None else np.median(depth[ok], axis=0) - depth
    return _over_open_eye(rise, eye_ratios(landmarks, width, height), ok)


LOWER_LID_CLIFF = (0.55, 0.65)
"""The lid gaps (over the rest gap) between which the character's close-up reads its eye as shutting fast
(:data:`EYE_SHOWN`: the upper lid's edge meets the iris): the lower lid follows the person's in full while the
eye is open at least as far as the close-up reads the upper of the two, not at all at or under the lower
(:func:`lower_lid_share`)."""


def lower_lid_share(opening: np.ndarray, shown=EYE_SHOWN, cliff=LOWER_LID_CLIFF) -> np.ndarray:
    """How much of the lower lid's rise (:func:`lower_lid_rise`) the character follows, for an eye's ``opening``
    (:func:`eye_opening`): 1 at or over what its close-up reads at the cliff's top (:data:`LOWER_LID_CLIFF`), 0 at
    or under what it reads at its foot, linear between. Closing further is a blink, the upper lid's: the eyes'
    calibration was measured with the upper lid alone closing, and a lower lid risen with a half-shut eye's (Face
    Mesh's lower lid rises a tenth or more of the open gap in a blink) left the upper lid short of the iris,
    where the close-up reads a half blink as open (on the development clips, a half blink of Noem's read 0.53 of
    the open eye, 0.35 with the lower lid still)."""
    gap, read = np.asarray(shown[0], np.float64), np.asarray(shown[2][0], np.float64)  # no squint: the upper lid's
    foot, top = np.interp(cliff[0], gap, read), np.interp(cliff[1], gap, read)
    return np.clip((np.asarray(opening, np.float64) - foot) / (top - foot), 0.0, 1.0)


def keep_mean(x: np.ndarray, mean: float) -> np.ndarray:
    """``clip(s * x, 0, 1)`` for the one ``s`` in [0, 1] that makes its mean ``mean`` (``x``'s own, clipped,
    where that is less): weights ``x [F] >= 0`` scaled down together until they average what they must, a zero
    kept zero and their order kept."""
    x = np.asarray(x, np.float64)
    lo, hi = 0.0, 1.0
    for _ in range(60):
        s = (lo + hi) / 2
        lo, hi = (lo, s) if np.clip(s * x, 0.0, 1.0).mean() > mean else (s, hi)
    return np.clip(lo * x, 0.0, 1.0) if np.clip(x, 0.0, 1.0).mean() > mean else np.clip(x, 0.0, 1.0)


SHUT_READ = 0.2
"""What a tracker reads of a shut eye (its opening over the open eye's, :func:`eye_opening`): the lids the export
carries close fully there (:func:`lid_closure`). Chosen on the face round trip's development identities
(``benchmarks/roundtrip_face.py``, identities 0-2; left eye's error and r over all frames): a held blink (truth 1)
reached eyeBlink 0.50 through the close-up's calibration (:data:`EYE_SHOWN`, which keeps Face Mesh reading the
character as it reads the person; error 0.07, r 0.68), 0.58 with the opening taken as the gap (0.07, 0.70), 0.71 /
0.75 / 0.78 closing linearly from the open eye to a shut reading of 0.2 / 0.3 / 0.4 (0.11 / 0.13 / 0.19: talking
eyes narrowed), 0.89 by the fit alone (0.18, 0.66); the opening itself down to :data:`LID_KNEE`, then closing to 0
at 0.2: 0.70 (0.07, 0.75)."""


LID_KNEE = 0.6
"""Down to this opening (of the open eye's) the lids' gap is the opening itself: a talking eye keeps its size."""


def lid_closure(opening: np.ndarray, shut=SHUT_READ, knee=LID_KNEE) -> np.ndarray:
    """The lid gap (over the rest gap) an eye's ``opening`` (over the open eye; :func:`eye_opening`) asks for: the
    opening itself down to ``knee`` (:data:`LID_KNEE`), from there linear to 0 at ``shut`` (:data:`SHUT_READ`),
    0 under it; at most 1.5; NaN stays NaN."""
    x = np.asarray(opening, np.float64)
    return np.clip(np.where(x < knee, knee * (x - shut) / (knee - shut), x), 0.0, 1.5)


def lid_gap(opening: np.ndarray, squint=0.0, shown=EYE_SHOWN) -> np.ndarray:
    """The character's lid gap (over its rest gap) whose close-up shows an eye's ``opening`` (over the open eye;
    :func:`eye_opening`) with its eyeSquint weight ``squint`` (a number, or one per opening): the inverse of each
    of ``shown``'s rows (:data:`EYE_SHOWN`), linear between its squints (clipped to them; NaN as none), shut (0) at
    or under the least a row reads, beyond its widest the gap grows as the opening does, at most 1.5; NaN stays
    NaN."""
    gap, levels = (np.asarray(v, np.float64) for v in shown[:2])
    x = np.asarray(opening, np.float64)
    per = np.stack(
        [np.where(x > r[-1], gap[-1] + (x - r[-1]), np.interp(x, r, gap)) for r in np.asarray(shown[2], np.float64)]
    )
    q = np.clip(np.nan_to_num(np.broadcast_to(np.asarray(squint, np.float64), x.shape)), levels[0], levels[-1])
    j = np.clip(np.searchsorted(levels, q, side="right") - 1, 0, max(len(levels) - 2, 0))
    if len(levels) == 1:
        out = per[0]
    else:
        t = (q - levels[j]) / (levels[j + 1] - levels[j])
        out = (1 - t) * np.take_along_axis(per, j[None], 0)[0] + t * np.take_along_axis(per, (j + 1)[None], 0)[0]
    return np.where(np.isfinite(x), np.clip(out, 0.0, 1.5), np.nan)


def face_points(V: np.ndarray, D: np.ndarray, names: list[str]) -> tuple[np.ndarray, float]:
    """The vertex indices of :data:`POINTS` on a face of rest vertices ``V [N, 3]`` and expression deltas
    ``D [E, N, 3]`` named ``names`` (ICT's 53), and the face's size (the upper lids' distance)."""
    ix = {n: i for i, n in enumerate(names)}
    mag = lambda n: np.linalg.norm(D[ix[n]], axis=-1)
    out = {}
    for s in ("L", "R"):
        m = mag(f"eyeBlink_{s}")
        up = int(np.argmax(m))
        out[f"upper_lid_{s}"] = up
        goal = V[up] + D[ix[f"eyeBlink_{s}"]][up]
        still = np.flatnonzero(m < 0.3 * m.max())
        out[f"lower_lid_{s}"] = int(still[np.argmin(np.linalg.norm(V[still] - goal, axis=-1))])
        out[f"brow_in_{s}"] = int(np.argmax(mag(f"browInnerUp_{s}")))
        out[f"brow_out_{s}"] = int(np.argmax(mag(f"browOuterUp_{s}")))
        out[f"corner_{s}"] = int(np.argmax(mag(f"mouthSmile_{s}")))
    size = float(np.linalg.norm(V[out["upper_lid_L"]] - V[out["upper_lid_R"]]))
    cx = (V[out["upper_lid_L"], 0] + V[out["upper_lid_R"], 0]) / 2
    mid = np.abs(V[:, 0] - cx) < 0.03 * size
    up = mag("mouthUpperUp_L") + mag("mouthUpperUp_R")
    c = np.flatnonzero(mid & (up > 0.5 * up[mid].max()))
    out["upper_lip"] = int(c[np.argmin(V[c, 1])])  # the inner edge: the lowest of the upper lip's midline
    lo = mag("mouthLowerDown_L") + mag("mouthLowerDown_R")
    front = V[:, 2] > V[out["upper_lip"], 2] - 0.1 * size  # the lip, not the mouth's inside behind it
    c = np.flatnonzero(mid & front & (lo > 0.5 * lo[mid & front].max()))
    out["lower_lip"] = int(c[np.argmax(V[c, 1])])
    return np.array([out[p] for p in POINTS]), size


class Transfer:
    """``Transfer(ict_rest, ict_deltas, ict_names, char_rest, char_deltas, char_names)(W [F, 53]) -> [F, 53]``:
    the character's weights for fitted ICT weights ``W`` (columns in ``char_names`` order, the same 53 names),
    see the module docstring. ``ict_rest``: the person's neutral ICT face (identity applied)."""

    def __init__(self, ict_rest, ict_deltas, ict_names, char_rest, char_deltas, char_names, pull: float = PULL):
        pi, si = face_points(ict_rest, ict_deltas, list(ict_names))
        pc, sc = face_points(char_rest, char_deltas, list(char_names))
        order = [list(ict_names).index(n) for n in char_names]
        self.Ai = np.asarray(ict_deltas, np.float64)[order][:, pi] / si  # [53, 12, 3] per ICT weight
        self.Bc = np.asarray(char_deltas, np.float64)[:, pc] / sc  # [53, 12, 3] per character weight
        self.free = np.array([n in TRANSFERRED for n in char_names])
        self.used = np.array([p in MATCHED for p in POINTS])
        B = self.Bc[self.free][:, self.used].reshape(int(self.free.sum()), -1)
        self.pull = pull
        self.solve = np.linalg.inv(B @ B.T + pull * np.eye(len(B)))
        self.B = B
        r = np.asarray(char_rest, np.float64)
        self.rest_gap = {
            s: float(r[pc[POINTS.index(f"upper_lid_{s}")], 1] - r[pc[POINTS.index(f"lower_lid_{s}")], 1]) / sc
            for s in ("L", "R")
        }

    def targets(self, W: np.ndarray) -> np.ndarray:
        """The ICT face's point displacements ``[F, 12, 3]`` (face sizes) for weights ``W [F, 53]``."""
        return np.einsum("fe,epc->fpc", np.asarray(W, np.float64), self.Ai)

    def character(self, Wc: np.ndarray) -> np.ndarray:
        """The character's point displacements ``[F, 12, 3]`` for its weights ``Wc [F, 53]``."""
        return np.einsum("fe,epc->fpc", np.asarray(Wc, np.float64), self.Bc)

    def __call__(self, W: np.ndarray) -> np.ndarray:
        W = np.asarray(W, np.float64)
        fixed = W.copy()
        fixed[:, self.free] = 0.0
        # what the free channels must add to the fixed ones' displacement of the matched points
        T = (self.targets(W) - self.character(fixed))[:, self.used].reshape(len(W), -1)
        out = W.copy()
        out[:, self.free] = (T @ self.B.T + self.pull * W[:, self.free]) @ self.solve.T
        return np.clip(out, 0.0, 1.0)

    def _gap_change(self, side: str) -> np.ndarray:
        """Each character weight's change ``[53]`` of the ``side`` eye's lid gap (face sizes)."""
        up, lo = POINTS.index(f"upper_lid_{side}"), POINTS.index(f"lower_lid_{side}")
        return self.Bc[:, up, 1] - self.Bc[:, lo, 1]

    def lid_gaps(self, Wc: np.ndarray) -> np.ndarray:
        """The character's lid gaps ``[F, 2]`` (left, right; face sizes, upper lid over lower) for its weights
        ``Wc [F, 53]``; zero weights give its rest face's gaps."""
        Wc = np.asarray(Wc, np.float64)
        return np.stack([self.rest_gap[s] + Wc @ self._gap_change(s) for s in ("L", "R")], -1)

    def lower_lids(self, Wc: np.ndarray) -> np.ndarray:
        """The rise ``[F, 2]`` (left, right; face sizes) of the character's lower lids for weights ``Wc [F, 53]``."""
        return self.character(Wc)[:, [POINTS.index("lower_lid_L"), POINTS.index("lower_lid_R")], 1]

    def follow_lower_lids(self, Wc: np.ndarray, rise: np.ndarray, names, level=None, opening=None) -> np.ndarray:
        """The character's weights ``Wc [F, 53]`` (named ``names``) with each lower lid moving as the person's
        does: ``rise [F, 2]`` (left, right; :func:`lower_lid_rise`, a share of the open eye's gap from the clip's
        median; NaN where not seen, left as it is) lifts the side's lower lid that share of the character's rest
        gap above ``level [2]`` (its rise at the clip's median, :meth:`lower_lids`, so the clip-long squint stays
        the fit's; default 0), by eyeSquint alone, clipped to [0, 1]; the other channels kept. With the eyes'
        ``opening [F, 2]`` (:func:`eye_opening`) the rise is followed by :func:`lower_lid_share` of it: not in a
        blink. :meth:`follow_lids` then sets the gap: what the lower lid does not close, the upper lid does."""
        out = np.array(Wc, np.float64)
        level = np.zeros(2) if level is None else np.asarray(level, np.float64)
        rise = np.asarray(rise, np.float64)
        if opening is not None:
            rise = rise * np.where(np.isfinite(opening), lower_lid_share(np.nan_to_num(opening, nan=1.0)), 1.0)
        ix = {n: i for i, n in enumerate(names)}
        for k, s in enumerate(("L", "R")):
            q, lo = ix[f"eyeSquint_{s}"], POINTS.index(f"lower_lid_{s}")
            if self.Bc[q, lo, 1] <= 0:
                continue
            others = out.copy()
            others[:, q] = 0.0
            goal = level[k] + np.nan_to_num(rise[:, k]) * self.rest_gap[s]
            x = (goal - self.character(others)[:, lo, 1]) / self.Bc[q, lo, 1]
            out[:, q] = np.where(np.isfinite(rise[:, k]), np.clip(x, 0.0, 1.0), out[:, q])
        return out

    def brow_rise(self, Wc: np.ndarray) -> np.ndarray:
        """The rise ``[F, 2, 2]`` (face sizes) of the character's brow points (left, right; inner, outer) for its
        weights ``Wc [F, 53]``."""
        pts = [[POINTS.index(f"brow_{p}_{s}") for p in ("in", "out")] for s in ("L", "R")]
        return self.character(Wc)[:, :, 1][:, pts]

    @staticmethod
    def _brow_goal(raised, k: int, level, shown: float) -> tuple[list[int], np.ndarray]:
        """Side ``k``'s brow points (inner, outer) and the rise ``[F, 2]`` they must reach (:meth:`follow_brows`)."""
        s = ("L", "R")[k]
        pts = [POINTS.index(f"brow_in_{s}"), POINTS.index(f"brow_out_{s}")]
        return pts, np.nan_to_num(raised[:, k], nan=0.0)[:, None] / shown + level[k]

    def _reach_brows(self, Wc, raised, names, level, pull: float, shown: float) -> np.ndarray:
        """``Wc`` with each side's browInnerUp and browOuterUp solved for the rise ``raised / shown + level`` of
        its brow points (:meth:`follow_brows`), the other channels kept."""
        out = np.array(Wc, np.float64)
        ix = {n: i for i, n in enumerate(names)}
        for k, s in enumerate(("L", "R")):
            ch = [ix[f"browInnerUp_{s}"], ix[f"browOuterUp_{s}"]]
            pts, rise = self._brow_goal(raised, k, level, shown)
            B = self.Bc[ch][:, pts, 1]  # [2 channels, 2 points]: each channel's rise of the points
            others = out.copy()
            others[:, ch] = 0.0
            goal = rise - self.character(others)[:, pts, 1]
            x = (goal @ B.T + pull * out[:, ch]) @ np.linalg.inv(B @ B.T + pull * np.eye(len(ch))).T
            seen = np.isfinite(raised[:, k])
            out[:, ch] = np.where(seen[:, None], np.clip(x, 0.0, 1.0), out[:, ch])
        return out

    def follow_brows(
        self, Wc, raised, names, level=None, pull: float = BROW_PULL, shown: float = BROW_SHOWN
    ) -> np.ndarray:
        """The character's weights ``Wc [F, 53]`` (named ``names``) with each brow moving as the person's does:
        ``raised [F, 2]`` (left, right; :func:`brow_raise`, face heights from the clip's median; NaN where not
        seen, left as it is) is the height the side's brows must show in the close-up: their inner and outer
        points rise ``raised / shown`` face sizes (``shown``: :data:`BROW_SHOWN`, the character's calibration)
        above ``level [2, 2]`` (their rise at the clip's median, :meth:`brow_rise`, so the clip-long level stays
        the fit's, measured from its rest face; default 0), reached by that side's browInnerUp and browOuterUp
        (least squares with ``pull`` towards their weights in ``Wc``).

        Where the brows must come lower than those channels at zero leave them (a frown), browDown takes them
        there (least squares on the two points); the side's browDown over the seen frames (the transferred one
        plus that) is then scaled down by the one factor that keeps its mean the one in ``Wc``
        (:func:`keep_mean`): the fit's mean, so a speaker's face over the clip reads as before (a neutral
        speaker's browDown at rest stays where the rest face put it) and only its timing follows the video; over
        a single frame nothing changes. The raise channels are then solved again on it; the other channels are
        kept."""
        level = np.zeros((2, 2)) if level is None else np.asarray(level, np.float64)
        raised = np.asarray(raised, np.float64)
        out = self._reach_brows(Wc, raised, names, level, pull, shown)
        ix = {n: i for i, n in enumerate(names)}
        frowned = False
        for k, s in enumerate(("L", "R")):
            seen = np.isfinite(raised[:, k])
            if seen.sum() < 2:  # one frame (a live stream): browDown stays the fit's
                continue
            d = ix[f"browDown_{s}"]
            pts, rise = self._brow_goal(raised, k, level, shown)
            above = np.maximum(self.character(out)[:, pts, 1] - rise, 0.0)  # how far the points stand too high
            b = -self.Bc[d][pts, 1]  # browDown's lowering of the two points
            extra = np.maximum(above @ b / (b @ b), 0.0)
            if extra[seen].any():
                out[seen, d] = keep_mean(out[seen, d] + extra[seen], float(out[seen, d].mean()))
                frowned = True
        return self._reach_brows(out, raised, names, level, pull, shown) if frowned else out

    def _lip_change(self) -> np.ndarray:
        """Each character weight's change ``[53]`` of its lip gap (face sizes, upper lip over lower)."""
        up, lo = POINTS.index("upper_lip"), POINTS.index("lower_lip")
        return self.Bc[:, up, 1] - self.Bc[:, lo, 1]

    def lip_gaps(self, Wc: np.ndarray) -> np.ndarray:
        """The character's lip gap ``[F]`` (face sizes) above its rest face's, for its weights ``Wc [F, 53]``."""
        return np.asarray(Wc, np.float64) @ self._lip_change()

    def follow_lips(self, Wc: np.ndarray, opening: np.ndarray, names, shown=LIP_SHOWN) -> np.ndarray:
        """The character's weights ``Wc [F, 53]`` (named ``names``) with its lips parted as the person's are:
        ``opening [F]`` is the mouth's opening (:func:`lip_opening`; NaN where not seen, left as it is), which
        the character's close-up shows at the lip gap ``(opening - offset) / slope`` (``shown``:
        :data:`LIP_SHOWN`); under the offset (less than the character can show) its lips shut
        (:data:`LIP_SHUT`). The gap is reached by jawOpen (opening) or mouthClose (closing), each first undoing
        the other, the other channels kept."""
        out = np.array(Wc, np.float64)
        ix = {n: i for i, n in enumerate(names)}
        j, c = ix["jawOpen"], ix["mouthClose"]
        dg = self._lip_change()
        if not (dg[j] > 0 > dg[c]):
            return out
        opening = np.asarray(opening, np.float64)
        seen = np.isfinite(opening)
        offset, slope = shown
        x = np.nan_to_num(opening, nan=0.0)
        need = np.where(x < offset, LIP_SHUT, (x - offset) / slope) - out @ dg
        undo_close = np.minimum(np.maximum(need, 0.0) / -dg[c], out[:, c])  # opening: first less mouthClose
        undo_jaw = np.minimum(np.maximum(-need, 0.0) / dg[j], out[:, j])  # closing: first less jawOpen
        rest = need + undo_close * dg[c] + undo_jaw * dg[j]  # what is left for the other channel
        jaw = out[:, j] - undo_jaw + np.maximum(rest, 0.0) / dg[j]
        close = out[:, c] - undo_close + np.maximum(-rest, 0.0) / -dg[c]
        out[:, j] = np.where(seen, np.clip(jaw, 0.0, 1.0), out[:, j])
        out[:, c] = np.where(seen, np.clip(close, 0.0, 1.0), out[:, c])
        return out

    def follow_lids(self, Wc: np.ndarray, opening: np.ndarray, names, shown=SHUT_READ) -> np.ndarray:
        """The character's weights ``Wc [F, 53]`` (named ``names``) with each eye's lids set so that its close-up
        shows the person's opening: ``opening [F, 2]`` (left, right) is each eye's opening over its open eye
        (:func:`eye_opening`: 1 open, 0 shut; NaN where not seen, left as it is). The gap of the character's
        lids is its rest gap times :func:`lid_closure` of that (``shown``: the shut reading, :data:`SHUT_READ`; a
        table such as :data:`EYE_SHOWN`: :func:`lid_gap` at the frame's eyeSquint weight, so that the close-up
        reads as the video; ``None``: the opening itself), by eyeBlink (closing) or eyeWide (opening wider), the
        other channels kept."""
        out = np.array(Wc, np.float64)
        ix = {n: i for i, n in enumerate(names)}
        opening = np.asarray(opening, np.float64)
        for k, s in enumerate(("L", "R")):
            if shown is None:
                gaps = np.clip(opening[:, k], 0.0, 1.5)
            elif np.isscalar(shown):
                gaps = lid_closure(opening[:, k], float(shown))
            else:
                gaps = lid_gap(opening[:, k], out[:, ix[f"eyeSquint_{s}"]], shown)
            dy = self._gap_change(s)
            b, w = ix[f"eyeBlink_{s}"], ix[f"eyeWide_{s}"]
            seen = np.isfinite(opening[:, k])
            others = out.copy()
            others[:, [b, w]] = 0.0
            need = self.rest_gap[s] * np.nan_to_num(gaps, nan=1.0) - (
                self.rest_gap[s] + others @ dy
            )  # what eyeBlink / eyeWide must add to the gap
            blink = np.clip(need / dy[b], 0.0, 1.0) if dy[b] < 0 else np.zeros(len(out))
            wide = np.clip(need / dy[w], 0.0, 1.0) if dy[w] > 0 else np.zeros(len(out))
            out[:, b] = np.where(seen, np.where(need < 0, blink, 0.0), out[:, b])
            out[:, w] = np.where(seen, np.where(need > 0, wide, 0.0), out[:, w])
        return out
