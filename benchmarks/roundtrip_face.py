"""The face's round trip with known answers: the ICT face model rendered with known expression weights (FACS
combinations held and released, blinks, speech), on several identities, head turns, two lights and two camera
distances, captured back with anima's face capture, and the weights a user gets compared with the truth.

    python benchmarks/roundtrip_face.py           # writes benchmarks/results/roundtrip_face.json (~10 min, 2 cores)
    python benchmarks/roundtrip_face.py --quick --out /tmp/roundtrip_face_quick.json   # 2 identities, 1 view (~1.5 min)
    python benchmarks/roundtrip_face.py --quick --views near still --videos /tmp/rtf   # keep the videos and truth

**Faces.** ICT-FaceKit light (:func:`anima.facemodel.ict.load_face_model`, the model anima fits): six identities
drawn from its identity PCA (100 coefficients ~N(0, 1) clipped to +-2, seed :data:`SEED`), each with its own skin
tone; identities 0-2 are **development** (whoever tunes the solver may look at them), 3-5 **test** (never used to
choose anything; reported apart). The whole head is drawn: skin, the mouth's inside, teeth, gums and tongue,
eyeballs (iris and pupil painted by their angle from the eye's front), lashes; the lips painted redder (the
face's vertices inside the outer lip contour of the model's 68 landmarks) and brows dark (a band along the
brow landmarks), colours on the vertices so they move with the expression. Two directional lights (a key and a
fill) and ambient, Lambert; rasterised at twice the pixels and averaged down (anti-aliased) to 512 x 512.

**Views.** ``near``: the camera 38 cm from the face (the face about half the picture's height), the key light
from the upper left; ``far``: 65 cm (about a third), the key from the upper right and another background
(distance and light change together: two views, not four). A pinhole of 0.9 x the width focal length
(about 58 degrees across). The head turns slowly about the neck all along (yaw up to 20 degrees, pitch up to 15,
roll up to 4: sines of 7.7, 5.3 and 9.1 s, phases drawn per identity and view). **Control** (``still``): the
near view with the head held facing the camera, the same weights: what the head's turning costs; reported apart
(``still_head_control``), never pooled into ``results``; ``by_view`` has each view alone.

**Weights** (ICT's channel names, both sides of a bilateral AU set), one clip per identity and view at 30 fps:
1 s at rest, then each FACS combination of :data:`COMBOS` ramped up over 1 s (smoothstep), held 1 s, released
over 1 s, then 0.5 s at rest; blinks (AU45: four blinks in 3 s, each closing over 3 frames, shut 2, opening over
4); then speech (jawOpen, mouthFunnel, mouthPucker, mouthLowerDown, mouthUpperUp, mouthPress, mouthStretch and
mouthRollLower moving like talk: smoothed random curves, syllables 3-5 a second; no smile), then 1 s at rest.
Each clip is an H.264 video (:class:`anima.io.video.VideoWriter`).

**Capture.** :func:`anima.capture.pipeline.capture_face` (``anima capture --face-only``, the shipped defaults), then
the weights a user gets: :func:`anima.export.avatar.character_face` (the clip's rest face taken out, the lids, lips
and brows set from the landmarks: what ``arkit.csv``, Live Link, glTF and the character carry; ``arkit.csv`` also
averages browInnerUp_L/R and cheekPuff_L/R into one ARKit column and clips to [0, 1], as here), and the fit before
that (``fit``) beside it.

**Metrics** (every frame of every clip unless said; ``frames`` and ``identities`` say what stands behind a
number; intervals are over identities: each identity's number with its two views pooled, then their mean, min
and max): Face Mesh's detection rate (frames with a face); per channel the mean absolute error and Pearson's r
over frames (r where the truth moves); per combination, each of its channels' mean during the hold (the 1 s hold
less 3 frames at each end; the blinks: the shut frames) against the truth; the confusion table: during each
combination's hold, the mean of every channel that looks alike (:data:`CONFUSABLE`: smile / stretch / upperUp /
dimple / frown; browDown / eyeSquint / cheekSquint / noseSneer; funnel / pucker / jawOpen) and the channels raised
most that the truth leaves at rest; the **smile leak**: mouthSmile (L/R mean) during each non-smile combination's
hold (and during speech) minus its mean in the rest frames (truth at rest for 5 frames either side). Bilateral
channels in those tables are the mean of _L and _R. Where the head turns: its yaw, pitch and roll as captured
against the truth (the slope of a line through them, 1 the same size of turn, and r), and per channel the
correlation of its error (captured - truth) with the true yaw and pitch (``err_r_yaw``, ``err_r_pitch``: the
head's pose leaking into the expression).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from anima.capture.config import CaptureConfig
from anima.capture.pipeline import capture_face
from anima.core.contract import EXPR_NAMES
from anima.export.avatar import character_face
from anima.facemodel.ict import GEOMETRY_RANGES, load_face_model
from anima.facemodel.neutral import presented
from anima.io.atomic import write_json
from anima.io.video import VideoWriter
from anima.render.face import put_label
from anima.render.raster import rasterize, vertex_normals

SEED = 20240611
FPS = 30.0
SIZE = 512
SUPERSAMPLE = 2
N_IDENTITIES = 6
DEV, TEST = (0, 1, 2), (3, 4, 5)
QUICK_IDS = (0, 3)
COMBOS = {
    "AU4+7": {"browDown": 0.8, "eyeSquint": 0.7},
    "AU9+10": {"noseSneer": 0.8, "mouthUpperUp": 0.6},
    "AU12+6": {"mouthSmile": 0.8, "cheekSquint": 0.6},
    "AU1+2+5+26": {"browInnerUp": 0.8, "browOuterUp": 0.8, "eyeWide": 0.7, "jawOpen": 0.45},
    "AU1+4+15": {"browInnerUp": 0.8, "browDown": 0.5, "mouthFrown": 0.7},
    "AU18": {"mouthPucker": 0.8},
    "AU22": {"mouthFunnel": 0.8},
    "AU22+26": {"mouthFunnel": 0.7, "jawOpen": 0.35},
    "AU20": {"mouthStretch": 0.8},
    "AU45": {"eyeBlink": 1.0},
}
"""FACS combinations (bilateral channel names without their side) and their peak weights."""
QUICK_COMBOS = ("AU4+7", "AU9+10", "AU12+6", "AU1+2+5+26", "AU22+26", "AU20")
SPEECH = {"jawOpen": 0.4, "mouthFunnel": 0.35, "mouthPucker": 0.35, "mouthLowerDown": 0.4, "mouthUpperUp": 0.3,
          "mouthPress": 0.3, "mouthStretch": 0.2, "mouthRollLower": 0.25}  # fmt: skip
"""Speech's channels and their largest weight."""
SPEECH_S, QUICK_SPEECH_S = 6.0, 3.0
CONFUSABLE = {
    "mouth_corners": ("mouthSmile", "mouthStretch", "mouthUpperUp", "mouthDimple", "mouthFrown"),
    "upper_face": ("browDown", "eyeSquint", "cheekSquint", "noseSneer"),
    "round_mouth": ("mouthFunnel", "mouthPucker", "jawOpen"),
}
VIEWS = {
    "near": {"distance_cm": 38.0, "key": (-0.55, 0.5, 1.0), "fill": (0.7, 0.05, 0.7), "background": (0.42, 0.44, 0.48)},
    "far": {"distance_cm": 65.0, "key": (0.6, 0.45, 1.0), "fill": (-0.7, -0.1, 0.7), "background": (0.55, 0.5, 0.45)},
    "still": {"distance_cm": 38.0, "key": (-0.55, 0.5, 1.0), "fill": (0.7, 0.05, 0.7), "background": (0.42, 0.44, 0.48),
              "still": True},
}  # fmt: skip
"""The camera and the lights; ``still``: the near view with the head held still, facing the camera (a control:
what the head's turning costs), reported apart."""
SKIN_TONES = ((0.87, 0.69, 0.58), (0.62, 0.44, 0.33), (0.93, 0.76, 0.66), (0.78, 0.57, 0.43),
              (0.45, 0.31, 0.23), (0.84, 0.66, 0.52))  # fmt: skip
