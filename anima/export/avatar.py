"""The animated character: anima's default person (``anima.facemodel.character``: a full body with the 53
expressions on its own face) shaped like the person, moved by the sequence on the rig (``anima.core.rig``),
in one glTF file (``avatar.glb``), the speech beside it (``speech.wav``), and a preview video
(``avatar.mp4``).

* **Shape**: the character's build (``--body``: neutral, female or male, :data:`anima.facemodel.character.BUILDS`,
  recorded in the sequence's ``meta["body"]``; default neutral) is its form; the captured bone lengths (shoulder
  width, upper arm, forearm, hip width) then adjust it (:func:`anima.facemodel.character.fit_shape`); the fit's
  error per measure is reported. A sequence without a body gets the build as it is.
* **Motion**: the tracked or generated body retargeted onto the character's own proportions; the head turns
  with the face fit's rotation where the sequence has a face; the legs stand with a weight shift unless the
  clip tracked them; a sequence without a body (a face-only capture, text2face) stands at ease (breathing,
  arms hanging), said in ``info.json``.
* **Face**: the character's 53 morph weights are chosen per frame so that its lids, brows, mouth corners and
  lips move as the fitted ICT face's do (:mod:`anima.facemodel.transfer`), not copied by name; a captured
  clip's brows, lids and lips then move as its landmarks show.
  The file carries them as ARKit's 52 morph targets (``eyeBlinkLeft`` ... ``tongueOut``:
  :func:`anima.facemodel.character.arkit_morphs`, :func:`~anima.facemodel.character.to_arkit`).
* **One timeline, one unit**: the animation is sampled at the sequence's frame rate, in metres; the scene's
  ``extras`` carry the frame rate and the frame range (``tools/blender_import.py`` sets Blender's scene from
  them: Blender's own importer keeps them as the scene's custom properties but opens at 24 fps, 250 frames).
* ``speech.wav``: the speech the motion goes with, 16-bit PCM; its offset from frame 0 (0 s) is in
  ``asset.extras.anima`` and ``info.json``.
"""

from __future__ import annotations

import subprocess
import threading
from collections import deque
from functools import lru_cache
from pathlib import Path

import numpy as np

from anima.core import rig, world
from anima.core.character import Motion
from anima.core.contact import TorsoSurface
from anima.core.contract import EXPR_NAMES, JOINT_NAMES, LEG_JOINTS
from anima.core.ground import Picture
from anima.core.occlusion import hand_over_face
from anima.core.rotations import matrix_to_quat, rotvec_to_matrix
from anima.errors import InputError
from anima.export.vrm import character_mesh, character_vrm
from anima.facemodel.character import (
    BUILDS,
    DEFAULT_BUILD,
    arkit_morphs,
    build_coeffs,
    eye_vertices,
    fit_shape,
    load_character,
    skin,
    to_arkit,
    tracked_measures,
    vertex_colors,
)
from anima.facemodel.ict import load_face_model
from anima.facemodel.neutral import faded, from_rest, is_captured, presented, rest_face
from anima.facemodel.transfer import (
    OPEN_PERCENTILE,
    Transfer,
    brow_heights,
    brow_raise,
    eye_opening,
    eye_ratios,
    lip_opening,
    lower_lid_depths,
    lower_lid_rise,
)
from anima.io.atomic import atomic_path
from anima.io.gltf import write_character_glb
from anima.io.sequence import TrackedSequence
from anima.io.video import FFMPEG
from anima.render.avatar import render_character_video
from anima.render.lod import cluster_mean

UNIT = "metre"


def body_of(seq: TrackedSequence) -> np.ndarray | None:
    """The sequence's body joints when some joint was tracked, else None."""
    if seq.body_joints is None or not np.isfinite(seq.body_joints).all(-1).any():
        return None
    return seq.body_joints


def legs_of(seq: TrackedSequence) -> dict | None:
    """The tracked legs as the rig takes them (``{"left_hip": [F, 3], "left_knee": ..., ...}``,
    pelvis-relative), or None when the sequence has no leg track or never saw a knee."""
    if seq.leg_joints is None or seq.body_joints is None or not np.isfinite(seq.leg_joints).all(-1).any():
        return None
    out = {n: seq.leg_joints[:, k].astype(np.float64) for k, n in enumerate(LEG_JOINTS)}
    for side in ("left", "right"):
        out[f"{side}_hip"] = seq.body_joints[:, JOINT_NAMES.index(f"{side}_hip")].astype(np.float64)
    return out


