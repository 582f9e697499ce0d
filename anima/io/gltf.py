"""Binary glTF 2.0 (GLB) writers: the fitted face (:func:`write_glb`: mesh with identity applied, metres, the 53
expression blendshapes as morph targets named in ``mesh.extras.targetNames``, animated with the head
rotation), and the skinned character with its motion (:func:`write_character_glb`). glTF axes match anima's
convention (+Y up, +Z towards the viewer: the character's forward)."""

from __future__ import annotations

import copy
import json
import struct
from pathlib import Path

import numpy as np

from anima.core.character import CharacterMesh, Motion, Skeleton
from anima.core.contract import TEXT_FPS
from anima.core.rotations import matrix_to_quat
from anima.io.atomic import write_bytes

CM_TO_M = 0.01
FLOAT, UINT = 5126, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


class _Buffer:
    def __init__(self):
        self.data = bytearray()
        self.views, self.accessors = [], []

    def add(self, arr: np.ndarray, comp: int, typ: str, target: int | None = None, minmax: bool = False) -> int:
        while len(self.data) % 4:
            self.data += b"\0"
        raw = np.ascontiguousarray(arr).tobytes()
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if target:
            view["target"] = target
        self.views.append(view)
        self.data += raw
        count = arr.shape[0]
        acc = {"bufferView": len(self.views) - 1, "componentType": comp, "count": int(count), "type": typ}
        if minmax:
            a2 = arr.reshape(count, -1)
            acc["min"] = [float(x) for x in a2.min(0)]
            acc["max"] = [float(x) for x in a2.max(0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def view(self, arr: np.ndarray) -> int:
        """A buffer view of ``arr``'s bytes (no accessor: a sparse accessor's indices or values)."""
        while len(self.data) % 4:
            self.data += b"\0"
        raw = np.ascontiguousarray(arr).tobytes()
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)})
        self.data += raw
        return len(self.views) - 1


def write_glb(
    path: str | Path,
    neutral_cm: np.ndarray,
    tris: np.ndarray,
    expr_deltas_cm: np.ndarray,
    expr_names: list[str],
    weights: np.ndarray | None = None,
    fps: float = TEXT_FPS,
    rotations_xyzw: np.ndarray | None = None,
) -> Path:
    """neutral ``[V, 3]`` cm, tris ``[T, 3]``, expr_deltas ``[53, V, 3]`` cm, weights ``[F, 53]`` (optional
    animation), rotations ``[F, 4]`` (x, y, z, w) head rotation per frame (optional)."""
    buf = _Buffer()
    pos = buf.add((neutral_cm * CM_TO_M).astype(np.float32), FLOAT, "VEC3", ARRAY_BUFFER, minmax=True)
    idx = buf.add(tris.astype(np.uint32).ravel(), UINT, "SCALAR", ELEMENT_ARRAY_BUFFER)
    targets = [
        {"POSITION": buf.add((d * CM_TO_M).astype(np.float32), FLOAT, "VEC3", ARRAY_BUFFER, minmax=True)}
        for d in expr_deltas_cm
    ]
    n_t = len(targets)
    gltf = {
        "asset": {"version": "2.0", "generator": "anima"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "face", "mesh": 0}],
        "meshes": [
            {
                "name": "ict_face",
                "primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "targets": targets, "mode": 4}],
                "weights": [0.0] * n_t,
                "extras": {"targetNames": list(expr_names)},
            }
        ],
    }
    if weights is not None and len(weights) > 0:
        F = len(weights)
        times = (np.arange(F, dtype=np.float32) / np.float32(fps)).astype(np.float32)
        t_acc = buf.add(times, FLOAT, "SCALAR", minmax=True)
        w_acc = buf.add(np.clip(weights, 0, 1).astype(np.float32).ravel(), FLOAT, "SCALAR")
        samplers = [{"input": t_acc, "output": w_acc, "interpolation": "LINEAR"}]
        channels = [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]
        if rotations_xyzw is not None:
            q = rotations_xyzw / np.linalg.norm(rotations_xyzw, axis=1, keepdims=True)
            r_acc = buf.add(q.astype(np.float32), FLOAT, "VEC4")
            samplers.append({"input": t_acc, "output": r_acc, "interpolation": "LINEAR"})
            channels.append({"sampler": 1, "target": {"node": 0, "path": "rotation"}})
        gltf["animations"] = [{"name": "capture", "samplers": samplers, "channels": channels}]
    return _pack(path, gltf, buf)