PARTS = ("face", "head_neck", "mouth_socket", "eye_socket_left", "eye_socket_right", "gums_tongue", "teeth",
         "eyeball_left", "eyeball_right", "eyelashes")  # fmt: skip
HOLD_EDGE = 3
REST_MARGIN = 5


# ---- the truth ----------------------------------------------------------------------------------------------


def channels(base: str, names: list[str]) -> list[int]:
    """The model's channels of ``base`` (both sides of a bilateral one)."""
    return [names.index(n) for n in (base, f"{base}_L", f"{base}_R") if n in names]


def smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def speech_curves(n: int, names: list[str], rng: np.random.Generator) -> np.ndarray:
    """``[n, E]`` weights moving like speech: per channel, white noise smoothed to syllables (3-5 a second),
    rectified and scaled to the channel's :data:`SPEECH` peak; both sides of a bilateral channel alike."""
    from scipy.ndimage import gaussian_filter1d

    W = np.zeros((n, len(names)))
    for base, peak in SPEECH.items():
        z = gaussian_filter1d(rng.standard_normal(n + 40), sigma=FPS / (2 * np.pi * rng.uniform(3, 5)) * 1.5)[20:-20]
        z = np.maximum(z / (np.std(z) + 1e-9) - 0.2, 0.0)
        z = z / max(z.max(), 1e-9) * peak
        ramp = smoothstep(np.minimum(np.arange(n), np.arange(n)[::-1]) / (0.3 * FPS))  # eases in and out
        for k in channels(base, names):
            W[:, k] = z * ramp
    return W


