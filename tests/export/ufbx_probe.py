"""Read an FBX file with ufbx (as Unity's and Unreal's importers read it) in a process of its own, and write what
the tests compare as plain arrays to an ``.npz``.

ufbx's Python bindings (0.0.5) keep one Python object for each part of a scene they have handed out and hand
the same one out again (``s.anim_stacks[0] is s.anim_stacks[0]``), but an object's release does not forget it:
read the same part again after its object went (``s.anim_stacks[0].time_begin``, then ``.time_end``) and the
interpreter reads freed memory and, depending on what was allocated there since, dies of a segmentation fault
(it once took the whole test session with it). Here every object read is held (``hold``) and never released:
the collector is off, the lists are copied through their buffers, and the process leaves with ``os._exit``
once the file is written.

    python ufbx_probe.py FILE.fbx OUT.npz TIMES_JSON NODE_NAMES_JSON

TIMES_JSON: the seconds at which to evaluate the scene (node world positions, skinned vertices);
NODE_NAMES_JSON: the nodes whose world position to report at each time (NaN where a name is not there)."""

import gc
import json
import os
import sys

import numpy as np

HELD = []  # every bindings object read, never released


def hold(x):
    HELD.append(x)
    return x


def _array(values) -> np.ndarray:
    """A copy of a bindings list: through its buffer where it has one (vectors, faces), else element by element
    (indices: plain integers)."""
    hold(values)
    try:
        view = hold(memoryview(values))
    except TypeError:
        return np.fromiter(values, np.int64, len(values))
    return np.array(view)


def probe(path: str, times: list[float], names: list[str]) -> dict:
    import ufbx

    s = hold(ufbx.load_file(path))
    out = {"unit_meters": hold(s.settings).unit_meters}
    stacks = hold(s.anim_stacks)
    stack = hold(stacks[0]) if len(stacks) else None
    out["stack_span"] = np.array([stack.time_begin, stack.time_end] if stack is not None else [np.nan, np.nan])
    props = hold(s.settings.props)
    out["time_span_ktime"] = np.array([hold(props.find_prop(n)).value_int for n in ("TimeSpanStart", "TimeSpanStop")])
    kids = [hold(n) for n in hold(hold(s.root_node).children)]
    tr = [hold(n.local_transform) for n in kids]
    out["kid_names"] = np.array([n.name for n in kids])
    out["kid_rotation"] = np.array([list(t.rotation) for t in tr], float)
    out["kid_translation"] = np.array([list(t.translation) for t in tr], float)
    out["kid_scale"] = np.array([list(t.scale) for t in tr], float)
    mesh = hold(hold(s.meshes)[0])
    skins, blends = hold(mesh.skin_deformers), hold(mesh.blend_deformers)
    out["skin_clusters"] = len(hold(hold(skins[0]).clusters)) if len(skins) else 0
    out["blend_channels"] = len(hold(hold(blends[0]).channels)) if len(blends) else 0
    out["num_vertices"] = mesh.num_vertices
    out["uv_sets"] = np.array([hold(u).name for u in hold(mesh.uv_sets)])
    mats = hold(mesh.materials)
    out["materials"] = len(mats)
    tex = hold(hold(hold(hold(mats[0]).pbr).base_color).texture) if len(mats) else None
    out["texture"] = np.frombuffer(bytes(hold(tex.content)), np.uint8) if tex is not None else np.zeros(0, np.uint8)
    uv, col = hold(mesh.vertex_uv), hold(mesh.vertex_color)
    out["uv"] = _array(uv.values)[_array(uv.indices)]
    if col.exists:
        out["color"] = _array(col.values)[_array(col.indices)][:, :3]
    begin, count = _array(mesh.faces).T.astype(np.int64)  # (index_begin, num_indices) a face
    out["triangles"] = begin[count == 3, None] + np.arange(3)
    out["vertex_indices"] = _array(mesh.vertex_indices)
    world, skinned = [], []
    for t in times:
        e = hold(ufbx.evaluate_scene(s, hold(s.anim), t, evaluate_skinning=True))
        sp = hold(hold(hold(e.meshes)[0]).skinned_position)
        skinned.append(_array(sp.values)[_array(sp.indices)])
        nodes = [hold(e.find_node(n)) for n in names]
        world.append([list(hold(n.node_to_world).c3) if n is not None else [np.nan] * 3 for n in nodes])
    out["world"] = np.array(world, float).reshape(len(times), len(names), 3)
    out["skinned"] = np.array(skinned, float).reshape(len(times), -1, 3)
    return out


if __name__ == "__main__":
    gc.disable()
    fbx, dst, times, names = sys.argv[1:5]
    data = probe(fbx, json.loads(times), json.loads(names))
    with open(dst, "wb") as f:
        np.savez(f, **data)
    sys.stdout.flush()
    os._exit(0)  # no bindings object released: the scene's memory goes with the process