UBYTE, USHORT = 5121, 5123


def write_character_glb(
    path: str | Path,
    character: CharacterMesh,
    motion: Motion,
    extras: dict | None = None,
    scene_extras: dict | None = None,
    doc_extensions: dict | None = None,
) -> Path:
    """A skinned character and its motion in one animated glTF 2.0 binary (one timeline):

    * one node per joint of ``character.skeleton`` (parents first) at its rest position (its translation is the
      offset from its parent), and a skin over all of them (inverse bind matrices of that rest pose); a rig
      with rest rotations (an A-pose, rolled bones) gets them as its nodes' rest rotations and inverse bind
      matrices, and ``motion.local_quats`` are then the nodes' local rotations as glTF has them;
    * the mesh (rest pose, metres) with its normals, four joints and weights a vertex, a neutral material
      (white, multiplying ``COLOR_0``, where the character has vertex colours), and the morph targets (written
      as sparse accessors) named in ``mesh.extras.targetNames``;
    * one animation: the root's translation, the local rotations of the joints ``motion.animated`` names and
      the morph weights, LINEAR, at ``motion.fps``;
    * ``scene_extras``: the scene's ``extras`` (Blender's importer keeps them as the scene's custom
      properties: anima puts the frame rate, the frame range and the unit there);
    * ``doc_extensions``: top-level glTF extensions (e.g. ``VRMC_vrm``; listed in ``extensionsUsed``).
    """
    sk = character.skeleton
    buf = _Buffer()
    nodes, ibm = _joint_nodes(sk)
    ibm_acc = buf.add(ibm.transpose(0, 2, 1).reshape(len(nodes), 16), FLOAT, "MAT4")  # column-major
    prim, targets = _skinned_primitive(buf, character)
    mesh_node = len(nodes)
    nodes.append({"name": "character", "mesh": 0, "skin": 0})
    root = int(np.flatnonzero(np.asarray(sk.parents) < 0)[0])
    samplers, channels = _motion_channels(buf, motion, root, mesh_node, bool(len(character.morph_names)))
    if character.colors is not None:
        c8 = np.clip(np.round(np.asarray(character.colors, np.float64) * 255), 0, 255).astype(np.uint8)
        c8 = np.concatenate([c8, np.full((len(c8), 1), 255, np.uint8)], 1)
        acc = buf.add(c8, UBYTE, "VEC4", ARRAY_BUFFER)
        buf.accessors[acc]["normalized"] = True
        prim["attributes"]["COLOR_0"] = acc
    if targets:
        prim["targets"] = targets
    gltf = {
        "asset": {"version": "2.0", "generator": "anima", **({"extras": extras} if extras else {})},
        "scene": 0,
        "scenes": [
            {"name": "avatar", "nodes": [root, mesh_node], **({"extras": scene_extras} if scene_extras else {})}
        ],
        "nodes": nodes,
        "skins": [{"name": "rig", "joints": list(range(mesh_node)), "skeleton": root, "inverseBindMatrices": ibm_acc}],
        "materials": [
            {
                "name": "neutral",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.78, 0.76, 0.74, 1.0] if character.colors is None else [1.0, 1.0, 1.0, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.7,
                },
            }
        ],  # fmt: skip
        "meshes": [
            {
                "name": "character",
                "primitives": [prim],
                **({"weights": [0.0] * len(targets)} if targets else {}),
                "extras": {"targetNames": list(character.morph_names)},
            }
        ],
        "animations": [{"name": "motion", "samplers": samplers, "channels": channels}],
    }
    if doc_extensions:
        gltf["extensions"] = doc_extensions
        gltf["extensionsUsed"] = sorted(doc_extensions)
    return _pack(path, gltf, buf)


