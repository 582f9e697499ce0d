"""Binary glTF 2.0 (GLB) export of the fitted face: mesh (identity applied, metres), the 53 expression
blendshapes as morph targets (``mesh.extras.targetNames``), and an animation of their weights plus the
head rotation. glTF axes match anima's camera convention (+Y up, +Z towards the viewer)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

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
    fps: float = 30.0,
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