def timeline(names: list[str], combos, speech_s: float, rng: np.random.Generator) -> tuple[np.ndarray, list[dict]]:
    """The clip's weights ``[F, E]`` and its segments (``{"name", "hold": (a, b), "frames": (a, b)}``)."""
    sec = lambda s: int(round(s * FPS))
    parts, segs, at = [np.zeros((sec(1.0), len(names)))], [], sec(1.0)
    for name in combos:
        if name == "AU45":
            one = np.concatenate([smoothstep(np.arange(1, 4) / 3), [1.0, 1.0], smoothstep(np.arange(3, -1, -1) / 4)])
            curve = np.zeros(sec(3.0))
            starts = [sec(0.3), sec(1.0), sec(1.7), sec(2.4)]
            for s in starts:
                curve[s : s + len(one)] = one
            hold = np.flatnonzero(curve >= 0.999)
        else:
            curve = np.concatenate([smoothstep(np.arange(sec(1.0)) / sec(1.0)), np.ones(sec(1.0)),
                                    smoothstep(np.arange(sec(1.0), 0, -1) / sec(1.0))])  # fmt: skip
            hold = np.arange(sec(1.0) + HOLD_EDGE, sec(2.0) - HOLD_EDGE)
        W = np.zeros((len(curve) + sec(0.5), len(names)))
        for base, peak in COMBOS[name].items():
            W[: len(curve), channels(base, names)] = (curve * peak)[:, None]
        segs.append({"name": name, "hold": (hold + at).tolist(), "frames": (at, at + len(curve))})
        parts.append(W)
        at += len(W)
    if speech_s > 0:
        W = speech_curves(sec(speech_s), names, rng)
        segs.append({"name": "speech", "hold": list(range(at, at + len(W))), "frames": (at, at + len(W))})
        parts.append(W)
        at += len(W)
    parts.append(np.zeros((sec(1.0), len(names))))
    return np.concatenate(parts), segs


def head_path(n: int, rng: np.random.Generator) -> np.ndarray:
    """``[n, 3]`` yaw, pitch, roll (radians): slow sines (20, 15 and 4 degrees at most), phases from ``rng``."""
    t = np.arange(n) / FPS
    ph = rng.uniform(0, 2 * np.pi, 3)
    deg = [20 * np.sin(2 * np.pi * t / 7.7 + ph[0]), 15 * np.sin(2 * np.pi * t / 5.3 + ph[1]),
           4 * np.sin(2 * np.pi * t / 9.1 + ph[2])]  # fmt: skip
    return np.radians(np.stack(deg, -1))


# ---- the picture --------------------------------------------------------------------------------------------


def _range(name: str, k: int) -> np.ndarray:
    a, b = GEOMETRY_RANGES[name][k]
    return np.arange(a, b + 1)