def _joint_nodes(sk: Skeleton) -> tuple[list[dict], np.ndarray]:
    """The skeleton's nodes (name, translation from the parent, rest rotation where the rig has them, children)
    and their inverse bind matrices ``[J, 4, 4]`` (float32)."""
    J = len(sk.names)
    parents = np.asarray(sk.parents)
    rest = np.asarray(sk.rest, np.float64)
    Rw = np.tile(np.eye(3), (J, 1, 1)) if sk.rest_rotations is None else np.asarray(sk.rest_rotations, np.float64)
    nodes = []
    for j in range(J):
        p = parents[j]
        Rp = Rw[p] if p >= 0 else np.eye(3)
        off = Rp.T @ (rest[j] - (rest[p] if p >= 0 else 0.0))
        nodes.append({"name": sk.names[j], "translation": [float(x) for x in off]})
        if sk.rest_rotations is not None:
            nodes[j]["rotation"] = [float(x) for x in matrix_to_quat(Rp.T @ Rw[j])]
    for j in range(J):
        kids = [int(c) for c in np.flatnonzero(parents == j)]
        if kids:
            nodes[j]["children"] = kids
    ibm = np.tile(np.eye(4), (J, 1, 1))
    ibm[:, :3, :3] = np.swapaxes(Rw, -1, -2)
    ibm[:, :3, 3] = -np.einsum("jab,jb->ja", np.swapaxes(Rw, -1, -2), rest)
    return nodes, ibm.astype(np.float32)


def _skinned_primitive(buf: _Buffer, ch: CharacterMesh) -> tuple[dict, list[dict]]:
    """The mesh's primitive (positions, normals, indices, joints and weights in ``buf``) and its morph targets
    (sparse accessors, their vertex indices sorted)."""
    V = len(ch.vertices)
    pos = buf.add(np.asarray(ch.vertices, np.float32), FLOAT, "VEC3", ARRAY_BUFFER, minmax=True)
    nrm = buf.add(np.asarray(ch.normals, np.float32), FLOAT, "VEC3", ARRAY_BUFFER)
    small = V < 65536
    idx = buf.add(
        np.asarray(ch.faces, np.uint16 if small else np.uint32).ravel(),
        USHORT if small else UINT,
        "SCALAR",
        ELEMENT_ARRAY_BUFFER,
    )
    jnt_acc = buf.add(np.asarray(ch.skin_joints, np.uint8), UBYTE, "VEC4", ARRAY_BUFFER)
    w = np.asarray(ch.skin_weights, np.float32)
    w = w / w.sum(1, keepdims=True)
    wgt_acc = buf.add(w, FLOAT, "VEC4", ARRAY_BUFFER)
    targets = []
    for vi, d in ch.morphs:
        vi = np.asarray(vi)
        order = np.argsort(vi)
        vi, d = vi[order], np.asarray(d, np.float32)[order]
        lo = np.minimum(d.min(0), 0.0) if len(d) else np.zeros(3)
        hi = np.maximum(d.max(0), 0.0) if len(d) else np.zeros(3)
        acc = {"componentType": FLOAT, "count": V, "type": "VEC3", "min": [float(x) for x in lo],
               "max": [float(x) for x in hi]}  # fmt: skip
        if len(vi):
            i_view = buf.view(vi.astype(np.uint16 if small else np.uint32))
            v_view = buf.view(d)
            acc["sparse"] = {
                "count": int(len(vi)),
                "indices": {"bufferView": i_view, "componentType": USHORT if small else UINT},
                "values": {"bufferView": v_view},
            }
        buf.accessors.append(acc)
        targets.append({"POSITION": len(buf.accessors) - 1})
    prim = {
        "attributes": {"POSITION": pos, "NORMAL": nrm, "JOINTS_0": jnt_acc, "WEIGHTS_0": wgt_acc},
        "indices": idx,
        "material": 0,
        "mode": 4,
    }
    return prim, targets


