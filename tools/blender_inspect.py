"""Run inside Blender (``blender -b --factory-startup --python tools/blender_inspect.py -- FILE OUT.json FPS
[FRAME ...]``): import a BVH, glTF or FBX file the way a user does and write what Blender got as JSON: the
armature's bones (names, parents, rest head/tail), the scene's frame range and rate, pose-bone world
matrices at every frame (joint positions), the meshes' skinned vertices, and the mesh shape-key values at the
given frames.

Blender 3.4 from Debian runs on Python 3.11 and numpy >= 1.24, where two of its bundled importers fail
(``open(..., 'rU')`` in the BVH importer, ``numpy.bool`` in the glTF importer); the shims below make them run.
"""

import builtins
import json
import sys

_open = builtins.open


def _open_compat(file, mode="r", *args, **kwargs):
    return _open(file, mode.replace("U", ""), *args, **kwargs)


builtins.open = _open_compat
import numpy  # noqa: E402

for _name, _type in (("bool", bool), ("int", int), ("float", float), ("object", object)):
    if not hasattr(numpy, _name) or _name == "bool":
        setattr(numpy, _name, _type)

import bpy  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1 :]
path, out, fps = argv[0], argv[1], float(argv[2])  # fps: a glTF file has times in seconds, sampled at the scene's
frames = [int(x) for x in argv[3:]]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.context.scene.render.fps, bpy.context.scene.render.fps_base = round(fps), round(fps) / fps
if path.lower().endswith(".bvh"):
    bpy.ops.import_anim.bvh(filepath=path, update_scene_fps=True, update_scene_duration=True, rotate_mode="NATIVE")
elif path.lower().endswith(".fbx"):
    bpy.ops.import_scene.fbx(filepath=path)
else:
    bpy.ops.import_scene.gltf(filepath=path)
scene = bpy.context.scene
arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
meshes = [o for o in bpy.data.objects if o.type == "MESH"]
res = {
    "objects": [[o.name, o.type] for o in bpy.data.objects],
    "frame_start": scene.frame_start,
    "frame_end": scene.frame_end,
    "fps": scene.render.fps / scene.render.fps_base,
}
if arms:
    arm = arms[0]
    res["bones"] = [b.name for b in arm.data.bones]
    res["parents"] = [b.parent.name if b.parent else None for b in arm.data.bones]
    res["rest_head"] = [list(arm.matrix_world @ b.head_local) for b in arm.data.bones]
    res["rest_tail"] = [list(arm.matrix_world @ b.tail_local) for b in arm.data.bones]
    act = arm.animation_data.action if arm.animation_data else None
    res["action_frame_range"] = list(act.frame_range) if act else None
    first, last = (
        (round(act.frame_range[0]), round(act.frame_range[1])) if act else (scene.frame_start, scene.frame_end)
    )
    heads = []
    for f in range(first, last + 1):
        scene.frame_set(f)
        heads.append([list(arm.matrix_world @ pb.head) for pb in arm.pose.bones])
    res["pose_heads"] = heads
res["meshes"] = [
    {
        "name": m.name,
        "vertices": len(m.data.vertices),
        "skinned_vertices": sum(1 for v in m.data.vertices if any(g.weight > 0 for g in v.groups)),
        "armature_modifier": any(md.type == "ARMATURE" and md.object is not None for md in m.modifiers),
    }
    for m in meshes
]
if meshes and meshes[0].data.shape_keys:
    m = meshes[0]
    keys = m.data.shape_keys.key_blocks
    res["shape_keys"] = [k.name for k in keys]
    values = {}
    for f in frames:
        scene.frame_set(f)
        values[str(f)] = {k.name: k.value for k in keys}
    res["shape_key_values"] = values
with _open(out, "w") as fh:
    json.dump(res, fh)
