"""Binary glTF 2.0 (GLB) export of the fitted face: mesh (identity applied, metres), the 53 expression
blendshapes as morph targets (``mesh.extras.targetNames``), and an animation of their weights plus the
head rotation. glTF axes match anima's camera convention (+Y up, +Z towards the viewer)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from anima.core.contract import TEXT_FPS
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


def write_avatar_glb(
    path: str | Path,
    joint_names: list[str],
    parents: np.ndarray,
    rest_offsets_m: np.ndarray,
    root_positions_m: np.ndarray,
    local_quats_xyzw: np.ndarray,
    head_joint: int,
    head_vertices_m: np.ndarray,
    tris: np.ndarray,
    expr_deltas_m: np.ndarray,
    expr_names: list[str],
    weights: np.ndarray,
    fps: float,
    extras: dict | None = None,
) -> Path:
    """A skeleton and a head in one animated glTF 2.0 binary (one timeline):

    * one node per joint (``joint_names``, ``parents``), rest translation ``rest_offsets_m [J, 3]``, the rest
      pose's rotations identity; a skin over all of them (inverse bind matrices of the rest pose);
    * the head mesh ``head_vertices_m [V, 3]`` (in the rest pose, metres) skinned wholly to ``head_joint``,
      with ``expr_deltas_m [E, V, 3]`` as morph targets named ``expr_names`` (``mesh.extras.targetNames``);
    * one animation: the root's translation ``[F, 3]``, every joint's local rotation ``[F, J, 4]`` (x, y, z, w)
      and the morph ``weights [F, E]``, LINEAR, at ``fps``.
    """
    J = len(joint_names)
    F = len(root_positions_m)
    buf = _Buffer()
    nodes = []
    for j in range(J):
        nodes.append({"name": joint_names[j], "translation": [float(x) for x in rest_offsets_m[j]]})
    for j in range(J):
        kids = [int(c) for c in np.flatnonzero(np.asarray(parents) == j)]
        if kids:
            nodes[j]["children"] = kids
    rest = np.zeros((J, 3))
    for j in range(J):
        rest[j] = (rest[parents[j]] if parents[j] >= 0 else 0.0) + rest_offsets_m[j]
    ibm = np.tile(np.eye(4, dtype=np.float32), (J, 1, 1))
    ibm[:, :3, 3] = -rest
    ibm_acc = buf.add(ibm.transpose(0, 2, 1).reshape(J, 16), FLOAT, "MAT4")  # column-major
    pos = buf.add(np.asarray(head_vertices_m, np.float32), FLOAT, "VEC3", ARRAY_BUFFER, minmax=True)
    idx = buf.add(np.asarray(tris, np.uint32).ravel(), UINT, "SCALAR", ELEMENT_ARRAY_BUFFER)
    V = len(head_vertices_m)
    jnt = np.zeros((V, 4), np.uint16 if J > 255 else np.uint8)
    jnt[:, 0] = head_joint
    jnt_acc = buf.add(jnt, USHORT if J > 255 else UBYTE, "VEC4", ARRAY_BUFFER)
    wgt = np.zeros((V, 4), np.float32)
    wgt[:, 0] = 1.0
    wgt_acc = buf.add(wgt, FLOAT, "VEC4", ARRAY_BUFFER)
    targets = [
        {"POSITION": buf.add(np.asarray(d, np.float32), FLOAT, "VEC3", ARRAY_BUFFER, minmax=True)}
        for d in expr_deltas_m
    ]
    mesh_node = len(nodes)
    nodes.append({"name": "head_mesh", "mesh": 0, "skin": 0})
    root = int(np.flatnonzero(np.asarray(parents) < 0)[0])
    times = (np.arange(F, dtype=np.float32) / np.float32(fps)).astype(np.float32)
    t_acc = buf.add(times, FLOAT, "SCALAR", minmax=True)
    samplers = [
        {
            "input": t_acc,
            "output": buf.add(np.asarray(root_positions_m, np.float32), FLOAT, "VEC3"),
            "interpolation": "LINEAR",
        }
    ]
    channels = [{"sampler": 0, "target": {"node": root, "path": "translation"}}]
    q = np.asarray(local_quats_xyzw, np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    for j in range(J):
        samplers.append(
            {"input": t_acc, "output": buf.add(q[:, j].astype(np.float32), FLOAT, "VEC4"), "interpolation": "LINEAR"}
        )
        channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "rotation"}})
    samplers.append(
        {
            "input": t_acc,
            "output": buf.add(np.clip(weights, 0, 1).astype(np.float32).ravel(), FLOAT, "SCALAR"),
            "interpolation": "LINEAR",
        }
    )
    channels.append({"sampler": len(samplers) - 1, "target": {"node": mesh_node, "path": "weights"}})
    gltf = {
        "asset": {"version": "2.0", "generator": "anima", **({"extras": extras} if extras else {})},
        "scene": 0,
        "scenes": [{"name": "avatar", "nodes": [root, mesh_node]}],
        "nodes": nodes,
        "skins": [{"name": "rig", "joints": list(range(J)), "skeleton": root, "inverseBindMatrices": ibm_acc}],
        "meshes": [
            {
                "name": "ict_head",
                "primitives": [
                    {
                        "attributes": {"POSITION": pos, "JOINTS_0": jnt_acc, "WEIGHTS_0": wgt_acc},
                        "indices": idx,
                        "targets": targets,
                        "mode": 4,
                    }
                ],
                "weights": [0.0] * len(targets),
                "extras": {"targetNames": list(expr_names)},
            }
        ],
        "animations": [{"name": "motion", "samplers": samplers, "channels": channels}],
    }
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
