"""Hostile avatars for the bad-input matrix and the memory benchmark: a real VRM 1.0 (the shared data's humanoid
test file) with one field broken at a time, node bombs (hundreds of thousands of nodes in a few MB, one long
chain), cycles and self-parents. Every one must be refused in one line (exit 2 or 4) or retargeted, within
seconds and bounded memory, by ``retarget``, ``view --avatar`` and ``live --avatar`` alike. And a rig anima never
wrote (:func:`unseen_rig`: random bone axes, facing -z), which must play as well as anima's own."""

from __future__ import annotations

import copy
import json
import struct
from pathlib import Path

import numpy as np

from anima.io.assets import asset

BASE = "avatars/VRMC_materials_mtoon_UV_Animation_Test.vrm"


def read_glb(path: Path) -> tuple[dict, bytes]:
    data = path.read_bytes()
    n = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20 : 20 + n])
    rest = data[20 + n :]
    binary = rest[8 : 8 + struct.unpack("<I", rest[:4])[0]] if len(rest) >= 8 else b""
    return doc, binary


def pack(path: Path, doc, binary: bytes, raw: str | None = None) -> Path:
    """A GLB of ``doc`` (or of the JSON text ``raw``, for what ``json.dumps`` cannot write: 1e999, NaN)."""
    js = (raw if raw is not None else json.dumps(doc, separators=(",", ":"))).encode()
    js += b" " * ((4 - len(js) % 4) % 4)
    b = binary + bytes((4 - len(binary) % 4) % 4)
    total = 12 + 8 + len(js) + 8 + len(b)
    path.write_bytes(
        struct.pack("<III", 0x46546C67, 2, total) + struct.pack("<II", len(js), 0x4E4F534A) + js
        + struct.pack("<II", len(b), 0x004E4942) + b
    )  # fmt: skip
    return path


def _hips(doc: dict) -> int:
    return doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["hips"]["node"]


def _edits(doc: dict) -> dict:
    """name -> a function that breaks one field of a copy of ``doc`` (returns the doc, or raw JSON text)."""
    hips = _hips(doc)
    kid = next(i for i, nd in enumerate(doc["nodes"]) if nd.get("children"))
    ch = doc["nodes"][kid]["children"][0]
    N = len(doc["nodes"])

    def node(i, **kv):
        def f(d):
            d["nodes"][i].update(kv)
            return d

        return f

    def set_(path, value):
        def f(d):
            x = d
            for k in path[:-1]:
                x = x[k]
            x[path[-1]] = value
            return d

        return f

    def raw(key, text):  # the hips' field written as raw JSON text
        def f(d):
            d["nodes"][hips][key] = "@RAW@"
            return json.dumps(d, separators=(",", ":")).replace('"@RAW@"', text)

        return f

    bones = ["extensions", "VRMC_vrm", "humanoid", "humanBones"]
    return {
        "children true": node(kid, children=True),
        "children of text": node(kid, children=["1"]),
        "child out of range": node(kid, children=[N + 5]),
        "child negative": node(kid, children=[-1]),
        "self parent": node(kid, children=[kid]),
        "two parents": node(next(i for i in range(N - 1, -1, -1) if i not in (kid, ch)), children=[ch]),
        "cycle": node(ch, children=[*doc["nodes"][ch].get("children", []), kid]),
        "node a number": lambda d: (d["nodes"].__setitem__(hips, 7), d)[1],
        "node a list": lambda d: (d["nodes"].__setitem__(hips, [1, 2]), d)[1],
        "nodes an object": set_(["nodes"], {"0": {}}),
        "rotation text": node(hips, rotation="abcd"),
        "rotation zero": node(hips, rotation=[0, 0, 0, 0]),
        "rotation 3 numbers": node(hips, rotation=[0, 0, 1]),
        "matrix 3 numbers": node(hips, matrix=[1, 0, 0]),
        "matrix of text": node(hips, matrix=["a"] * 16),
        "translation null": node(hips, translation=None),
        "scale 0": node(hips, scale=[0, 0, 0]),
        "scale 1e999": raw("scale", "[1e999,1,1]"),
        "translation NaN": raw("translation", "[NaN,0,0]"),
        "rotation -Infinity": raw("rotation", "[-Infinity,0,0,1]"),
        "name a number": node(hips, name=12),
        "mesh out of range": node(hips, mesh=10_000),
        "skin negative": node(hips, skin=-1),
        "mesh true": node(hips, mesh=True),
        "humanBones a list": set_(bones, [{"node": hips}]),
        "humanBones.hips a number": set_([*bones, "hips"], 5),
        "humanBones.hips.node text": set_([*bones, "hips"], {"node": "0"}),
        "humanBones.hips.node out of range": set_([*bones, "hips"], {"node": N + 100}),
        "humanoid a string": set_(["extensions", "VRMC_vrm", "humanoid"], "hips"),
        "VRMC_vrm a list": set_(["extensions", "VRMC_vrm"], [1]),
        "extensions a list": set_(["extensions"], []),
        "expressions preset a list": set_(["extensions", "VRMC_vrm", "expressions"], {"preset": [1]}),
        "expression binds of text": set_(
            ["extensions", "VRMC_vrm", "expressions"], {"preset": {"happy": {"morphTargetBinds": "x"}}}
        ),
        "expression bind index text": set_(
            ["extensions", "VRMC_vrm", "expressions"],
            {"preset": {"happy": {"morphTargetBinds": [{"node": hips, "index": "x", "weight": 1}]}}},
        ),
        "skins with joints out of range": set_(["skins"], [{"joints": [0, N + 7]}]),
        "skins a dict": set_(["skins"], {"joints": [0]}),
        "meshes primitives null": lambda d: (d["meshes"][0].__setitem__("primitives", None), d)[1],
        "mesh targets text": lambda d: (d["meshes"][0]["primitives"][0].__setitem__("targets", "x"), d)[1],
        "mesh weights text": lambda d: (d["meshes"][0].__setitem__("weights", ["a"]), d)[1],
        "accessor count negative": lambda d: (d["accessors"][0].__setitem__("count", -1), d)[1],
        "accessor type bogus": lambda d: (d["accessors"][0].__setitem__("type", "VEC9"), d)[1],
        "bufferView offset huge": lambda d: (d["bufferViews"][0].__setitem__("byteOffset", 10**12), d)[1],
        "animation path bogus": set_(
            ["animations"],
            [
                {
                    "samplers": [{"input": 0, "output": 0}],
                    "channels": [{"sampler": 0, "target": {"node": hips, "path": "colour"}}],
                }
            ],
        ),
        "animation sampler out of range": set_(
            ["animations"], [{"samplers": [], "channels": [{"sampler": 3, "target": {"node": 0, "path": "rotation"}}]}]
        ),
        "buffers byteLength text": lambda d: (d["buffers"][0].__setitem__("byteLength", "big"), d)[1],
        "asset a list": set_(["asset"], []),
    }


