"""The bounded check of a user's glTF / VRM document before anima reads it (``anima.io.gltf_read``): every
field anima reads is of its type and in range, counts are bounded by fixed limits and by the file's size, and
the node hierarchy is a forest (no cycle, no node with two parents, no self-parent), walked iteratively in
linear time. A document that fails is refused with one line naming the field (:class:`SchemaError`); nothing
anima reads later can meet a wrong type, so a hostile avatar ends in a refusal, never an internal error.

What is checked (the parts anima reads; everything else is carried through untouched):

* top level: ``nodes``, ``meshes``, ``skins``, ``accessors``, ``bufferViews``, ``buffers``, ``animations``,
  ``scenes`` lists of objects; ``asset``, ``extensions``, ``extras`` objects;
* nodes: ``children`` (node indices), ``mesh`` / ``skin`` (indices), ``matrix`` (16 finite numbers),
  ``translation`` (3), ``rotation`` (4, not all zero), ``scale`` (3 finite);
* meshes: ``primitives`` (objects), their ``targets`` (objects), ``weights`` (finite numbers);
* skins: ``joints`` (node indices), ``inverseBindMatrices`` and ``skeleton`` (indices);
* accessors and buffer views: types, component types, counts and offsets as integers within the file;
* animations: samplers' accessors and channels' nodes and paths;
* VRM 1.0: ``humanoid.humanBones`` an object of ``{node}`` objects, expression presets' binds.
"""

from __future__ import annotations

import math

from anima.errors import SchemaError

MAX_NODES = 20_000
"""Nodes of an avatar anima reads: VRoid and Ready Player Me avatars have hundreds, game characters a few
thousand; a node bomb (hundreds of thousands in a few MB) is refused by count before any walk."""
MAX_DEPTH = 1_000
"""The deepest node chain: a skeleton is tens of bones deep; a 100,000-node chain is refused."""
MAX_ITEMS = 100_000  # meshes, accessors, buffer views, skins, animations, channels, ...
_BYTES_PER_ITEM = 2  # the smallest JSON of one array element ("{}" or "0,"): counts bounded by the file's size
_COMPONENTS = {5120, 5121, 5122, 5123, 5125, 5126}
_TYPES = {"SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"}
_PATHS = {"translation", "rotation", "scale", "weights"}