def torso_surface(V: np.ndarray, rest: np.ndarray, ch) -> TorsoSurface:
    """The front of the shaped character's torso (vertices mostly skinned to the hips and spine), for hands
    that rest on it (:mod:`anima.core.contact`)."""
    torso_joints = [rig.IX[n] for n in ("Hips", "Spine", "Spine1", "Spine2")]
    main = ch.skin_joints[np.arange(len(V)), np.argmax(ch.skin_weights, 1)]
    return TorsoSurface.from_mesh(V, rest[rig.IX["Spine2"]], np.isin(main, torso_joints))


def picture_of(seq: TrackedSequence) -> Picture | None:
    """The sequence's 2D evidence for the world (:class:`anima.core.ground.Picture`), or None (no body in the
    picture: a generated sequence, a face-only capture)."""
    if seq.body_image is None or body_of(seq) is None or not np.isfinite(seq.body_image).any():
        return None
    step = seq.camera_step.astype(np.float64) if seq.camera_step is not None else np.zeros((seq.n_frames, 3))
    return Picture(seq.width, seq.height, seq.body_image.astype(np.float64), seq.body_joints.astype(np.float64),
                   None if seq.leg_image is None else seq.leg_image.astype(np.float64),
                   None if seq.leg_joints is None else seq.leg_joints.astype(np.float64),
                   seq.leg_conf, np.cumsum(step[:, :2], 0))  # fmt: skip


def head_rotations(seq: TrackedSequence) -> np.ndarray | None:
    """The face fit's head rotations ``[F, 3, 3]`` (NaN where no face was tracked), or None when the sequence
    has no head rotation of its own (no face, or a generated face that never turns: the body's head joints
    then turn the head)."""
    if not seq.tracked.any() or not np.any(np.abs(seq.rotation[seq.tracked]) > 1e-6):
        return None
    R = rotvec_to_matrix(seq.rotation.astype(np.float64))
    R[~seq.tracked] = np.nan
    return R


def build_of(seq: TrackedSequence) -> str:
    """The character's build for ``seq`` (:data:`anima.facemodel.character.BUILDS`): ``seq.meta["body"]`` (``--body``,
    recorded with the sequence), else :data:`~anima.facemodel.character.DEFAULT_BUILD`."""
    build = seq.meta.get("body") or DEFAULT_BUILD
    if build not in BUILDS:
        raise InputError(f"this sequence asks for the body {build!r}; anima's are {', '.join(BUILDS)}")
    return str(build)


def character_motion(seq: TrackedSequence, seed: int = 0) -> dict:
    """The sequence on the character (see the module docstring): ``coeffs``, ``vertices`` (the shaped rest
    mesh), ``rest`` (its rest joints), the rig motion (``root``, ``local``, ``global``, ``positions``) and a
    ``report`` (build, shape fit, legs, body)."""
    ch = load_character()
    body = body_of(seq)
    build = build_of(seq)
    if body is not None:
        coeffs, shape = fit_shape(tracked_measures(body), ch, build=build)
    else:
        coeffs = build_coeffs(build)
        shape = {"measures": {}, "height_m": round(float(ch.shaped(coeffs)[0][:, 1].max()), 3)}
    V, rest = ch.shaped(coeffs)
    legs = legs_of(seq) if body is not None else None
    posture = posture_of(seq, legs) if body is not None else None
    if posture and posture[0] == "seated":
        legs = rig.seated_legs(body, rest)
    mo = world.solve(body, rest, seq.fps, head_rotations(seq), picture_of(seq), legs, seed=seed, frames=seq.n_frames,
                     surface=torso_surface(V, rest, ch), seated=bool(posture and posture[0] == "seated"))  # fmt: skip
    idle = "idle: no body in this sequence, the default body stands at ease"
    report = {
        "body": "tracked" if body is not None else idle,
        "build": build,
        "height_m": shape["height_m"],
        "shape_fit": shape["measures"],
        **mo["report"],
    }
    if posture:
        report["posture"] = f"{posture[0]} ({posture[1]})"
        if posture[0] == "seated":
            report["legs"] = "seated: the picture shows no legs; thighs level, shins down, feet on the floor"
    return {"coeffs": coeffs, "vertices": V, "rest": rest, **mo, "report": report}