class Face:
    """The ICT head drawn for the camera: its triangles (:data:`PARTS`) and colours per vertex for an identity's
    skin tone."""

    def __init__(self, model, identity: np.ndarray, skin_rgb):
        self.model = model
        self.base = model.vertices(identity).astype(np.float64)
        self.deltas = model.expr_deltas.reshape(len(model.expr_deltas), -1).astype(np.float32)
        polys = model.faces[np.concatenate([_range(p, 1) for p in PARTS])]
        lashes = np.isin(polys[:, 0], _range("eyelashes", 0))
        eye_y = self.base[_range("eyeball_left", 0), 1].mean()
        polys = polys[~lashes | (self.base[polys[:, 0], 1] > eye_y)]  # the upper lashes (the lower: a black rim)
        self.tris = np.ascontiguousarray(
            np.concatenate([polys[:, [0, 1, 2]], polys[polys[:, 3] >= 0][:, [0, 2, 3]]]), np.int64
        )
        self.colors = self._paint(np.asarray(skin_rgb, np.float64))
        lm = self.base[model.landmarks68]
        self.aim = lm.mean(0)
        self.pivot = np.array([0.0, lm[8, 1] - 3.0, lm[8, 2] - 9.0])  # about the top of the neck

    def _paint(self, skin: np.ndarray) -> np.ndarray:
        V = self.base
        lm = V[self.model.landmarks68]
        col = np.tile(skin, (len(V), 1))
        dark = skin * 0.55
        face = _range("face", 0)
        # lips: the face's vertices inside the outer lip contour (landmarks 48-59), seen from the front
        contour = lm[48:60, :2].astype(np.float32)
        P = V[face]
        inside = np.array([cv2.pointPolygonTest(contour, (float(x), float(y)), True) for x, y in P[:, :2]])
        front = P[:, 2] > lm[48:60, 2].min() - 1.5
        w = np.clip((inside + 0.08) / 0.15, 0, 1) * front
        lip = 0.45 * skin + 0.55 * np.array([0.7, 0.33, 0.33]) * (0.5 + 0.5 * skin.mean() / 0.7)
        col[face] = col[face] * (1 - w[:, None]) + lip * w[:, None]
        # brows: a band along the brow landmarks (17-21, 22-26), thicker at the inner end
        for a in (17, 22):
            pts = lm[a : a + 5]
            d = np.full(len(P), np.inf)
            for i in range(4):
                p0, p1 = pts[i, :2], pts[i + 1, :2]
                t = np.clip(((P[:, :2] - p0) @ (p1 - p0)) / ((p1 - p0) @ (p1 - p0)), 0, 1)
                d = np.minimum(d, np.linalg.norm(P[:, :2] - (p0 + t[:, None] * (p1 - p0)), axis=-1))
            inner = np.abs(P[:, 0]) < np.abs(pts[:, 0]).mean()
            half = np.where(inner, 0.55, 0.4)
            w = np.clip((half - d) / 0.15, 0, 1) * (P[:, 2] > pts[:, 2].min() - 1.0)
            col[face] = col[face] * (1 - 0.85 * w[:, None]) + (dark * 0.45) * 0.85 * w[:, None]
        # the mouth's inside, teeth, eyes
        col[_range("mouth_socket", 0)] = (0.22, 0.07, 0.07)
        col[_range("gums_tongue", 0)] = (0.55, 0.25, 0.25)
        col[_range("teeth", 0)] = (0.88, 0.86, 0.8)
        col[_range("eyelashes", 0)] = (0.08, 0.06, 0.05)
        for s in ("left", "right"):
            col[_range(f"eye_socket_{s}", 0)] = skin * 0.5
            ball = _range(f"eyeball_{s}", 0)
            B = V[ball]
            c = (B.max(0) + B.min(0)) / 2
            c[2] = B[:, 2].max() - (B[:, 1].max() - B[:, 1].min()) / 2  # the sphere's centre behind its front
            d = B - c
            ang = np.degrees(np.arccos(np.clip(d[:, 2] / np.linalg.norm(d, axis=-1), -1, 1)))
            col[ball] = (0.9, 0.88, 0.85)
            col[ball[ang < 24]] = (0.32, 0.22, 0.14)
            col[ball[ang < 10]] = (0.04, 0.03, 0.03)
        return col

    def draw(self, weights: np.ndarray, ypr: np.ndarray, view: dict) -> np.ndarray:
        """One ``SIZE`` square RGB uint8 frame: the face with ``weights [E]`` turned by ``ypr`` (radians)."""
        on = np.flatnonzero(weights)
        V = self.base + (weights[on].astype(np.float32) @ self.deltas[on]).reshape(-1, 3)
        y, p, r = ypr
        cy, sy, cp, sp, cr, sr = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rx = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
        Rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
        X = (V - self.pivot) @ (Ry @ Rx @ Rz).T + self.pivot
        S = SIZE * SUPERSAMPLE
        f = 0.9 * S
        depth = view["distance_cm"] + self.aim[2] - X[:, 2]
        u = S / 2 + f * (X[:, 0] - self.aim[0]) / depth
        v = S / 2 - f * (X[:, 1] - self.aim[1]) / depth
        n = vertex_normals(X, self.tris)
        light = 0.22
        for d, k in ((view["key"], 0.72), (view["fill"], 0.3)):
            d = np.asarray(d, np.float64) / np.linalg.norm(d)
            light = light + k * np.clip(n @ d, 0, 1)
        img, mask, _ = rasterize(np.stack([u, v, -depth], -1), self.tris, (self.colors * light[:, None]).clip(0, 1),
                                 (S, S), back_faces=False)  # fmt: skip
        img = cv2.resize(img, (SIZE, SIZE), interpolation=cv2.INTER_AREA)  # the face's colour, averaged down
        cover = cv2.resize(mask.astype(np.float32), (SIZE, SIZE), interpolation=cv2.INTER_AREA)
        img += (1.0 - cover)[..., None] * np.asarray(view["background"], np.float32)
        return np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8)