def _bomb(doc: dict, binary: bytes, n: int, chain: bool) -> tuple[dict, bytes]:
    """``doc`` with ``n`` extra nodes: under one parent (flat), or one chain ``n`` deep, hung under the hips."""
    d = copy.deepcopy(doc)
    first = len(d["nodes"])
    d["nodes"] += [{"children": [first + k + 1]} if chain and k < n - 1 else {} for k in range(n)]
    hips = _hips(d)
    kids = [first] if chain else list(range(first, first + n))
    d["nodes"][hips]["children"] = d["nodes"][hips].get("children", []) + kids
    return d, binary


def make(folder: Path) -> dict[str, Path]:
    """Write every hostile avatar into ``folder``; ``{name: path}``."""
    folder.mkdir(parents=True, exist_ok=True)
    doc, binary = read_glb(asset(BASE))
    out = {}
    for k, (name, edit) in enumerate(_edits(doc).items()):
        r = edit(copy.deepcopy(doc))
        out[name] = pack(folder / f"hostile_{k:02d}.vrm", r, binary, r if isinstance(r, str) else None)
    for name, n, chain in (("300k-node bomb", 300_000, False), ("100k-node chain", 100_000, True),
                           ("19k-node chain", 19_000, True), ("19k flat nodes", 19_000, False)):  # fmt: skip
        d, b = _bomb(doc, binary, n, chain)
        out[name] = pack(folder / f"bomb_{n}_{'chain' if chain else 'flat'}.vrm", d, b)
    return out


def unseen_rig(path, seed=3, arkit=False):
    """A rig anima never wrote: the character in an A-pose, every bone's axes turned at random (so its local
    rotations mean nothing to anima's rig), the whole body facing -z, names ``mixamorig1_*``; its morph targets
    named ``shape0``... (none found by name), or ``arkit``: as ARKit names them."""
    from anima.core import rig
    from anima.core.character import CharacterMesh, Motion, Skeleton
    from anima.core.contract import EXPR_NAMES
    from anima.core.rotations import matrix_to_quat, rotvec_to_matrix
    from anima.export.vrm import character_avatar
    from anima.facemodel.character import load_character
    from anima.io.gltf import write_character_glb
    from anima.render.raster import vertex_normals

    ch = load_character()
    a = character_avatar("mean", "A")
    rng = np.random.default_rng(seed)
    turn = rotvec_to_matrix(np.array([0.0, np.pi, 0.0]))
    R = turn @ a["rest_rot"] @ rotvec_to_matrix(rng.normal(size=(rig.N_RIG, 3)))
    J, V = a["rest"] @ turn.T, a["vertices"] @ turn.T
    par = np.maximum(rig.PARENTS_RIG, 0)
    local = np.einsum("jba,jbc->jac", R[par], R)
    local[rig.HIPS] = R[rig.HIPS]
    morphs = list(EXPR_NAMES) if arkit else [f"shape{k}" for k in range(len(ch.morph_index))]
    character = CharacterMesh(
        Skeleton(["mixamorig1_" + n for n in rig.NAMES], rig.PARENTS_RIG, J, R), V, vertex_normals(V, ch.faces),
        ch.faces, ch.skin_joints, ch.skin_weights, list(zip(ch.morph_index, ch.morph_delta)), morphs,
    )  # fmt: skip
    weights = np.zeros((1, len(ch.morph_index)))
    motion = Motion(J[rig.HIPS][None], matrix_to_quat(local)[None], 30.0, weights, ~rig.LEAVES)
    return write_character_glb(path, character, motion)