POSTURES = ("auto", "seated", "standing")
BOTTOM_EDGE = 0.92
"""``--posture auto``: a body whose hips the picture shows at or under this share of its height (rounded to a
percent, as info.json says it), and whose legs it never shows, is a speaker seen from the waist up at a desk or
in a chair: taken as seated. With legs in the picture, their tracked pose decides."""
HIPS_SEEN = 0.25
"""``--posture auto``: the share of frames in which both hips must be seen (kept by the body's cleaning: Pose
visibility at least its ``min_conf``) for the picture to show where they are. Where they are not, the picture
is cut above them (a head-and-shoulders or chest-up framing): MediaPipe still places them, out of the picture,
but that is its guess, and such a framing shows no seat, so the character stands."""


def hips_in_picture(seq: TrackedSequence) -> tuple[float, float | None]:
    """Where ``seq``'s picture shows the hips: (the share of frames in which both hips are seen, the median of
    their row over those frames as a share of the picture's height, or None when they are never seen)."""
    hips = [JOINT_NAMES.index("left_hip"), JOINT_NAMES.index("right_hip")]
    if seq.body_image is None or not len(seq.body_image):
        return 0.0, None
    if seq.body_conf is not None:
        min_conf = float(seq.meta.get("skeleton", {}).get("cleaning", {}).get("min_conf", 0.5))
        seen = (seq.body_conf[:, hips] >= min_conf).all(1)
    else:  # no confidence stored: the hips the cleaning kept
        seen = np.isfinite(seq.body_joints[:, hips]).all((1, 2))
    seen &= np.isfinite(seq.body_image[:, hips]).all((1, 2))
    if not seen.any():
        return 0.0, None
    rows = seq.body_image[seen][:, hips, 1].mean(1)
    return float(seen.mean()), float(np.median(rows) / seq.height)


def _thighs_seen(legs: dict) -> np.ndarray:
    """The frames ``[F]`` in which both thighs are seen (hip and knee): those the rig follows the legs in
    (:func:`anima.core.rig.tracked_legs`; a lone ankle or toe, or one knee, is not a leg it can pose)."""
    parts = [legs.get(f"{s}_{j}") for s in ("left", "right") for j in ("hip", "knee")]
    if any(x is None for x in parts):
        return np.zeros(0, bool)
    return np.logical_and.reduce([np.isfinite(x).all(-1) for x in parts])


def posture_of(seq: TrackedSequence, legs: dict | None) -> tuple[str, str] | None:
    """How the legs of ``seq``'s body stand: ``(posture, why)``, or None for a sequence without a picture
    (generated motion). ``seq.meta["posture"]`` (``anima capture --posture``) is ``auto`` (default), ``seated``
    or ``standing``. Auto stands the character unless the picture shows a seat: legs in the picture (both
    thighs seen) are followed as tracked (``tracked``: a seated person whose knees are seen sits as they show);
    without them, hips seen at the picture's bottom edge (:data:`BOTTOM_EDGE`) are a speaker at a desk or in a
    chair (``seated``); hips seen higher up, or not seen at all (a chest-up framing, :data:`HIPS_SEEN`), stand
    it (``standing``)."""
    asked = str(seq.meta.get("posture", "auto"))
    if asked in ("seated", "standing"):
        return asked, "--posture " + asked
    if seq.body_image is None:  # generated motion (gesture, text2face): no picture to read a chair from
        return None
    if legs is not None and _thighs_seen(legs).any():
        return "tracked", "auto: the legs are in the picture and followed as tracked"
    share, row = hips_in_picture(seq)
    row = None if row is None else round(row, 2)  # as info.json says it
    if row is None or share < HIPS_SEEN:
        seen = "never seen" if row is None else f"seen in only {share:.0%} of the frames"
        return "standing", f"auto: the hips {seen} (the picture is cut above them): nothing shows a seat"
    if row >= BOTTOM_EDGE:
        return "seated", f"auto: the hips seen at the picture's bottom edge ({row:.0%} of its height), no legs seen"
    return "standing", f"auto: the hips seen above the picture's bottom edge ({row:.0%} of its height), no legs seen"