# ---- one clip -----------------------------------------------------------------------------------------------


def film(face: Face, W: np.ndarray, ypr: np.ndarray, view: dict, path: Path, keep: set[int]) -> dict[int, np.ndarray]:
    """Render the clip into the H.264 video ``path``; returns the frames of ``keep`` (for the contact sheet)."""
    kept = {}
    with VideoWriter(path, FPS, (SIZE, SIZE), quality=6) as w:
        for f in range(len(W)):
            img = face.draw(W[f], ypr[f], view)
            w.write(img)
            if f in keep:
                kept[f] = img
    return kept


def run_clip(model, ident: int, coef: np.ndarray, view_name: str, combos, speech_s: float, work: Path,
             keep_mid: bool) -> tuple[dict, dict]:  # fmt: skip
    """One identity seen from one view: rendered, captured, read. Returns (the clip's arrays, its kept
    frames)."""
    names = list(model.expr_names)
    W, segs = timeline(names, combos, speech_s, np.random.default_rng([SEED, ident]))  # the same in every view
    turn = head_path(len(W), np.random.default_rng([SEED, ident, list(VIEWS).index(view_name)]))
    ypr = np.zeros((len(W), 3)) if VIEWS[view_name].get("still") else turn
    video = work / f"id{ident}_{view_name}.mp4"
    keep = {s["hold"][len(s["hold"]) // 2] for s in segs} | {15} if keep_mid else set()
    t0 = time.perf_counter()
    kept = {}
    if not video.is_file():
        face = Face(model, coef, SKIN_TONES[ident % len(SKIN_TONES)])
        kept = film(face, W, ypr, VIEWS[view_name], video, keep)
        np.savez_compressed(work / f"id{ident}_{view_name}_truth.npz", weights=W, names=np.array(names), ypr=ypr,
                            identity=coef, segments=json.dumps(segs))  # fmt: skip
    t1 = time.perf_counter()
    seq = capture_face(str(video), CaptureConfig(face_only=True), progress=False)
    t2 = time.perf_counter()
    rest = presented(seq)[1]
    G = character_face(seq)[:, [EXPR_NAMES.index(n) for n in seq.expr_names]]  # what every export carries
    F = min(len(W), seq.n_frames)
    clip = {
        "identity": ident, "view": view_name, "truth": W[:F], "got": np.clip(G[:F], 0, 1),
        "fit": np.asarray(seq.expression[:F]), "tracked": np.asarray(seq.tracked[:F]), "segments": segs,
        "ypr": ypr[:F], "ypr_got": seq.head_euler()[:F],
        "names": list(seq.expr_names), "rest_taken": rest, "render_s": round(t1 - t0, 1),
        "capture_s": round(t2 - t1, 1), "frames_rendered": len(W), "frames_captured": int(seq.n_frames),
    }  # fmt: skip
    assert clip["names"] == names, "the capture's channels are the model's"
    return clip, kept


# ---- the numbers ---------------------------------------------------------------------------------------------


def _stats(per_identity: list[float], digits: int = 3) -> dict:
    v = np.array([x for x in per_identity if x is not None and np.isfinite(x)])
    if not len(v):
        return {"mean": None, "min": None, "max": None, "identities": 0}
    r = lambda x: round(float(x), digits)
    return {"mean": r(v.mean()), "min": r(v.min()), "max": r(v.max()), "identities": len(v)}


def _bases(names: list[str]) -> list[str]:
    out = []
    for n in names:
        b = n[:-2] if n.endswith(("_L", "_R")) else n
        if b not in out:
            out.append(b)
    return out


def _base_mean(A: np.ndarray, names: list[str], base: str) -> np.ndarray:
    return A[:, channels(base, names)].mean(-1)


def rest_frames(T: np.ndarray) -> np.ndarray:
    """Frames whose truth is at rest for :data:`REST_MARGIN` frames either side."""
    moving = np.abs(T).max(-1) > 1e-6
    near = np.convolve(moving.astype(float), np.ones(2 * REST_MARGIN + 1), "same") > 0
    return ~near


def _pearson(a: np.ndarray, b: np.ndarray) -> float | None:
    if np.std(a) < 1e-6 or np.std(b) < 1e-9:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def summarise(clips: list[dict]) -> dict:
    """The metrics of the module docstring over ``clips`` (one split's)."""
    names = clips[0]["names"]
    ids = sorted({c["identity"] for c in clips})
    by_id = {i: [c for c in clips if c["identity"] == i] for i in ids}
    cat = lambda cs, k: np.concatenate([c[k] for c in cs])
    out = {"identities": ids, "clips": len(clips), "frames": int(sum(len(c["truth"]) for c in clips))}
    out["face_found"] = _stats([cat(cs, "tracked").mean() for cs in by_id.values()]) | {
        "pooled": round(float(cat(clips, "tracked").mean()), 4)}  # fmt: skip

    Y, Yg = cat(clips, "ypr"), cat(clips, "ypr_got")
    turning = bool(np.std(Y) > 1e-6)
    if turning:  # the head's pose as captured against the truth: slope (1: the same size of turn) and r
        out["head_pose"] = {a: {"slope": round(float(np.polyfit(Y[:, j], Yg[:, j], 1)[0]), 3),
                                "r": round(float(np.corrcoef(Y[:, j], Yg[:, j])[0, 1]), 4),
                                "truth_range_deg": round(float(np.degrees(np.ptp(Y[:, j]))), 1)}
                            for j, a in enumerate(("yaw", "pitch", "roll"))}  # fmt: skip
    per_channel = {}
    for k, n in enumerate(names):
        T, G, Fit = cat(clips, "truth")[:, k], cat(clips, "got")[:, k], cat(clips, "fit")[:, k]
        row = {"mae": round(float(np.abs(G - T).mean()), 4),
               "mae_by_identity": _stats([np.abs(cat(cs, "got")[:, k] - cat(cs, "truth")[:, k]).mean()
                                          for cs in by_id.values()], 4),
               "fit_mae": round(float(np.abs(Fit - T).mean()), 4)}  # fmt: skip
        if turning:
            err = G - T
            row["err_r_yaw"] = round(float(np.corrcoef(err, Y[:, 0])[0, 1]), 3) if np.std(err) > 1e-6 else None
            row["err_r_pitch"] = round(float(np.corrcoef(err, Y[:, 1])[0, 1]), 3) if np.std(err) > 1e-6 else None
        if np.std(T) > 1e-6:
            r = _pearson(T, G)
            row["r"] = None if r is None else round(r, 3)
            row["r_by_identity"] = _stats([_pearson(cat(cs, "truth")[:, k], cat(cs, "got")[:, k])
                                           for cs in by_id.values()])  # fmt: skip
            fr = _pearson(T, Fit)
            row["fit_r"] = None if fr is None else round(fr, 3)
        per_channel[n] = row
    out["per_channel"] = per_channel

    combos = [s["name"] for s in clips[0]["segments"]]
    confusable = [b for group in CONFUSABLE.values() for b in group]
    holds, confusion, leak = {}, {}, {}
    for name in combos:
        seg = lambda c: next(s for s in c["segments"] if s["name"] == name)
        truth_bases = list(COMBOS.get(name, SPEECH))
        per_id = {}
        for i, cs in by_id.items():
            T = np.concatenate([c["truth"][seg(c)["hold"]] for c in cs])
            G = np.concatenate([c["got"][seg(c)["hold"]] for c in cs])
            Fit = np.concatenate([c["fit"][seg(c)["hold"]] for c in cs])
            rest = [c["got"][rest_frames(c["truth"])] for c in cs]
            per_id[i] = {"T": T, "G": G, "Fit": Fit,
                         "smile_leak": np.mean([_base_mean(c["got"][seg(c)["hold"]], names, "mouthSmile").mean()
                                                - _base_mean(r, names, "mouthSmile").mean()
                                                for c, r in zip(cs, rest)])}  # fmt: skip
        n_frames = int(sum(len(p["T"]) for p in per_id.values()))
        row = {"frames": n_frames}
        for b in truth_bases:
            got = [_base_mean(p["G"], names, b).mean() for p in per_id.values()]
            row[b] = {"truth": round(float(np.mean([_base_mean(p["T"], names, b).mean() for p in per_id.values()])), 3),
                      "got": _stats(got),
                      "fit": round(float(np.mean([_base_mean(p["Fit"], names, b).mean()
                                                  for p in per_id.values()])), 3)}  # fmt: skip
        holds[name] = row
        conf = {"frames": n_frames}
        for b in confusable:
            conf[b] = _stats([_base_mean(p["G"], names, b).mean() for p in per_id.values()])["mean"]
        rises = []
        for b in _bases(names):
            if b in truth_bases:
                continue
            v = np.mean([_base_mean(p["G"], names, b).mean() for p in per_id.values()])
            if v >= 0.05:
                rises.append((b, round(float(v), 3)))
        conf["raised_not_in_truth"] = sorted(rises, key=lambda x: -x[1])[:6]
        confusion[name] = conf
        if name != "AU12+6":
            leak[name] = _stats([p["smile_leak"] for p in per_id.values()]) | {"frames": n_frames}
    rest_smile = [np.mean([_base_mean(c["got"][rest_frames(c["truth"])], names, "mouthSmile").mean() for c in cs])
                  for cs in by_id.values()]  # fmt: skip
    out["holds"], out["confusion"], out["smile_leak"] = holds, confusion, leak
    out["smile_at_rest"] = _stats(rest_smile) | {"frames": int(sum(rest_frames(c["truth"]).sum() for c in clips))}
    return out


def contact_sheet(kept: dict, path: Path) -> None:
    """The kept frames (``{(identity, view, label): image}``) as a grid: a row per identity and view."""
    rows = {}
    for (i, v, label), img in kept.items():
        rows.setdefault((i, v), []).append(put_label(cv2.resize(img, (256, 256), interpolation=cv2.INTER_AREA),
                                                      f"id{i} {v} {label}"))  # fmt: skip
    width = max(len(r) for r in rows.values())
    pad = lambda r: r + [np.zeros_like(r[0])] * (width - len(r))
    sheet = np.concatenate([np.concatenate(pad(r), 1) for r in rows.values()], 0)
    cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "roundtrip_face.json"))
    ap.add_argument("--quick", action="store_true", help="2 identities (one development, one test), the near view, "
                    f"the key combinations ({', '.join(QUICK_COMBOS)}), 3 s of speech")  # fmt: skip
    ap.add_argument("--videos", default=None, help="keep the rendered videos and their truth here (reused when there)")
    ap.add_argument("--views", nargs="*", choices=list(VIEWS), default=None,
                    help="the views (default: all three; --quick: near)")  # fmt: skip
    ap.add_argument("--sheet", default="/tmp/roundtrip_face_sheet.png",
                    help="a contact sheet of frames at each hold's middle (two identities, every view)")  # fmt: skip
    a = ap.parse_args()
    t0 = time.perf_counter()
    model = load_face_model()
    coefs = np.clip(np.random.default_rng(SEED).standard_normal((N_IDENTITIES, model.id_deltas.shape[0])), -2, 2)
    ids = QUICK_IDS if a.quick else tuple(range(N_IDENTITIES))
    views = tuple(a.views) if a.views else ("near",) if a.quick else tuple(VIEWS)
    combos = QUICK_COMBOS if a.quick else tuple(COMBOS)
    speech_s = QUICK_SPEECH_S if a.quick else SPEECH_S
    shown = {QUICK_IDS[0], QUICK_IDS[1]}
    clips, kept = [], {}
    with tempfile.TemporaryDirectory(prefix="anima-roundtrip-face-") as tmp:
        work = Path(a.videos) if a.videos else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for i in ids:
            for v in views:
                clip, frames = run_clip(model, i, coefs[i], v, combos, speech_s, work, i in shown)
                label = {s["hold"][len(s["hold"]) // 2]: s["name"] for s in clip["segments"]} | {15: "rest"}
                kept |= {(i, v, label[f]): img for f, img in sorted(frames.items())}
                clips.append(clip)
                print(json.dumps({k: clip[k] for k in ("identity", "view", "frames_rendered", "render_s", "capture_s")}
                                 | {"face_found": round(float(clip["tracked"].mean()), 3),
                                    "rest_taken": clip["rest_taken"]}), flush=True)  # fmt: skip
    if kept and a.sheet:
        contact_sheet(kept, Path(a.sheet))
    split = {"development": [i for i in ids if i in DEV], "test": [i for i in ids if i in TEST]}

    def by_split(cs: list[dict]) -> dict:
        if not cs:
            return {}
        out = {k: summarise([c for c in cs if c["identity"] in v]) for k, v in split.items() if v}
        return out | {"all": summarise(cs)}

    turning = [c for c in clips if not VIEWS[c["view"]].get("still")]
    results = by_split(turning)
    control = by_split([c for c in clips if VIEWS[c["view"]].get("still")])
    by_view = {v: summarise([c for c in clips if c["view"] == v]) for v in views}
    import mediapipe

    write_json(a.out, {
        "protocol": "benchmarks/roundtrip_face.py docstring", "quick": a.quick,
        "splits": {"development": list(DEV), "test": list(TEST),
                   "note": "development identities may be looked at to tune the solver; test identities never"},
        "identities": {str(i): {"seed": SEED, "row": i, "coefficients": "N(0, 1) clipped to +-2, 100 modes",
                                "skin_rgb": SKIN_TONES[i % len(SKIN_TONES)]} for i in ids},
        "views": {v: VIEWS[v] for v in views}, "combinations": {c: COMBOS[c] for c in combos},
        "speech": {"seconds": speech_s, "channels": SPEECH}, "fps": FPS, "size": SIZE,
        "capture": "anima.capture.pipeline.capture_face (anima capture --face-only), then "
                   "anima.export.avatar.character_face (what arkit.csv and every export carry)",
        "reader": f"mediapipe {mediapipe.__version__}", "machine": "2 cores, no GPU",
        "clips": [{k: c[k] for k in ("identity", "view", "frames_rendered", "frames_captured", "render_s",
                                     "capture_s", "rest_taken")} | {"face_found": round(float(c["tracked"].mean()), 4)}
                  for c in clips],
        "results": results, "still_head_control": control, "by_view": by_view,
        "run_s": round(time.perf_counter() - t0, 1),
    })  # fmt: skip
    print(json.dumps(headline(results) | {"still_head_control": headline(control)}, indent=1))
    print(f"{time.perf_counter() - t0:.0f} s")


KEY_CHANNELS = ("browDown_L", "eyeSquint_L", "noseSneer_L", "mouthUpperUp_L", "mouthSmile_L", "cheekSquint_L",
                "browInnerUp_L", "eyeWide_L", "jawOpen", "mouthFrown_L", "mouthPucker", "mouthFunnel",
                "mouthStretch_L", "eyeBlink_L")  # fmt: skip


def headline(results: dict) -> dict:
    """A short view of the results for the terminal."""
    out = {}
    for k, r in results.items():
        pc = r["per_channel"]
        out[k] = {"face_found": r["face_found"]["pooled"], "frames": r["frames"],
                  "mae/r": {n: [pc[n]["mae"], pc[n].get("r")] for n in KEY_CHANNELS if n in pc},
                  "smile_leak": {c: v["mean"] for c, v in r["smile_leak"].items()},
                  "holds": {c: {b: [v["truth"], v["got"]["mean"]] for b, v in h.items() if b != "frames"}
                            for c, h in r["holds"].items()}}  # fmt: skip
    return out


if __name__ == "__main__":
    main()
