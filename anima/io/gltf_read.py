"""Reading a user's glTF 2.0 binary (``.glb``) or VRM (``.vrm``, a GLB with ``VRMC_vrm``): the JSON document,
its binary chunk, every node's rest transform, the skins, the meshes' morph target names, and the VRM
humanoid map and expressions. Bounded before reading (a file over :data:`MAX_BYTES` is refused by its size;
declared buffer sizes are checked against the file). No code runs, no external file is fetched (only
embedded buffers are read: an avatar that names an external ``.bin`` or a data URI is refused)."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from anima.core.kinematics import parents_first
from anima.core.rotations import matrix_to_quat, quat_to_matrix
from anima.errors import InputError, SchemaError
from anima.io.gltf_check import check_document
from anima.io.validate import input_file, parse_json

MAX_BYTES = 200 * 2**20
_GLB, _JSON, _BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
_COMP = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_N = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


@dataclass
class Gltf:
    path: Path
    doc: dict
    bin: bytes
    names: list[str] = field(default_factory=list)
    parents: np.ndarray = field(default_factory=lambda: np.zeros(0, int))

    @property
    def nodes(self) -> list[dict]:
        return self.doc.get("nodes", [])

    @property
    def vrm(self) -> dict | None:
        return (self.doc.get("extensions") or {}).get("VRMC_vrm")

    def accessor(self, i: int) -> np.ndarray:
        """An accessor's values ``[count, n]`` (sparse accessors applied), as float64."""
        acc = self.doc["accessors"][i]
        n, count = _N[acc["type"]], int(acc["count"])
        dtype = _COMP[acc["componentType"]]
        out = np.zeros((count, n), np.float64)
        if "bufferView" in acc:
            out = self._view(acc["bufferView"], dtype, count * n, acc.get("byteOffset", 0), n).reshape(count, n)
            out = out.astype(np.float64)
            if acc.get("normalized") and np.issubdtype(dtype, np.integer):
                out /= np.iinfo(dtype).max
        sp = acc.get("sparse")
        if sp:
            k = int(sp["count"])
            idx = self._view(sp["indices"]["bufferView"], _COMP[sp["indices"]["componentType"]], k,
                             sp["indices"].get("byteOffset", 0)).astype(np.int64)  # fmt: skip
            val = self._view(sp["values"]["bufferView"], dtype, k * n, sp["values"].get("byteOffset", 0), n)
            if np.any(idx >= count) or np.any(idx < 0):
                raise SchemaError(f"{self.path}: a sparse accessor points outside its data")
            out[idx] = val.reshape(k, n)
        return out

    def _view(self, v: int, dtype, n: int, offset: int, width: int = 1) -> np.ndarray:
        """``n`` values of ``dtype`` from buffer view ``v`` (elements of ``width`` values; a stride other than
        the element's size, i.e. interleaved attributes, is refused)."""
        view = self.doc["bufferViews"][v]
        start = int(view.get("byteOffset", 0)) + int(offset)
        size = np.dtype(dtype).itemsize * n
        stride = view.get("byteStride")
        if stride and stride != np.dtype(dtype).itemsize * width:
            raise SchemaError(f"{self.path}: interleaved buffer views (byteStride {stride}) are not read")
        if view.get("buffer", 0) != 0 or start < 0 or start + size > len(self.bin):
            raise SchemaError(f"{self.path}: a buffer view lies outside the file's embedded buffer")
        return np.frombuffer(self.bin, dtype, n, start)

    def local(self, i: int) -> np.ndarray:
        """A node's rest transform (4x4) from its matrix or its translation, rotation (x, y, z, w), scale."""
        nd = self.nodes[i]
        if "matrix" in nd:
            return np.asarray(nd["matrix"], np.float64).reshape(4, 4).T
        M = np.eye(4)
        q = np.asarray(nd.get("rotation", [0, 0, 0, 1]), np.float64)
        x, y, z, w = q / max(np.linalg.norm(q), 1e-12)
        M[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
        M[:3, :3] *= np.asarray(nd.get("scale", [1, 1, 1]), np.float64)[None]
        M[:3, 3] = nd.get("translation", [0, 0, 0])
        return M

    def world(self, overrides: dict | None = None) -> np.ndarray:
        """Every node's world transform ``[N, 4, 4]`` (parents first): the rest pose, or with ``overrides``
        ``{node: {"translation" | "rotation" | "scale": value}}`` replacing parts of nodes' local transforms."""
        W = np.tile(np.eye(4), (len(self.nodes), 1, 1))
        for i in parents_first(self.parents):
            p = self.parents[i]
            L = self.local(i) if not overrides or i not in overrides else self._local_with(i, overrides[i])
            W[i] = (W[p] if p >= 0 else np.eye(4)) @ L
        return W

    def _local_with(self, i: int, parts: dict) -> np.ndarray:
        nd = dict(self.nodes[i])
        if "matrix" in nd:  # as the writer splits it
            M = np.asarray(nd.pop("matrix"), np.float64).reshape(4, 4).T
            sc = np.linalg.norm(M[:3, :3], axis=0)
            nd.update(translation=M[:3, 3], rotation=matrix_to_quat(M[:3, :3] / sc), scale=sc)
        M = np.eye(4)
        M[:3, :3] = quat_to_matrix(np.asarray(parts.get("rotation", nd.get("rotation", [0, 0, 0, 1])), np.float64))
        M[:3, :3] *= np.asarray(parts.get("scale", nd.get("scale", [1, 1, 1])), np.float64)[None]
        M[:3, 3] = parts.get("translation", nd.get("translation", [0, 0, 0]))
        return M

    def animation(self, index: int = 0) -> dict:
        """Animation ``index`` as ``{(node, path): (times [F], values [F, n])}`` (weights: ``[F, targets]``)."""
        anims = self.doc.get("animations") or []
        if not 0 <= index < len(anims):
            raise InputError(f"{self.path} has no animation {index}")
        a, out = anims[index], {}
        for ch in a.get("channels", []):
            smp = a["samplers"][ch["sampler"]]
            t = self.accessor(smp["input"])[:, 0]
            v = self.accessor(smp["output"])
            if ch["target"]["path"] == "weights":
                v = v.reshape(len(t), -1)
            out[(int(ch["target"]["node"]), ch["target"]["path"])] = (t, v)
        return out

    def posed_worlds(self, index: int = 0) -> np.ndarray:
        """World transforms ``[F, N, 4, 4]`` of every node at each sample of animation ``index`` (its channels
        sampled on the same times, as anima writes them)."""
        tracks = self.animation(index)
        F = max(len(t) for t, _ in tracks.values())
        out = np.zeros((F, len(self.nodes), 4, 4))
        for f in range(F):
            ov: dict = {}
            for (node, path), (_, v) in tracks.items():
                if path != "weights":
                    ov.setdefault(node, {})[path] = v[min(f, len(v) - 1)]
            out[f] = self.world(ov)
        return out


def read_gltf(path: str | Path) -> Gltf:
    """Read a ``.glb`` / ``.vrm`` (see the module docstring). InputError for what is not one, SchemaError for a
    glTF this reader does not take (a VRM 0.x, external buffers, a node graph with cycles)."""
    p = input_file(path, "avatar")
    size = p.stat().st_size
    if size > MAX_BYTES:
        raise InputError(f"{p} is {size / 2**20:.0f} MB: avatars of at most {MAX_BYTES // 2**20} MB are read")
    data = p.read_bytes()
    if len(data) < 20 or struct.unpack("<I", data[:4])[0] != _GLB:
        raise InputError(f"{p} is not a binary glTF (.glb / .vrm)")
    _, version, total = struct.unpack("<III", data[:12])
    if version != 2 or total > len(data):
        raise InputError(f"{p}: a glTF binary of version {version} or cut short ({len(data)} of {total} bytes)")
    js_len, js_type = struct.unpack("<II", data[12:20])
    if js_type != _JSON or 20 + js_len > len(data):
        raise InputError(f"{p}: no JSON chunk")
    doc = parse_json(data[20 : 20 + js_len], str(p))
    if not isinstance(doc, dict):
        raise InputError(f"{p}: its JSON is not a glTF document")
    if not isinstance(doc.get("extensions", {}), dict) or not isinstance(doc.get("buffers", []), list):
        raise SchemaError(f"{p}: its extensions or buffers are not of glTF's types")
    rest = data[20 + js_len :]
    binary = b""
    if len(rest) >= 8:
        b_len, b_type = struct.unpack("<II", rest[:8])
        if b_type == _BIN:
            binary = rest[8 : 8 + b_len]
    for b in doc.get("buffers", [])[:1]:
        if not isinstance(b, dict) or not isinstance(b.get("byteLength", 0), int):
            raise SchemaError(f"{p}: its buffer is not a glTF buffer")
        if "uri" in b:
            raise SchemaError(f"{p}: its buffer is an external file or a data URI; anima reads embedded buffers only")
        if int(b.get("byteLength", 0)) > len(binary):
            raise SchemaError(f"{p}: its buffer declares more bytes than the file holds")
    if (doc.get("extensions") or {}).get("VRM") is not None and (doc.get("extensions") or {}).get("VRMC_vrm") is None:
        raise SchemaError(f"{p} is a VRM 0.x file: convert it to VRM 1.0 (e.g. with UniVRM or VRoid Studio)")
    parents = np.asarray(check_document(doc, p, size), int)  # types, ranges, counts, a forest: or one line
    nodes = doc.get("nodes", [])
    return Gltf(p, doc, binary, [str(nd.get("name", f"node{i}")) for i, nd in enumerate(nodes)], parents)