class OnCharacter:
    """A sequence on the character, shared by the writers of one output set (``avatar.glb``, ``body.bvh`` and
    ``avatar.mp4``, written on their own threads by :func:`anima.export.motion.write_motion_outputs`): its motion
    (:func:`character_motion`) and its face (:func:`character_face`) each computed once, on first use (a
    second thread that asks meanwhile waits for it), and never changed by a writer."""

    def __init__(self, seq: TrackedSequence):
        self.seq = seq
        self._locks = {"motion": threading.Lock(), "face": threading.Lock()}
        self._made: dict = {}

    def _once(self, key: str, make):
        with self._locks[key]:
            if key not in self._made:
                self._made[key] = make(self.seq)
            return self._made[key]

    def motion(self) -> dict:
        return self._once("motion", character_motion)

    def face(self) -> np.ndarray:
        return self._once("face", character_face)


def write_avatar(
    seq: TrackedSequence, path: str | Path, speech: str | None = None, preset: str = "anima", on=None
) -> dict:
    """``avatar.glb`` for ``seq`` (see the module docstring), joints named by ``preset`` (anima, mixamo, vrm,
    unreal); returns what it holds (for ``info.json``). ``on``: the sequence's :class:`OnCharacter` when other
    writers share it."""
    ch = load_character()
    on = on or OnCharacter(seq)
    m = on.motion()
    F = seq.n_frames
    weights = on.face()
    extras = {
        "anima": {
            "speech": "speech.wav" if speech else None,
            "speech_offset_s": 0.0,
            "fps": seq.fps,
            "frames": F,
            "unit": UNIT,
            "rig": {"preset": preset, "joints": rig.N_RIG, "conventions": "docs/rig.md"},
            "character": ch.provenance.get("licences", {}),
            "build": m["report"]["build"],
        }
    }
    # frames as Blender numbers them after import (the first sample at frame 0)
    scene_extras = {
        "anima_fps": float(seq.fps),
        "anima_frame_start": 0,
        "anima_frame_end": int(F) - 1,
        "anima_unit": UNIT,
    }
    character = character_mesh(rig.preset_names(preset), m["rest"], m["vertices"], list(zip(*arkit_morphs())))
    # the file's morphs are ARKit's 52 (anima.io.arkit: the one table)
    motion = Motion(m["root"], matrix_to_quat(m["local"]), seq.fps, to_arkit(weights), ~rig.LEAVES)
    write_character_glb(path, character, motion, extras, scene_extras, doc_extensions=_vrm_extension(path))
    return {"kind": "character", "joints": rig.N_RIG, "preset": preset, "unit": UNIT, **extras["anima"], **m["report"]}


def _vrm_extension(path: str | Path) -> dict | None:
    """``VRMC_vrm`` (humanoid map, expression presets) when ``path`` is a ``.vrm``; else None."""
    if Path(path).suffix.lower() != ".vrm":
        return None
    return {"VRMC_vrm": character_vrm(rig.N_RIG, {n: j for j, n in enumerate(rig.NAMES)})}


@lru_cache(maxsize=1)
def face_transfer() -> Transfer:
    """The ICT face to the character's face (:mod:`anima.facemodel.transfer`), built once."""
    ict, ch = load_face_model(), load_character()
    nb = ch.n_body  # the face's own points: on its skin, not on the teeth or the lashes that follow it
    return Transfer(ict.neutral, ict.expr_deltas, ict.expr_names, ch.vertices[:nb].astype(np.float64),
                    ch.morph_dense()[:, :nb], EXPR_NAMES)  # fmt: skip


MOUTH = [k for k, n in enumerate(EXPR_NAMES) if n.startswith(("jaw", "mouth", "cheekPuff"))]
"""The mouth's channels: under a hand (:func:`anima.core.occlusion.hand_over_face`) they have no evidence."""


