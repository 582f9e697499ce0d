"""Any anima motion on a user's own avatar (``anima retarget``): a VRM 1.0 or a skinned glTF character gets
the motion as its first animation, everything else of the file kept.

* **Which bone is which**: the VRM humanoid map when the file has one; otherwise the node names, read in each
  convention anima knows (Mixamo with any ``mixamorig*`` prefix, Ready Player Me's, Unreal's, VRM's, anima's),
  the one naming the most bones wins. An avatar without the required bones (hips, spine, head, both arms,
  forearms, hands, thighs, shins, feet) is refused with the missing ones named (exit 4).
* **Rest-pose-aware** (:func:`retarget_rotations`): copying local rotations between rigs is wrong whenever
  their rest poses or bone axes differ (a Mixamo T-pose, an A-pose, rolled forearms: "arms upside down"). Each
  mapped bone gets a frame measured on the skeleton's geometry, the same way on both rigs: its primary axis
  towards the next mapped joint down its chain (the spine to the neck, the hand to the middle finger...), its
  secondary axis the character's forward (torso, neck, head, shoulders, upper arms, legs), the palm's normal
  (forearms, hands, fingers: measured from the index and little finger knuckles) or up (feet, toes). The
  target bone's world rotation is the source bone's posed frame times the inverse of the target's rest frame
  times the target's rest rotation: each bone points where the source's points and twists as it twists,
  whatever the target's axes. Unmapped nodes (twist helpers, hair, eyes) keep their rest local transform.
* **Root and floor**: the hips' travel is scaled by the ratio of the hip heights (above the feet joints);
  a frame whose feet joints would go below their rest height is raised by the difference.
* **Faces**: ARKit-52 onto the avatar's morph targets by name (prefixes, case and ``_L``/``Left`` spellings
  ignored); else, on a VRM, onto its expression presets through :data:`anima.export.vrm.VRM_PRESETS`. The
  report lists which channels found a home.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from anima.core import rig
from anima.core.contract import EXPR_NAMES
from anima.core.kinematics import parents_first
from anima.core.rotations import matrix_to_quat
from anima.errors import InputError, SchemaError
from anima.export.avatar import body_of, character_face, character_motion
from anima.export.vrm import VRM_PRESETS, arkit_weights, vrm_expressions
from anima.io.arkit import LIVE_LINK_COLUMNS, arkit_name
from anima.io.atomic import write_json
from anima.io.gltf import write_with_animation
from anima.io.gltf_read import Gltf, read_gltf
from anima.io.outdir import check_out_file, record_out_file
from anima.io.sequence import read_sequence
from anima.io.validate import read_json

SIDES = ("Left", "Right")
REQUIRED = ("Hips", "Spine", "Head") + tuple(
    f"{s}{b}" for s in SIDES for b in ("Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot")
)
"""The bones an avatar must have (VRM 1.0's required humanoid bones, in anima's names)."""
FEET = tuple(f"{s}{b}" for s in SIDES for b in ("Foot", "ToeBase", "Toe_End"))
_PREFER = {"Hips": "Spine", "Spine2": "Neck", "LeftHand": "LeftHandMiddle1", "RightHand": "RightHandMiddle1"}
_KIDS = {j: [int(c) for c in np.flatnonzero(rig.PARENTS_RIG == j)] for j in range(rig.N_RIG)}


@dataclass
class Humanoid:
    """Which node of an avatar is which rig joint (``nodes``: rig joint name -> node index) and how that was
    found (``convention``)."""

    nodes: dict[str, int]
    convention: str


def _norm(name: str) -> str:
    s = re.sub(r"[^a-z0-9]", "", re.split(r"[:|]", str(name))[-1].lower())
    return re.sub(r"^mixamorig\d*", "", s)


def find_humanoid(g: Gltf) -> Humanoid:
    """The avatar's humanoid (see the module docstring); SchemaError naming the missing bones."""
    vrm = g.vrm
    if vrm and (vrm.get("humanoid") or {}).get("humanBones"):
        from_vrm = {v: k for k, v in rig.CONVENTIONS["vrm"].items() if v}
        nodes = {}
        for bone, spec in vrm["humanoid"]["humanBones"].items():
            node = spec.get("node") if isinstance(spec, dict) else None
            if bone in from_vrm and isinstance(node, int) and 0 <= node < len(g.nodes):
                nodes[from_vrm[bone]] = node
        best = Humanoid(nodes, "vrm (VRMC_vrm humanoid)")
    else:
        joints = {j for s in g.doc.get("skins", []) for j in s.get("joints", []) if isinstance(j, int)}
        cand = sorted(joints) if joints else range(len(g.nodes))
        best = Humanoid({}, "none")
        for conv in rig.NAME_SEARCH:
            table = {_norm(v): k for k, v in rig.CONVENTIONS[conv].items() if v}
            nodes = {}
            for i in cand:
                k = table.get(_norm(g.names[i]))
                if k and k not in nodes:
                    nodes[k] = i
            if len(nodes) > len(best.nodes):
                best = Humanoid(nodes, f"{conv} names")
    missing = [b for b in REQUIRED if b not in best.nodes]
    if missing:
        vrm_names = [rig.CONVENTIONS["vrm"][b] for b in missing]
        raise SchemaError(
            f"{g.path}: no humanoid skeleton anima recognises: missing {', '.join(vrm_names)} "
            f"(found {len(best.nodes)} bones by {best.convention}; VRM humanoid map, Mixamo, Unreal or anima names)"
        )
    return best