def with_mtoon_outline(src: Path, dst: Path) -> Path:
    """VRM ``src`` with its first material drawn by MToon (``VRMC_materials_mtoon``) with an outline, as VRoid's
    avatars are: three-vrm then draws the mesh with two materials (the surface, the outline) over two groups."""
    doc, binary = read_glb(Path(src))
    doc["extensionsUsed"] = [*doc.get("extensionsUsed", []), "VRMC_materials_mtoon"]
    doc["materials"][0].setdefault("extensions", {})["VRMC_materials_mtoon"] = {
        "specVersion": "1.0", "shadeColorFactor": [0.8, 0.7, 0.7], "outlineWidthMode": "worldCoordinates",
        "outlineWidthFactor": 0.002, "outlineColorFactor": [0.1, 0.05, 0.05], "outlineLightingMixFactor": 0.0,
    }  # fmt: skip
    return pack(Path(dst), doc, binary)


_COMPONENTS = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}


def _accessor(doc: dict, binary: bytes, i: int) -> np.ndarray:
    """A tightly packed accessor's values ``[count, width]``, sparse ones too (what anima's writer makes)."""
    a = doc["accessors"][i]
    dtype, width = np.dtype(_COMPONENTS[a["componentType"]]), _WIDTH[a["type"]]

    def read(view: int, dt, n: int, offset: int = 0) -> np.ndarray:
        start = doc["bufferViews"][view].get("byteOffset", 0) + offset
        return np.frombuffer(binary, dt, n, start)

    if "bufferView" in a:
        out = read(a["bufferView"], dtype, a["count"] * width, a.get("byteOffset", 0)).reshape(-1, width).copy()
    else:
        out = np.zeros((a["count"], width), dtype)
    if "sparse" in a:
        sp = a["sparse"]
        idx = read(sp["indices"]["bufferView"], _COMPONENTS[sp["indices"]["componentType"]], sp["count"])
        out[idx] = read(sp["values"]["bufferView"], dtype, sp["count"] * width).reshape(-1, width)
    return out


def _append(doc: dict, binary: bytearray, values: np.ndarray, kind: str, target: int | None = None) -> int:
    """``values`` (float32 ``[n, 3]`` or uint32 ``[n]``) as a new accessor at the end of ``binary``."""
    data = np.ascontiguousarray(values).tobytes()
    binary.extend(bytes((4 - len(binary) % 4) % 4))
    view = {"buffer": 0, "byteOffset": len(binary), "byteLength": len(data), **({"target": target} if target else {})}
    doc["bufferViews"].append(view)
    binary.extend(data)
    acc = {"bufferView": len(doc["bufferViews"]) - 1, "count": len(values), "type": kind,
           "componentType": 5125 if values.dtype == np.uint32 else 5126}  # fmt: skip
    if kind == "VEC3":
        acc |= {"min": values.min(0).tolist(), "max": values.max(0).tolist()}
    doc["accessors"].append(acc)
    return len(doc["accessors"]) - 1