def character_face(seq: TrackedSequence, lids: bool = True, lips: bool = True, brows: bool = True) -> np.ndarray:
    """The character's 53 morph weights ``[F, 53]`` for the sequence's face (easing to the rest face where it was
    lost, :func:`anima.facemodel.neutral.faded`, and the mouth alone where a hand covers it): chosen so that its
    lids, brows, mouth corners and lips move as the fitted face's do (:func:`face_transfer`), not copied by
    name; a captured clip's brows, lids (the lower lids first, then the gap) and lips then move as its landmarks
    show (``brows=False``, ``lids=False``, ``lips=False``: by the transfer alone, the read-back benchmark's
    comparisons)."""
    W = np.zeros((seq.n_frames, len(EXPR_NAMES)), np.float32)
    if seq.tracked.any():
        expression = presented(seq)[0]  # a captured clip's face measured from its rest face
        idx = [seq.expr_names.index(n) if n in seq.expr_names else -1 for n in EXPR_NAMES]
        for k, i in enumerate(idx):
            if i >= 0:
                W[:, k] = np.where(seq.tracked, expression[:, i], 0.0)
        tr = face_transfer()
        W = tr(np.clip(W, 0.0, 1.0))
        seen = is_captured(seq.meta) and seq.landmarks is not None and len(seq.landmarks) > 0
        if seen and brows:  # as the video shows them, the brows first (they move the lids a little)
            level = np.median(tr.brow_rise(W)[seq.tracked], axis=0)  # the fit's clip-long brows, from its rest
            W = tr.follow_brows(W, brow_raise(seq.landmarks, seq.tracked, seq.width, seq.height), EXPR_NAMES, level)
        if seen and lids:  # the lower lids first (a squint), then the gap as the video shows it
            opening = eye_opening(seq.landmarks, seq.tracked, seq.width, seq.height)
            level = np.median(tr.lower_lids(W)[seq.tracked], axis=0)  # the fit's clip-long squint, from its rest
            rise = lower_lid_rise(seq.landmarks, seq.tracked, seq.width, seq.height)
            W = tr.follow_lids(tr.follow_lower_lids(W, rise, EXPR_NAMES, level, opening), opening, EXPR_NAMES)
        if seen and lips:
            opening = np.where(seq.tracked, lip_opening(seq.landmarks, seq.width, seq.height), np.nan)
            W = tr.follow_lips(W, opening, EXPR_NAMES)
        W = faded(W.astype(np.float32), seq.tracked, seq.fps)
        covered = hand_over_face(seq)
        if covered.any():  # no evidence under the hand: the mouth eases to its rest and back, never frozen
            W[:, MOUTH] = faded(W[:, MOUTH], seq.tracked & ~covered, seq.fps)
    return np.clip(W, 0.0, 1.0)


def _median_seen(values) -> np.ndarray | None:
    """The median ``[2]`` of a window's per-frame pairs ``values`` over the frames where both were seen; None under
    ten such frames."""
    X = np.stack(values)
    ok = np.isfinite(X).all(-1)
    return np.median(X[ok], axis=0) if ok.sum() >= 10 else None