# ---- frames -------------------------------------------------------------------------------------------------


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def bone_frame(primary: np.ndarray, secondary: np.ndarray) -> np.ndarray:
    """Rotation matrices ``[..., 3, 3]`` whose columns are the primary axis, the secondary made orthogonal to
    it, and their cross product (a secondary parallel to the primary falls back to another axis)."""
    e1 = _unit(primary)
    s = secondary - np.sum(secondary * e1, -1, keepdims=True) * e1
    bad = np.linalg.norm(s, axis=-1) < 1e-6
    if np.any(bad):
        alt = np.where(np.abs(e1[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        alt = alt - np.sum(alt * e1, -1, keepdims=True) * e1
        s = np.where(bad[..., None], alt, s)
    e2 = _unit(s)
    return np.stack([e1, e2, np.cross(e1, e2)], -1)


def _chain(j: int) -> list[int]:
    out, k = [], j
    while _KIDS[k]:
        pref = _PREFER.get(rig.NAMES[k])
        k = rig.IX[pref] if pref else _KIDS[k][0]
        out.append(k)
    return out


def _ref_kind(name: str) -> str:
    if "ForeArm" in name or "Hand" in name:
        return "palm"
    if "Foot" in name or "Toe" in name:
        return "up"
    return "forward"


def palm_normals(pos: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each side's palm normal (pointing out of the palm) from the hand and its index and little finger
    knuckles; straight down where the hand has no fingers."""
    out = {}
    for s in SIDES:
        h, i, p = (pos.get(f"{s}Hand{x}") for x in ("", "Index1", "Pinky1"))
        if h is None or i is None or p is None:
            out[s] = np.array([0.0, -1.0, 0.0])
            continue
        n = np.cross(i - h, p - h)
        out[s] = _unit(-n if s == "Left" else n)
    return out


def _plan(mapped: set[str]) -> dict[str, tuple[str | None, str | None]]:
    """Per mapped joint: the joint its primary axis aims at (the first mapped one down its chain), or None
    with the mapped ancestor it continues from."""
    plan = {}
    for n in mapped:
        j = rig.IX[n]
        aim = next((rig.NAMES[k] for k in _chain(j) if rig.NAMES[k] in mapped), None)
        anc = None
        if aim is None:
            p = rig.PARENTS_RIG[j]
            while p >= 0 and rig.NAMES[p] not in mapped:
                p = rig.PARENTS_RIG[p]
            anc = rig.NAMES[p] if p >= 0 else None
        plan[n] = (aim, anc)
    return plan


def _refs(pos: dict[str, np.ndarray], names) -> dict[str, np.ndarray]:
    palm = palm_normals(pos)
    out = {}
    for n in names:
        kind = _ref_kind(n)
        out[n] = palm["Left" if n.startswith("Left") else "Right"] if kind == "palm" else (
            np.array([0.0, 1.0, 0.0]) if kind == "up" else np.array([0.0, 0.0, 1.0])
        )  # fmt: skip
    return out


def _rest_frames(pos: dict[str, np.ndarray], plan: dict) -> dict[str, np.ndarray]:
    refs = _refs(pos, plan)
    out = {}
    for n, (aim, anc) in plan.items():
        prim = pos[aim] - pos[n] if aim else (pos[n] - pos[anc] if anc else np.array([0.0, 1.0, 0.0]))
        out[n] = bone_frame(prim, refs[n])
    return out


def facing(pos_world: dict[str, np.ndarray]) -> np.ndarray:
    """The rotation ``A`` from anima's axes (+x the character's left, +y up, +z forward) to the avatar's: +y
    stays glTF's up, +x along the avatar's left (its hips' and shoulders' left-right lines)."""
    x = pos_world["LeftUpLeg"] - pos_world["RightUpLeg"] + pos_world["LeftArm"] - pos_world["RightArm"]
    x = _unit(x * [1.0, 0.0, 1.0])
    y = np.array([0.0, 1.0, 0.0])
    return np.stack([x, y, np.cross(x, y)], -1)


def avatar_front(g: Gltf, hum: Humanoid) -> list[float]:
    """The avatar's forward at its rest, in its file's world axes (:func:`facing`'s): the side a camera stands
    on to see its face (the viewer's face close-up)."""
    W = g.world()
    front = facing({n: W[i, :3, 3] for n, i in hum.nodes.items()})[:, 2]
    return [round(float(v), 4) for v in front]


def in_t_pose(g: Gltf, hum: Humanoid, max_deg: float = 10.0) -> bool:
    """Whether the avatar's rest is a T-pose: both upper arms and forearms within ``max_deg`` of horizontal."""
    W = g.world()
    for s in SIDES:
        a, b, c = (W[hum.nodes[f"{s}{n}"], :3, 3] for n in ("Arm", "ForeArm", "Hand"))
        for u in (b - a, c - b):
            if np.degrees(np.arcsin(abs(u[1]) / max(np.linalg.norm(u), 1e-9))) > max_deg:
                return False
    return True


# ---- the motion -------------------------------------------------------------------------------------------------


def _rotation_part(M: np.ndarray) -> np.ndarray:
    """The nearest rotation to each ``M [..., 3, 3]`` (a node's scale divided out)."""
    U, _, Vt = np.linalg.svd(M)
    U[..., :, -1] *= np.where(np.linalg.det(U @ Vt) < 0, -1.0, 1.0)[..., None]
    return U @ Vt


def retarget_rotations(
    src_rest: np.ndarray, src_G: np.ndarray, src_P: np.ndarray, tgt_pos: dict[str, np.ndarray], A: np.ndarray
) -> dict[str, np.ndarray]:
    """World rotations ``{joint: [F, 3, 3]}`` (in anima's axes; the avatar's are ``A @ R @ A.T``) that give each
    mapped target bone the source bone's posed frame: ``S(f) @ C_t.T`` with ``S`` the source frame (primary
    from the posed joints, secondary turned by the source bone's rotation) and ``C_t`` the target's rest frame
    (its rest positions ``tgt_pos`` already in anima's axes). ``src_rest [J, 3]``: the source rig's rest (world
    rotations identity), ``src_G [F, J, 3, 3]`` / ``src_P [F, J, 3]``: its posed world rotations and joints."""
    plan = _plan(set(tgt_pos))
    src_pos = {n: src_rest[rig.IX[n]] for n in plan}
    Ct = _rest_frames(tgt_pos, plan)
    refs = _refs(src_pos, plan)
    out = {}
    for n, (aim, anc) in plan.items():
        j = rig.IX[n]
        if aim:
            prim = src_P[:, rig.IX[aim]] - src_P[:, j]
        else:
            rest_dir = src_pos[n] - src_pos[anc] if anc else np.array([0.0, 1.0, 0.0])
            prim = src_G[:, j] @ rest_dir
        S = bone_frame(prim, src_G[:, j] @ refs[n])
        out[n] = S @ Ct[n].T
    return out


def pose_avatar(g: Gltf, hum: Humanoid, src: dict) -> dict:
    """The avatar posed by the source rig motion ``src`` (``rest``, ``global``, ``positions``, ``root``, as
    :func:`anima.export.avatar.character_motion` gives them): ``{"local_rot": {node: [F, 4]}, "hips_t": [F, 3]
    (the hips node's local translation), "world": {node: [F, 4, 4]} (the mapped nodes and their ancestors), "A",
    "raised_m", "hip_ratio"}``."""
    W0 = g.world()
    pos_w = {n: W0[i, :3, 3] for n, i in hum.nodes.items()}
    A = facing(pos_w)
    tgt_pos = {n: A.T @ p for n, p in pos_w.items()}
    R = retarget_rotations(src["rest"], src["global"], src["positions"], tgt_pos, A)
    F = len(src["root"])
    rest_rot = _rotation_part(W0[:, :3, :3])
    Wrot = {hum.nodes[n]: A @ r @ A.T @ rest_rot[hum.nodes[n]] for n, r in R.items()}
    feet = [n for n in FEET if n in hum.nodes]
    floor_t = min(pos_w[n][1] for n in feet)
    floor_s = min(src["rest"][rig.IX[n], 1] for n in feet)
    hips = hum.nodes["Hips"]
    ratio = (pos_w["Hips"][1] - floor_t) / max(src["rest"][rig.HIPS, 1] - floor_s, 1e-6)
    hips_w = pos_w["Hips"] + (A @ ((src["root"] - src["rest"][rig.HIPS]) * ratio).T).T
    world = _fk(g, Wrot, hips, hips_w)
    low = np.min([world[hum.nodes[n]][:, 1, 3] for n in feet], 0)
    raise_m = np.maximum(floor_t - low, 0.0)
    if raise_m.max() > 0:
        hips_w = hips_w + raise_m[:, None] * [0.0, 1.0, 0.0]
        world = _fk(g, Wrot, hips, hips_w)
    par = g.parents
    local_rot, hips_t = {}, None
    for i in Wrot:
        Pw = world[par[i]] if par[i] >= 0 else np.tile(np.eye(4), (F, 1, 1))
        Lm = _affine_inverse(Pw) @ world[i]
        local_rot[i] = _continuous(matrix_to_quat(_rotation_part(Lm[:, :3, :3])))
        if i == hips:
            hips_t = Lm[:, :3, 3]
    return {"local_rot": local_rot, "hips_t": hips_t, "world": world, "A": A, "raised_m": float(raise_m.max()),
            "hip_ratio": float(ratio)}  # fmt: skip


def _affine_inverse(M: np.ndarray) -> np.ndarray:
    """Inverses of affine transforms ``M [..., 4, 4]`` (the 3 x 3 part by its adjugate: no LAPACK call per
    matrix, which costs milliseconds each on a busy machine)."""
    A = M[..., :3, :3]
    c0, c1, c2 = A[..., :, 0], A[..., :, 1], A[..., :, 2]
    adj = np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], -2)  # rows of the inverse x det
    det = np.einsum("...i,...i->...", c0, adj[..., 0, :])
    inv = np.zeros_like(M)
    inv[..., :3, :3] = adj / det[..., None, None]
    inv[..., :3, 3] = -np.einsum("...ij,...j->...i", inv[..., :3, :3], M[..., :3, 3])
    inv[..., 3, 3] = 1.0
    return inv


def _continuous(q: np.ndarray) -> np.ndarray:
    """Quaternions ``[F, 4]`` with each sign chosen next to the previous frame's (no flips through -q)."""
    q = q.copy()
    for f in range(1, len(q)):
        if np.dot(q[f], q[f - 1]) < 0:
            q[f] = -q[f]
    return q


def _fk(g: Gltf, Wrot: dict[int, np.ndarray], hips: int, hips_w: np.ndarray) -> dict[int, np.ndarray]:
    """World transforms ``{node: [F, 4, 4]}`` of the mapped nodes and their ancestors (no other node: the
    work and memory do not grow with the rest of the file's nodes): mapped nodes at their world rotations
    ``Wrot`` (their own scale kept), the hips at ``hips_w``, every other node at its rest local transform."""
    F = len(hips_w)
    needed: set[int] = set()
    for i in [*Wrot, hips]:
        while i >= 0 and i not in needed:
            needed.add(i)
            i = int(g.parents[i])
    W: dict[int, np.ndarray] = {}
    eye = np.tile(np.eye(4), (F, 1, 1))
    for i in [i for i in parents_first(g.parents) if i in needed]:
        p = g.parents[i]
        Pw = W[p] if p >= 0 else eye
        L0 = g.local(i)
        if i not in Wrot and i != hips:
            W[i] = Pw @ L0
            continue
        scale = np.linalg.norm(L0[:3, :3], axis=0)
        L = np.tile(L0, (F, 1, 1))
        if i in Wrot:
            Rl = np.swapaxes(_rotation_part(Pw[:, :3, :3]), -1, -2) @ Wrot[i]
            L[:, :3, :3] = Rl * scale[None, None, :]
        if i == hips:
            L[:, :3, 3] = np.linalg.solve(Pw, np.concatenate([hips_w, np.ones((F, 1))], 1)[..., None])[:, :3, 0]
        W[i] = Pw @ L
    return W


# ---- faces ------------------------------------------------------------------------------------------------------


def _morph_key(name: str) -> str:
    s = re.sub(r"[^a-z0-9]", "", re.split(r"[.:|]", str(name))[-1].lower())
    return re.sub(r"^(arkit|blendshape\d*|bs)", "", s)


def _arkit_keys() -> dict[str, int]:
    col = {n: i for i, n in enumerate(LIVE_LINK_COLUMNS)}
    keys = {}
    for n, i in col.items():
        keys[_morph_key(n)] = i
        for long, short in (("Left", "L"), ("Right", "R")):
            if n.endswith(long):
                keys[_morph_key(n[: -len(long)] + short)] = i
    for n in EXPR_NAMES:  # ICT spellings (browInnerUp_L: the one ARKit BrowInnerUp)
        a = arkit_name(n)
        a = a if a in col else arkit_name(n[:-2])
        if a in col:
            keys.setdefault(_morph_key(n), col[a])
    return keys


def morph_names(g: Gltf) -> dict[int, list[str]]:
    """``{node: its mesh's morph target names}`` for every node with a mesh that has morph targets (names from
    ``extras.targetNames`` of the mesh or its first primitive; unnamed targets as ``target<i>``)."""
    out = {}
    meshes = g.doc.get("meshes", [])
    for i, nd in enumerate(g.nodes):
        m = nd.get("mesh")
        if not isinstance(m, int) or not 0 <= m < len(meshes):
            continue
        prims = meshes[m].get("primitives") or [{}]
        n = len(prims[0].get("targets") or [])
        if not n:
            continue
        names = (meshes[m].get("extras") or {}).get("targetNames") or (prims[0].get("extras") or {}).get("targetNames")
        names = [str(x) for x in names] if isinstance(names, list) and len(names) == n else []
        out[i] = names or [f"target{k}" for k in range(n)]
    return out


def face_tracks(g: Gltf, arkit: np.ndarray) -> tuple[list[tuple[int, str, np.ndarray]], dict]:
    """Morph weight tracks ``[(node, "weights", [F, targets])]`` carrying ARKit weights ``[F, 52]`` onto the
    avatar (see the module docstring), and the report of which channels found a home."""
    F = len(arkit)
    names = morph_names(g)
    keys = _arkit_keys()
    meshes = g.doc.get("meshes", [])
    W = {}
    for node, ns in names.items():
        base = meshes[g.nodes[node]["mesh"]].get("weights") or [0.0] * len(ns)
        W[node] = np.tile(np.asarray(base, np.float64)[: len(ns)], (F, 1))
    found: dict[str, list[str]] = {}
    for node, ns in names.items():
        for k, n in enumerate(ns):
            c = keys.get(_morph_key(n))
            if c is not None:
                W[node][:, k] = arkit[:, c]
                found.setdefault(LIVE_LINK_COLUMNS[c], []).append(f"{g.names[node]}/{n}")
    report: dict = {"arkit_columns": len(LIVE_LINK_COLUMNS)}
    if found:
        report.update(
            via="morph targets named like ARKit",
            found_a_home=sorted(found),
            no_home=[c for c in LIVE_LINK_COLUMNS if c not in found],
        )
    else:
        presets = ((g.vrm or {}).get("expressions") or {}).get("preset") or {}
        expr = vrm_expressions(arkit)
        homed, empty = [], []
        for name in VRM_PRESETS:
            spec = presets.get(name)
            binds = [b for b in (spec or {}).get("morphTargetBinds", []) if isinstance(b, dict)]
            binds = [b for b in binds if b.get("node") in W and 0 <= int(b.get("index", -1)) < W[b["node"]].shape[1]]
            if not binds:
                (empty if spec is not None else []).append(name)
                continue
            e = expr[name] if not spec.get("isBinary") else (expr[name] > 0.5).astype(float)
            for b in binds:
                W[b["node"]][:, int(b["index"])] += e * float(b.get("weight", 1.0))
            homed.append(name)
        report.update(
            via="VRM expression presets" if homed else "none (no ARKit-named morph targets, no VRM expressions)",
            found_a_home=homed,
            no_home=[n for n in VRM_PRESETS if n not in homed],
            table="anima.export.vrm.VRM_PRESETS",
        )
    tracks = [(node, "weights", np.clip(w, 0.0, 1.0)) for node, w in W.items()] if report["found_a_home"] else []
    return tracks, report


def load_avatar(avatar: str | Path) -> tuple[Gltf, Humanoid]:
    """A user's avatar (.vrm or a skinned .glb) and its humanoid bones; refused (exit 2/4) when it is not one."""
    if Path(avatar).suffix.lower() not in (".vrm", ".glb"):
        raise InputError(f"--avatar {avatar}: expected a .vrm (VRM 1.0) or a .glb (skinned glTF binary)")
    g = read_gltf(avatar)
    if not g.doc.get("skins") and g.vrm is None:
        raise SchemaError(f"{avatar} has no skin: anima animates skinned characters (a glTF with a skin)")
    hum = find_humanoid(g)
    check_rest(g, hum)
    return g, hum


def check_rest(g: Gltf, hum: Humanoid) -> None:
    """Refuse an avatar whose humanoid bones (or a node above one) have no usable rest transform: a zero or
    absurd scale, which no pose can be solved through."""
    W = g.world()
    seen: set[int] = set()
    for name, i in hum.nodes.items():
        while i >= 0 and i not in seen:
            seen.add(i)
            M = W[i, :3, :3]
            det = abs(np.linalg.det(M)) if np.isfinite(M).all() else 0.0
            if not 1e-12 < det < 1e12:
                raise SchemaError(f"{g.path}: node {g.names[i]!r} (at or above the {name} bone) has a zero or "
                                  "absurd scale: no pose can be solved through it")  # fmt: skip
            i = int(g.parents[i])


class LiveRetarget:
    """One frame at a time (``anima live --avatar``): anima's rig pose and expression weights onto a user's
    avatar, by the same maths as :func:`run` (:func:`pose_avatar`, :func:`face_tracks`) with no look-ahead."""

    def __init__(self, avatar: str | Path, rest: np.ndarray):
        self.g, self.hum = load_avatar(avatar)
        self.rest = rest
        self.root = rest[rig.HIPS][None]

    def frame(self, local: np.ndarray, expression: np.ndarray, face: bool) -> dict:
        """``{"r": [[node, x, y, z, w], ...] local rotations, "h": [node, x, y, z] the hips' translation,
        "m": [[node, [weights]], ...] morph weights}`` of one frame (``local [65, 3, 3]``, ``expression [53]``)."""
        G, P = rig.forward(local[None], self.rest, self.root)
        posed = pose_avatar(self.g, self.hum, {"rest": self.rest, "global": G, "positions": P, "root": self.root})
        arkit = arkit_weights(expression[None], list(EXPR_NAMES)) * float(face)
        tracks, _ = face_tracks(self.g, arkit)
        hips = self.hum.nodes["Hips"]
        return {
            "r": [[int(i), *np.round(q[0], 4).tolist()] for i, q in posed["local_rot"].items()],
            "h": [int(hips), *np.round(posed["hips_t"][0], 4).tolist()],
            "m": [[int(node), np.round(w[0], 3).tolist()] for node, _, w in tracks],
        }


# ---- the command ------------------------------------------------------------------------------------------------

SEQUENCE_FILES = ("capture.npz", "gesture.npz", "motion.npz")


def find_sequence(result: str | Path) -> Path:
    """The sequence file of a result folder (capture, gesture or text2face), or ``result`` itself."""
    p = Path(result)
    if p.is_dir():
        for name in SEQUENCE_FILES:
            if (p / name).is_file():
                return p / name
        raise InputError(f"{p} holds no anima sequence ({', '.join(SEQUENCE_FILES)}): give a result folder or file")
    return p


def _is_ours(path: Path) -> bool:
    return "retarget" in ((read_gltf(path).doc.get("asset") or {}).get("extras") or {}).get("anima", {})


def _is_info(path: Path) -> bool:
    return read_json(path, "retarget info", max_bytes=10_000_000).get("kind") == "anima retarget"


def run(result: str | Path, avatar: str | Path, out: str | Path, command: str | None = None) -> dict:
    """``anima retarget RESULT --avatar AVATAR --out OUT``: the avatar with RESULT's motion (body and face) as
    its first animation, written to OUT (``.vrm`` from a ``.vrm`` avatar, or ``.glb``), and ``OUT.json``
    (what went where); returns that report."""
    seq_path = find_sequence(result)
    inputs = [result, seq_path, avatar]
    out = check_out_file(out, inputs=inputs, suffixes=(".vrm", ".glb"), ours=_is_ours, what="an avatar")
    info_path = check_out_file(
        out.with_suffix(".json"), "--out (its info)", inputs=inputs, ours=_is_info, what="a retarget info file"
    )
    g, hum = load_avatar(avatar)
    if out.suffix.lower() == ".vrm" and g.vrm is None:
        raise InputError(f"--out {out}: a .vrm needs a VRM avatar; {avatar} is a plain glTF (write a .glb)")
    seq = read_sequence(seq_path)  # the landmarks too: the face the character shows
    F = seq.n_frames
    tracks: list = []
    report: dict = {
        "kind": "anima retarget",
        "sequence": str(seq_path),
        "avatar": str(avatar),
        "frames": F,
        "fps": seq.fps,
        "convention": hum.convention,
        "bones": {n: g.names[i] for n, i in sorted(hum.nodes.items(), key=lambda x: rig.IX[x[0]])},
        "bones_not_on_avatar": [n for n in rig.NAMES if n not in hum.nodes and not rig.LEAVES[rig.IX[n]]],
    }
    if body_of(seq) is not None:
        m = character_motion(seq)
        posed = pose_avatar(g, hum, m)
        tracks += [(hum.nodes["Hips"], "translation", posed["hips_t"])]
        tracks += [(i, "rotation", q) for i, q in posed["local_rot"].items()]
        report["body"] = {
            "source": "the sequence's body on anima's rig (legs: " + m["report"]["legs"] + ")",
            "hip_height_ratio": round(posed["hip_ratio"], 4),
            "feet_raised_max_m": round(posed["raised_m"], 4),
        }
    else:
        report["body"] = "none in this sequence: the face only (the avatar keeps its rest pose)"
    arkit = arkit_weights(character_face(seq), list(EXPR_NAMES))  # what anima's character shows
    ftracks, report["face"] = face_tracks(g, arkit)
    if not seq.tracked.any():
        report["face"]["note"] = "no face in this sequence: the expressions stay at 0"
    tracks += ftracks
    if not tracks:
        raise InputError(f"{seq_path} has neither a body nor a face anima could put on {avatar}")
    report["command"] = command
    scene_extras = {"anima_fps": float(seq.fps), "anima_frame_start": 0, "anima_frame_end": int(F) - 1,
                    "anima_unit": "metre"}  # fmt: skip
    write_with_animation(
        out, g.doc, g.bin, seq.fps, tracks, name="anima", extras={"anima": {"retarget": report}},
        scene_extras=scene_extras,
    )  # fmt: skip
    record_out_file(out, "anima retarget")
    write_json(info_path, report)
    record_out_file(info_path, "anima retarget info")
    return {**report, "outputs": [str(out), str(info_path)]}