def _head_triangles(doc: dict, binary: bytes, node: int, prim: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(triangles [T, 3], whether the head bone or a bone under it moves all three of its vertices most [T])``."""
    tris = _accessor(doc, binary, prim["indices"]).reshape(-1, 3)
    joints = _accessor(doc, binary, prim["attributes"]["JOINTS_0"])
    weights = _accessor(doc, binary, prim["attributes"]["WEIGHTS_0"])
    skin = doc["skins"][doc["nodes"][node]["skin"]]["joints"]
    under = [doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["head"]["node"]]
    for n in under:
        under += doc["nodes"][n].get("children", [])
    main = np.asarray(skin)[joints[np.arange(len(joints)), np.argmax(weights, 1)]]
    return tris, np.isin(main, under)[tris].all(1)


def split_like_vroid(src: Path, dst: Path) -> Path:
    """VRM ``src`` (one skinned mesh) made of separate meshes on the same skin, as VRoid's avatars are: a face mesh
    (the triangles the head bone or a bone under it moves most) of two primitives with two materials (the skin; the
    eyes, brows, lips, lashes and teeth), both carrying the morph targets the expressions bind, and a body mesh
    (every other triangle, the neck's too) with none."""
    doc, binary = read_glb(Path(src))
    node = next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n)
    mesh = doc["meshes"][doc["nodes"][node]["mesh"]]
    (prim,) = mesh["primitives"]
    tris, head = _head_triangles(doc, binary, node, prim)
    colour = _accessor(doc, binary, prim["attributes"]["COLOR_0"])[:, :3]
    values, counts = np.unique(colour, axis=0, return_counts=True)
    skin_coloured = np.all(colour == values[np.argmax(counts)], 1)[tris].all(1)
    binary = bytearray(binary)

    def indices(t: np.ndarray) -> int:
        return _append(doc, binary, t.astype(np.uint32).ravel(), "SCALAR", 34963)

    doc["materials"].append({**doc["materials"][0], "name": "face parts"})
    face_parts = len(doc["materials"]) - 1
    mesh["name"] = "Face"
    mesh["primitives"] = [
        {**prim, "indices": indices(tris[head & skin_coloured])},
        {**prim, "indices": indices(tris[head & ~skin_coloured]), "material": face_parts},
    ]
    body = {k: v for k, v in prim.items() if k != "targets"}
    doc["meshes"].append({"name": "Body", "primitives": [{**body, "indices": indices(tris[~head])}]})
    doc["nodes"].append({"name": "Body", "mesh": len(doc["meshes"]) - 1, "skin": doc["nodes"][node]["skin"]})
    doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    doc["buffers"][0]["byteLength"] = len(binary)
    return pack(Path(dst), doc, bytes(binary))


def rigid_head(src: Path, dst: Path) -> Path:
    """VRM ``src`` (one skinned mesh, its rest unturned) with its head as a rigid mesh, a child of the head bone
    (no skin), carrying the morph targets the expressions bind, as low-poly and robot avatars are built; the body
    stays skinned (with its neck) and has none."""
    doc, binary = read_glb(Path(src))
    node = next(i for i, n in enumerate(doc["nodes"]) if "mesh" in n)
    mesh = doc["meshes"][doc["nodes"][node]["mesh"]]
    (prim,) = mesh["primitives"]
    tris, head = _head_triangles(doc, binary, node, prim)
    bone = doc["extensions"]["VRMC_vrm"]["humanoid"]["humanBones"]["head"]["node"]
    parent = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    at, n = np.zeros(3), bone
    while n is not None:  # the head bone's place at rest (every rotation of this rest is the identity)
        assert doc["nodes"][n].get("rotation", [0, 0, 0, 1]) == [0, 0, 0, 1], "a rest with turned bones"
        at += doc["nodes"][n].get("translation", [0, 0, 0])
        n = parent.get(n)
    used = np.unique(tris[head])
    local = np.full(int(tris.max()) + 1, -1)
    local[used] = np.arange(len(used))
    binary = bytearray(binary)
    attr = lambda name: _accessor(doc, binary, prim["attributes"][name])[used]
    rigid = {
        "attributes": {
            "POSITION": _append(doc, binary, (attr("POSITION") - at).astype(np.float32), "VEC3", 34962),
            "NORMAL": _append(doc, binary, attr("NORMAL").astype(np.float32), "VEC3", 34962),
            "COLOR_0": _append(doc, binary, (attr("COLOR_0") / 255.0).astype(np.float32), "VEC4", 34962),
        },
        "indices": _append(doc, binary, local[tris[head]].astype(np.uint32).ravel(), "SCALAR", 34963),
        "targets": [
            {"POSITION": _append(doc, binary, _accessor(doc, binary, t["POSITION"])[used], "VEC3")}
            for t in prim["targets"]
        ],
        "material": prim["material"],
    }
    doc["meshes"].append({"name": "Head", "primitives": [rigid], "extras": mesh.get("extras", {})})
    doc["nodes"].append({"name": "Head mesh", "mesh": len(doc["meshes"]) - 1})
    doc["nodes"][bone].setdefault("children", []).append(len(doc["nodes"]) - 1)
    mesh["primitives"] = [{**{k: v for k, v in prim.items() if k != "targets"}, "indices": _append(
        doc, binary, tris[~head].astype(np.uint32).ravel(), "SCALAR", 34963)}]  # fmt: skip
    mesh.pop("extras", None)
    mesh.pop("weights", None)
    for e in doc["extensions"]["VRMC_vrm"]["expressions"]["preset"].values():
        for b in e.get("morphTargetBinds", []):
            b["node"] = len(doc["nodes"]) - 1
    doc["buffers"][0]["byteLength"] = len(binary)
    return pack(Path(dst), doc, bytes(binary))