class LiveCharacterFace:
    """:func:`character_face` for a stream (``anima live``'s page), one frame at a time: the fitted weights
    measured from a running rest face (:func:`anima.facemodel.neutral.rest_face` over the faces of the last
    :attr:`WINDOW_S` seconds, once it holds :data:`~anima.facemodel.neutral.MIN_SECONDS` of them), transferred by
    geometry, the lids set from the frame's landmarks over a running open eye (the same percentile as a
    clip's, :data:`anima.facemodel.transfer.OPEN_PERCENTILE`; the lower lids from their depth over a running
    median, around the transferred lower lids' running median), the brows from its brows' height over a running
    median (around the transferred brows' running median; a frown's browDown stays the fit's: a clip's takes its
    timing from the landmarks over the whole clip, :meth:`~anima.facemodel.transfer.Transfer.follow_brows`) and
    the lips from its landmarks' lip opening.
    The rest is re-estimated every :attr:`EVERY` frames. Called for seen faces only."""

    WINDOW_S = 30.0  # contract: not (a span of seconds)
    EVERY = 15

    def __init__(self):
        self.transfer = face_transfer()
        self.t: deque[float] = deque()
        self.expr: deque[np.ndarray] = deque()
        self.eyes: deque[np.ndarray] = deque()
        self.brows: deque[np.ndarray] = deque()
        self.lowers: deque[np.ndarray] = deque()
        self.rest: dict[str, float] = {}
        self.open_eye = None
        self.brow_rest = None
        self.brow_level = None
        self.lower_rest = None
        self.lower_level = None
        self.n = 0

    def __call__(
        self, expression: np.ndarray, landmarks: np.ndarray | None, size: tuple[int, int], t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(the character's weights [53], the fit measured from the rest [53])`` for one seen face:
        ``expression [53]`` (the fit, EXPR_NAMES order), its Face Mesh ``landmarks [478, 2+]`` (normalised;
        None: lids by the transfer alone), the image ``size`` (H, W) and the frame's time ``t`` (seconds). The
        second is what ARKit outputs send (as a capture's ``arkit.csv`` is measured from its rest)."""
        H, W = size
        self.t.append(float(t))
        self.expr.append(np.asarray(expression, np.float32))
        ratio = eye_ratios(landmarks[None], W, H)[0] if landmarks is not None else np.full(2, np.nan)
        brows = brow_heights(landmarks[None], W, H)[0] if landmarks is not None else np.full(2, np.nan)
        lower = lower_lid_depths(landmarks[None], W, H)[0] if landmarks is not None else np.full(2, np.nan)
        self.eyes.append(ratio)
        self.brows.append(brows)
        self.lowers.append(lower)
        while self.t[-1] - self.t[0] > self.WINDOW_S:
            for q in (self.t, self.expr, self.eyes, self.brows, self.lowers):
                q.popleft()
        if self.n % self.EVERY == 0:
            span = self.t[-1] - self.t[0]
            fps = (len(self.t) - 1) / span if span > 0 else 0.0
            X = np.stack(self.expr)
            self.rest = rest_face(X, list(EXPR_NAMES), np.ones(len(X), bool), fps) if fps > 0 else {}
            E = np.stack(self.eyes)
            ok = np.isfinite(E).all(-1)
            self.open_eye = np.percentile(E[ok], OPEN_PERCENTILE, axis=0) if ok.sum() >= 10 else None
            self.brow_rest, self.lower_rest = _median_seen(self.brows), _median_seen(self.lowers)
            shown = self.transfer(np.clip(from_rest(X, list(EXPR_NAMES), self.rest), 0.0, 1.0))  # as a clip's
            self.brow_level = np.median(self.transfer.brow_rise(shown), axis=0)
            self.lower_level = np.median(self.transfer.lower_lids(shown), axis=0)
        self.n += 1
        presented = np.clip(from_rest(np.asarray(expression)[None], list(EXPR_NAMES), self.rest), 0.0, 1.0)
        w = self.transfer(presented)
        if self.brow_rest is not None and np.isfinite(brows).all():
            w = self.transfer.follow_brows(w, (brows - self.brow_rest)[None], EXPR_NAMES, self.brow_level)
        if self.open_eye is not None and np.isfinite(ratio).all() and (self.open_eye > 0).all():
            opening = (ratio / self.open_eye)[None]
            if self.lower_rest is not None and np.isfinite(lower).all():
                rise = ((self.lower_rest - lower) / self.open_eye)[None]
                w = self.transfer.follow_lower_lids(w, rise, EXPR_NAMES, self.lower_level, opening)
            w = self.transfer.follow_lids(w, opening, EXPR_NAMES)
        if landmarks is not None:
            w = self.transfer.follow_lips(w, lip_opening(np.asarray(landmarks)[None], W, H), EXPR_NAMES)
        return np.clip(w[0], 0.0, 1.0).astype(np.float32), presented[0].astype(np.float32)


def write_speech(source: str, path: str | Path) -> Path:
    """The audio track of ``source`` as 16-bit PCM WAV (mono, 48 kHz), atomically."""
    with atomic_path(path) as tmp:
        r = subprocess.run(
            [
                FFMPEG,
                "-hide_banner",
                "-nostdin",
                "-v",
                "error",
                "-y",
                "-i",
                str(source),
                "-vn",
                "-ac",
                "1",
                "-ar",
                "48000",
                "-c:a",
                "pcm_s16le",
                str(tmp),
            ],
            capture_output=True,
            timeout=600,
        )
        if r.returncode != 0:
            raise InputError(
                f"cannot write the speech of {source} to WAV: "
                f"{r.stderr.decode(errors='replace').strip().splitlines()[-1:] or ['ffmpeg failed']}"
            )
    return Path(path)


BODY_VIEW_TRIANGLES = 8000
"""The triangles ``avatar.mp4``'s front and 3/4 views draw (of the character's 27,804): the figure is about 420
pixels tall there, several triangles a pixel at full detail; the face close-up keeps every triangle."""


def render_avatar_preview(
    seq: TrackedSequence, path: str | Path, audio: str | None = None, progress: bool = False, on=None
) -> Path:
    """``avatar.mp4``: the character, front and 3/4 views, with the speech (``on``: as :func:`write_avatar`)."""
    ch = load_character()
    on = on or OnCharacter(seq)
    m = on.motion()
    weights = on.face()

    D = ch.morph_dense().reshape(len(EXPR_NAMES), -1)  # [53, V * 3]: a chunk's expressions in one product

    def posed(f0: int, f1: int) -> np.ndarray:
        """Vertices ``[n, V, 3]`` of frames ``f0:f1``: the expressions on the rest mesh, then skinned."""
        if f1 <= f0:
            return np.zeros((0, len(ch.vertices), 3))
        V = m["vertices"] + (weights[f0:f1].astype(np.float32) @ D).reshape(f1 - f0, -1, 3)
        return skin(V, m["rest"], m["global"][f0:f1], m["positions"][f0:f1], ch)

    render_character_video(path, seq.fps, m["positions"], rig.HEAD, posed, ch.faces, audio=audio, progress=progress,
                           face=(*face_camera(m, ch), eye_vertices()), colors=vertex_colors(),
                           lod=cluster_mean(ch.vertices, ch.faces, BODY_VIEW_TRIANGLES))  # fmt: skip
    return Path(path)


FACE_CENTRE = np.array([0.0, 0.085, 0.02])
"""The face's centre in the head joint's frame (metres; the head joint sits where the neck meets the skull)."""


BUST = ("Head", "Neck", "HeadTop_End", "Spine2", "LeftShoulder", "RightShoulder")
"""What the close-up draws: the head, the neck and the bust under them (the upper chest and the shoulders), so the
square's bottom shows shoulders, not the neck's ragged cut (as the viewer's close-up does). Read back on the nine
development clips (``benchmarks/face_readback.py``, the calibrations as they were), d3's blinks came to the
video's 5 (7 with the head and neck alone) and the radio clip's brows to r 0.84 (0.79); docs/face_rig.md."""


def head_triangles(ch) -> np.ndarray:
    """The character's triangles whose vertices all follow the bones of :data:`BUST` (what a close-up draws)."""
    main = ch.skin_joints[np.arange(len(ch.vertices)), np.argmax(ch.skin_weights, 1)]
    head = np.isin(main, [rig.IX[b] for b in BUST])
    return ch.faces[head[ch.faces].all(1)]


def face_camera(m: dict, ch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The close-up's camera per frame, mounted on the head like a face-capture rig's helmet camera: the face's
    centre ``[F, 3]``, the head's rotation ``[F, 3, 3]`` (its columns the head's axes in the world: the view
    undoes it, so the face is seen from straight in front on every frame and only the expression moves; the
    body's views show where the head turns), and the triangles it draws (:func:`head_triangles`). Chosen on
    five development clips read back by a face tracker (``benchmarks/face_readback.py``): a camera that followed
    only the head's yaw let the character's nods and tilts move its brows against its lids, brow height r 0.52
    on Obama's clip; locked to the head, 0.77."""
    G, P = m["global"][:, rig.HEAD], m["positions"][:, rig.HEAD]
    centre = P + np.einsum("fij,j->fi", G, FACE_CENTRE)
    return centre, np.asarray(G, np.float64), head_triangles(ch)