def _int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _num(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


class _Check:
    def __init__(self, path, size: int):
        self.path, self.size = path, size

    def fail(self, what: str):
        raise SchemaError(f"{self.path}: {what}")

    def items(self, doc: dict, key: str, limit: int = MAX_ITEMS) -> list:
        v = doc.get(key, [])
        if not isinstance(v, list):
            self.fail(f"its {key} are not a list")
        if len(v) > min(limit, self.size // _BYTES_PER_ITEM + 1):
            self.fail(f"{len(v):,} {key}; anima reads at most {min(limit, self.size // _BYTES_PER_ITEM + 1):,}")
        for i, x in enumerate(v):
            if not isinstance(x, dict):
                self.fail(f"{key}[{i}] is not an object")
        return v

    def obj(self, d: dict, key: str, where: str) -> dict:
        v = d.get(key, {})
        if v is None:
            return {}
        if not isinstance(v, dict):
            self.fail(f"its {key} is not an object" if where == "the document" else f"{where}.{key} is not an object")
        return v

    def index(self, d: dict, key: str, n: int, where: str, required: bool = False) -> None:
        if key not in d:
            if required:
                self.fail(f"{where} has no {key}")
            return
        if not _int(d[key]) or not 0 <= d[key] < n:
            self.fail(f"{where}.{key} is {str(d[key])[:40]!r}, not an index below {n}")

    def numbers(self, d: dict, key: str, count: int | None, where: str) -> None:
        if key not in d:
            return
        v = d[key]
        if not isinstance(v, list) or (count is not None and len(v) != count) or not all(_num(x) for x in v):
            self.fail(f"{where}.{key} is not {count or 'a list of'} finite numbers")

    def indices(self, d: dict, key: str, n: int, where: str) -> list:
        v = d.get(key, [])
        if not isinstance(v, list) or not all(_int(x) and 0 <= x < n for x in v):
            self.fail(f"{where}.{key} holds something that is not an index below {n}")
        return v


def check_document(doc: dict, path, size: int) -> list[int]:
    """Check ``doc`` (see the module docstring); returns every node's parent (-1 for a root)."""
    c = _Check(path, size)
    for key in ("asset", "extensions", "extras"):
        c.obj(doc, key, "the document")
    nodes = c.items(doc, "nodes", MAX_NODES)
    meshes, skins = c.items(doc, "meshes"), c.items(doc, "skins")
    accessors, views = c.items(doc, "accessors"), c.items(doc, "bufferViews")
    c.items(doc, "buffers", 1_000)
    c.items(doc, "scenes", 1_000)
    N = len(nodes)
    parents = [-1] * N
    for i, nd in enumerate(nodes):
        w = f"nodes[{i}]"
        for k in ("mesh", "skin"):
            c.index(nd, k, len(meshes) if k == "mesh" else len(skins), w)
        for k, n in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            c.numbers(nd, k, n, w)
        if "rotation" in nd and not any(nd["rotation"]):
            c.fail(f"{w}.rotation is all zero, not a rotation")
        if "name" in nd and not isinstance(nd["name"], str):
            c.fail(f"{w}.name is not text")
        for ch in c.indices(nd, "children", N, w):
            if ch == i or parents[ch] >= 0:
                c.fail(f"{w} has child {ch}, which is itself or already has a parent")
            parents[ch] = i
    _check_forest(c, parents)
    for i, m in enumerate(meshes):
        prims = m.get("primitives", [])
        if not isinstance(prims, list) or not all(isinstance(p, dict) for p in prims):
            c.fail(f"meshes[{i}].primitives are not a list of objects")
        for j, p in enumerate(prims):
            t = p.get("targets", [])
            if not isinstance(t, list) or not all(isinstance(x, dict) for x in t):
                c.fail(f"meshes[{i}].primitives[{j}].targets are not a list of objects")
            c.obj(p, "extras", f"meshes[{i}].primitives[{j}]")
        c.numbers(m, "weights", None, f"meshes[{i}]")
        c.obj(m, "extras", f"meshes[{i}]")
    for i, s in enumerate(skins):
        c.indices(s, "joints", N, f"skins[{i}]")
        c.index(s, "inverseBindMatrices", len(accessors), f"skins[{i}]")
        c.index(s, "skeleton", N, f"skins[{i}]")
    for i, v in enumerate(views):
        for k in ("buffer", "byteOffset", "byteLength", "byteStride"):
            if k in v and (not _int(v[k]) or not 0 <= v[k] <= size):
                c.fail(f"bufferViews[{i}].{k} is not a size within the file")
    for i, a in enumerate(accessors):
        w = f"accessors[{i}]"
        if a.get("type") not in _TYPES or a.get("componentType") not in _COMPONENTS:
            c.fail(f"{w} has no valid type / componentType")
        if not _int(a.get("count")) or not 0 <= a["count"] <= size:
            c.fail(f"{w}.count is not a count within the file")
        if "byteOffset" in a and (not _int(a["byteOffset"]) or not 0 <= a["byteOffset"] <= size):
            c.fail(f"{w}.byteOffset is not an offset within the file")
        c.index(a, "bufferView", len(views), w)
        if "sparse" in a:
            sp = a["sparse"]
            if not isinstance(sp, dict) or not _int(sp.get("count")) or not 0 <= sp["count"] <= size:
                c.fail(f"{w}.sparse is not a sparse accessor")
            for k in ("indices", "values"):
                part = sp.get(k)
                if not isinstance(part, dict):
                    c.fail(f"{w}.sparse.{k} is not an object")
                c.index(part, "bufferView", len(views), f"{w}.sparse.{k}", required=True)
                if k == "indices" and part.get("componentType") not in _COMPONENTS:
                    c.fail(f"{w}.sparse.indices has no valid componentType")
    for i, an in enumerate(c.items(doc, "animations")):
        samplers = an.get("samplers", [])
        if not isinstance(samplers, list) or not all(isinstance(s, dict) for s in samplers):
            c.fail(f"animations[{i}].samplers are not a list of objects")
        for j, s in enumerate(samplers):
            c.index(s, "input", len(accessors), f"animations[{i}].samplers[{j}]", required=True)
            c.index(s, "output", len(accessors), f"animations[{i}].samplers[{j}]", required=True)
        chans = an.get("channels", [])
        if not isinstance(chans, list) or not all(isinstance(s, dict) for s in chans):
            c.fail(f"animations[{i}].channels are not a list of objects")
        for j, ch in enumerate(chans):
            w = f"animations[{i}].channels[{j}]"
            c.index(ch, "sampler", len(samplers), w, required=True)
            t = ch.get("target")
            if not isinstance(t, dict) or t.get("path") not in _PATHS:
                c.fail(f"{w}.target is not a node path")
            c.index(t, "node", N, f"{w}.target", required=True)
    _check_vrm(c, c.obj(c.obj(doc, "extensions", "the document"), "VRMC_vrm", "extensions"), N)
    return parents


def _check_forest(c: _Check, parents: list[int]) -> None:
    """Every node reaches a root within :data:`MAX_DEPTH` steps (no cycle), in one pass with memoised depths."""
    depth = [-1] * len(parents)
    for i in range(len(parents)):
        chain, j = [], i
        while j >= 0 and depth[j] < 0:
            chain.append(j)
            if len(chain) > MAX_DEPTH:
                c.fail(f"its node hierarchy is deeper than {MAX_DEPTH} (or has a cycle)")
            j = parents[j]
        d = depth[j] if j >= 0 else -1
        for k in reversed(chain):
            d += 1
            depth[k] = d
        if d > MAX_DEPTH:
            c.fail(f"its node hierarchy is deeper than {MAX_DEPTH}")


def _check_vrm(c: _Check, vrm: dict, n_nodes: int) -> None:
    if not vrm:
        return
    hum = c.obj(vrm, "humanoid", "VRMC_vrm")
    bones = c.obj(hum, "humanBones", "VRMC_vrm.humanoid")
    for name, spec in bones.items():
        if not isinstance(spec, dict):
            c.fail(f"VRMC_vrm.humanoid.humanBones.{name} is not an object")
        c.index(spec, "node", n_nodes, f"VRMC_vrm.humanoid.humanBones.{name}", required=True)
    presets = c.obj(c.obj(vrm, "expressions", "VRMC_vrm"), "preset", "VRMC_vrm.expressions")
    for name, spec in presets.items():
        w = f"VRMC_vrm.expressions.preset.{name}"
        if not isinstance(spec, dict):
            c.fail(f"{w} is not an object")
        binds = spec.get("morphTargetBinds", [])
        if not isinstance(binds, list) or not all(isinstance(b, dict) for b in binds):
            c.fail(f"{w}.morphTargetBinds are not a list of objects")
        for k, b in enumerate(binds):
            c.index(b, "node", n_nodes, f"{w}.morphTargetBinds[{k}]", required=True)
            if not _int(b.get("index")) or b["index"] < 0:
                c.fail(f"{w}.morphTargetBinds[{k}].index is not an index")
            if "weight" in b and not _num(b["weight"]):
                c.fail(f"{w}.morphTargetBinds[{k}].weight is not a finite number")
        if "isBinary" in spec and not isinstance(spec["isBinary"], bool):
            c.fail(f"{w}.isBinary is not true or false")
