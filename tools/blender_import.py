"""Open an anima ``avatar.glb`` in Blender with its own timeline: the scene's frame rate and frame range from the
file (anima writes them in the glTF scene's ``extras``, which Blender's importer keeps as the scene's custom
properties ``anima_fps``, ``anima_frame_start``, ``anima_frame_end``; the importer itself leaves a new scene at
24 fps and 250 frames, which cuts a long clip short).

    blender --python tools/blender_import.py -- avatar.glb                 # and work on it
    blender -b --python tools/blender_import.py -- avatar.glb --report r.json --render front.png --frame 30

``--report``: what Blender got (meshes, skinning, bones, frame range and rate, the character's height in metres
at the first frame, shape keys; with ``--frames 0,10,...`` the bones' world heads and the shape keys' values at
those frames); ``--render``: a workbench render of the character from the front at
``--frame``, on a transparent background (the tests read its silhouette). Units: anima writes metres, which is
Blender's unit: no scaling.

Blender 3.4 from Debian runs on Python 3.11 and numpy >= 1.24, where its bundled glTF importer fails on
``numpy.bool``: the shim below makes it run.
"""

import json
import sys

import numpy

for _name, _type in (("bool", bool), ("int", int), ("float", float), ("object", object)):
    if not hasattr(numpy, _name) or _name == "bool":
        setattr(numpy, _name, _type)

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402


def scene_extras(path: str) -> dict:
    """The ``extras`` of the file's first scene, read from the GLB's JSON chunk (before importing: Blender's
    importer turns the animation's seconds into frames at the scene's rate, so the rate must be set first)."""
    import struct

    with open(path, "rb") as fh:
        head = fh.read(20)
        if head[:4] != b"glTF":
            return {}
        n = struct.unpack("<I", head[12:16])[0]
        doc = json.loads(fh.read(n))
    scenes = doc.get("scenes") or [{}]
    return scenes[doc.get("scene", 0)].get("extras", {}) or {}


def import_avatar(path: str) -> dict:
    """Import ``path`` into a new empty scene whose rate and range are the file's (its scene extras)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    fps = float(scene_extras(path).get("anima_fps", 0) or 0)
    if fps > 0:
        scene.render.fps = max(1, round(fps))
        scene.render.fps_base = scene.render.fps / fps
    bpy.ops.import_scene.gltf(filepath=path)
    scene = bpy.context.scene
    if scene.get("anima_frame_end"):
        scene.frame_start = int(scene.get("anima_frame_start", 0))
        scene.frame_end = int(scene["anima_frame_end"])
    return {
        "fps": scene.render.fps / scene.render.fps_base,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
    }


def world_vertices(obj):
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    me = ev.to_mesh()
    pts = [obj.matrix_world @ v.co for v in me.vertices]
    ev.to_mesh_clear()
    return pts


def report(frame: int | None = None, picks=()) -> dict:
    """What Blender got; at each frame of ``picks`` also the bones' world heads and the shape keys' values."""
    scene = bpy.context.scene
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    scene.frame_set(frame if frame is not None else scene.frame_start)
    out = {
        "fps": scene.render.fps / scene.render.fps_base,
        "frame_start": scene.frame_start,
        "frame_end": scene.frame_end,
        "meshes": [o.name for o in meshes],
        "skinned": [o.name for o in meshes if any(m.type == "ARMATURE" and m.object for m in o.modifiers)],
        "bones": [b.name for b in arms[0].data.bones] if arms else [],
        "shape_keys": len(meshes[0].data.shape_keys.key_blocks) if meshes and meshes[0].data.shape_keys else 0,
        "action_frame_range": list(arms[0].animation_data.action.frame_range)
        if arms and arms[0].animation_data and arms[0].animation_data.action
        else None,
    }
    if meshes:
        pts = [p for o in meshes for p in world_vertices(o)]
        zs = [p.z for p in pts]
        out["height_m"] = max(zs) - min(zs)
        out["bbox"] = [[min(p[i] for p in pts) for i in range(3)], [max(p[i] for p in pts) for i in range(3)]]
    if arms:
        out["rest_head"] = [list(arms[0].matrix_world @ b.head_local) for b in arms[0].data.bones]
    out["pose_heads"], out["shape_key_values"] = {}, {}
    for f in picks:
        scene.frame_set(f)
        if arms:
            out["pose_heads"][str(f)] = [list(arms[0].matrix_world @ pb.head) for pb in arms[0].pose.bones]
        if meshes and meshes[0].data.shape_keys:
            out["shape_key_values"][str(f)] = {k.name: k.value for k in meshes[0].data.shape_keys.key_blocks}
    return out


def render_front(path: str, frame: int, size: int = 256) -> None:
    """A workbench render from the front (-Y in Blender, the character facing it), orthographic, framed on the
    character at ``frame``, transparent background."""
    scene = bpy.context.scene
    scene.frame_set(frame)
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    pts = [p for o in meshes for p in world_vertices(o)]
    lo = Vector([min(p[i] for p in pts) for i in range(3)])
    hi = Vector([max(p[i] for p in pts) for i in range(3)])
    centre = (lo + hi) / 2
    cam_data = bpy.data.cameras.new("front")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = max(hi.z - lo.z, hi.x - lo.x) * 1.15
    cam = bpy.data.objects.new("front", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (centre.x, lo.y - 5.0, centre.z)
    cam.rotation_euler = (1.5707963, 0.0, 0.0)
    scene.camera = cam
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.film_transparent = True
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    if not argv:
        raise SystemExit("usage: blender --python tools/blender_import.py -- avatar.glb [--report R.json] "
                         "[--render OUT.png] [--frame N]")  # fmt: skip
    opts = {argv[i]: argv[i + 1] for i in range(1, len(argv) - 1, 2)}
    got = import_avatar(argv[0])
    frame = int(opts.get("--frame", bpy.context.scene.frame_start))
    if "--render" in opts:
        render_front(opts["--render"], frame)
    if "--report" in opts:
        picks = [int(x) for x in opts.get("--frames", "").split(",") if x]
        r = report(bpy.context.scene.frame_start, picks)
        with open(opts["--report"], "w") as fh:
            json.dump(r, fh)
    print(f"anima avatar: {got['frame_end'] - got['frame_start'] + 1} frames at {got['fps']:g} fps")