def _motion_channels(
    buf: _Buffer, motion: Motion, root: int, mesh_node: int, morphs: bool
) -> tuple[list[dict], list[dict]]:
    """The animation's samplers and channels: the ``root`` node's translation, the animated joints' rotations
    (normalised) and, with ``morphs``, the mesh node's weights (clipped to [0, 1])."""
    F = motion.n_frames
    times = (np.arange(F, dtype=np.float32) / np.float32(motion.fps)).astype(np.float32)
    t_acc = buf.add(times, FLOAT, "SCALAR", minmax=True)
    samplers = [
        {
            "input": t_acc,
            "output": buf.add(np.asarray(motion.root, np.float32), FLOAT, "VEC3"),
            "interpolation": "LINEAR",
        }
    ]
    channels = [{"sampler": 0, "target": {"node": root, "path": "translation"}}]
    q = np.asarray(motion.local_quats, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    for j in range(q.shape[1]) if motion.animated is None else np.flatnonzero(motion.animated):
        samplers.append(
            {"input": t_acc, "output": buf.add(q[:, j].astype(np.float32), FLOAT, "VEC4"), "interpolation": "LINEAR"}
        )
        channels.append({"sampler": len(samplers) - 1, "target": {"node": int(j), "path": "rotation"}})
    if morphs:
        samplers.append(
            {
                "input": t_acc,
                "output": buf.add(np.clip(motion.weights, 0, 1).astype(np.float32).ravel(), FLOAT, "SCALAR"),
                "interpolation": "LINEAR",
            }
        )
        channels.append({"sampler": len(samplers) - 1, "target": {"node": mesh_node, "path": "weights"}})
    return samplers, channels


def write_vrma(
    path: str | Path,
    skeleton: Skeleton,
    motion: Motion,
    humanoid: dict[str, int],
    expressions: dict[str, np.ndarray],
    extras: dict | None = None,
) -> Path:
    """A VRM Animation (``.vrma``: glTF 2.0 binary with ``VRMC_vrm_animation`` 1.0): the skeleton's nodes at
    their rest (world rotations identity, i.e. the T-pose rest, offsets child minus parent of ``skeleton.rest``),
    one animation of the root's translation ``[F, 3]``, the humanoid joints' local rotations (``motion``'s) and
    one node per expression whose translation's x is the weight (as the extension defines); ``humanoid``: VRM
    bone name -> joint index; ``expressions``: VRM preset name -> weights ``[F]``."""
    J = len(skeleton.names)
    parents = np.asarray(skeleton.parents)
    rest = np.asarray(skeleton.rest, np.float64)
    buf = _Buffer()
    nodes = []
    for j in range(J):
        off = rest[j] - (rest[parents[j]] if parents[j] >= 0 else 0.0)
        nodes.append({"name": skeleton.names[j], "translation": [float(x) for x in off]})
    for j in range(J):
        kids = [int(c) for c in np.flatnonzero(parents == j)]
        if kids:
            nodes[j]["children"] = kids
    root = int(np.flatnonzero(parents < 0)[0])
    F = motion.n_frames
    times = (np.arange(F, dtype=np.float32) / np.float32(motion.fps)).astype(np.float32)
    t_acc = buf.add(times, FLOAT, "SCALAR", minmax=True)
    samplers, channels = [], []

    def track(node: int, what: str, values: np.ndarray, typ: str) -> None:
        samplers.append({"input": t_acc, "output": buf.add(values.astype(np.float32), FLOAT, typ),
                         "interpolation": "LINEAR"})  # fmt: skip
        channels.append({"sampler": len(samplers) - 1, "target": {"node": int(node), "path": what}})

    track(root, "translation", np.asarray(motion.root), "VEC3")
    q = np.asarray(motion.local_quats, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    for j in humanoid.values():
        track(j, "rotation", q[:, j], "VEC4")
    preset = {}
    for name, w in expressions.items():
        nodes.append({"name": f"expression_{name}", "translation": [0.0, 0.0, 0.0]})
        k = len(nodes) - 1
        preset[name] = {"node": k}
        v = np.zeros((F, 3))
        v[:, 0] = np.clip(np.asarray(w, np.float64), 0.0, 1.0)
        track(k, "translation", v, "VEC3")
    ext = {
        "specVersion": "1.0",
        "humanoid": {"humanBones": {b: {"node": int(j)} for b, j in humanoid.items()}},
        "expressions": {"preset": preset},
    }
    gltf = {
        "asset": {"version": "2.0", "generator": "anima", **({"extras": extras} if extras else {})},
        "scene": 0,
        "scenes": [{"name": "vrma", "nodes": [root] + [preset[n]["node"] for n in preset]}],
        "nodes": nodes,
        "animations": [{"name": "anima", "samplers": samplers, "channels": channels}],
        "extensions": {"VRMC_vrm_animation": ext},
        "extensionsUsed": ["VRMC_vrm_animation"],
    }
    return _pack(path, gltf, buf)


def write_with_animation(
    path: str | Path,
    doc: dict,
    binary: bytes,
    fps: float,
    tracks: list[tuple[int, str, np.ndarray]],
    name: str = "anima",
    extras: dict | None = None,
    scene_extras: dict | None = None,
) -> Path:
    """A copy of a user's glTF (``doc`` and its embedded ``binary``, as :func:`anima.io.gltf_read.read_gltf` gives
    them) with one more animation, first in the list: ``tracks`` of (node, ``"translation" | "rotation" |
    "weights"``, values ``[F, n]``; rotations ``(x, y, z, w)``), sampled at ``fps``. Everything else of the file
    (meshes, materials, textures, extensions) is kept byte for byte; the new data is appended to the buffer. An
    animated node given by a ``matrix`` gets the same transform as translation, rotation and scale (glTF does
    not animate matrix nodes)."""
    gltf = copy.deepcopy(doc)
    buf = _Buffer()
    buf.data = bytearray(binary)
    buf.views = gltf.get("bufferViews", [])
    buf.accessors = gltf.get("accessors", [])
    F = len(tracks[0][2]) if tracks else 0
    times = (np.arange(F, dtype=np.float32) / np.float32(fps)).astype(np.float32)
    t_acc = buf.add(times, FLOAT, "SCALAR", minmax=True)
    typ = {"translation": "VEC3", "rotation": "VEC4", "scale": "VEC3", "weights": "SCALAR"}
    samplers, channels = [], []
    for node, what, values in tracks:
        nd = gltf["nodes"][node]
        if "matrix" in nd:
            M = np.asarray(nd.pop("matrix"), np.float64).reshape(4, 4).T
            sc = np.linalg.norm(M[:3, :3], axis=0)
            nd.update(
                translation=[float(x) for x in M[:3, 3]],
                rotation=[float(x) for x in matrix_to_quat(M[:3, :3] / sc)],
                scale=[float(x) for x in sc],
            )
        v = np.asarray(values, np.float32)
        v = v.ravel() if what == "weights" else v
        samplers.append({"input": t_acc, "output": buf.add(v, FLOAT, typ[what]), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": int(node), "path": what}})
    gltf["animations"] = [{"name": name, "samplers": samplers, "channels": channels}] + gltf.get("animations", [])
    if extras:
        gltf.setdefault("asset", {}).setdefault("extras", {}).update(extras)
    if scene_extras:
        scene = gltf.get("scene", 0)
        if gltf.get("scenes"):
            gltf["scenes"][scene].setdefault("extras", {}).update(scene_extras)
    gltf.pop("buffers", None)
    gltf.pop("bufferViews", None)
    gltf.pop("accessors", None)
    return _pack(path, gltf, buf)


def _pack(path, gltf: dict, buf: _Buffer) -> Path:
    while len(buf.data) % 4:
        buf.data += b"\0"
    gltf["buffers"] = [{"byteLength": len(buf.data)}]
    gltf["bufferViews"] = buf.views
    gltf["accessors"] = buf.accessors
    js = json.dumps(gltf, separators=(",", ":")).encode()
    js += b" " * ((4 - len(js) % 4) % 4)
    total = 12 + 8 + len(js) + 8 + len(buf.data)
    return write_bytes(
        path,
        struct.pack("<III", 0x46546C67, 2, total)
        + struct.pack("<II", len(js), 0x4E4F534A)
        + js
        + struct.pack("<II", len(buf.data), 0x004E4942)
        + bytes(buf.data),
    )
