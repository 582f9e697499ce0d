"""Run inside Blender (``blender -b --factory-startup --python benchmarks/blender_render_take.py -- TAKE.glb
OUT_DIR CAMERA.json``): render anima's character playing a take, as a camera films a person, for the round-trip
benchmark (``benchmarks/roundtrip_body.py``). The scene: the character (its glTF as Blender imports it), a
textured floor and a textured backdrop far behind (so a panning camera has a background to track), a sun and
the workbench renderer with the textures shown. ``CAMERA.json``: ``{"fps", "frames", "size", "lens_mm",
"sensor_mm", "position": [[x, y, z] per frame], "target": [[x, y, z] per frame]}`` in anima's axes (+y up,
+z the character's front; Blender's are z up: (x, y, z) -> (x, -z, y)). Writes ``OUT_DIR/frame_NNNN.png``.
The textures are random noise made here with numpy (seed 0).

Blender 3.4 from Debian runs on Python 3.11 and numpy >= 1.24, where its bundled glTF importer fails on
``numpy.bool``: the shim below makes it run."""

import json
import sys

import numpy

for _name, _type in (("bool", bool), ("int", int), ("float", float), ("object", object)):
    if not hasattr(numpy, _name) or _name == "bool":
        setattr(numpy, _name, _type)

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

glb, out_dir, cam_path = sys.argv[sys.argv.index("--") + 1 :][:3]
cam = json.load(open(cam_path))
fps = float(cam["fps"])
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps, scene.render.fps_base = round(fps), round(fps) / fps
bpy.ops.import_scene.gltf(filepath=glb)


def blender(p):
    return Vector((p[0], -p[2], p[1]))


def noise_material(name, size, seed, tone):
    rng = numpy.random.default_rng(seed)
    base = rng.random((size // 16, size // 16, 1))
    img = numpy.kron(base, numpy.ones((16, 16, 1)))  # blocks: corners an optical flow can follow
    img = numpy.clip(tone[None, None] * (0.55 + 0.45 * img) + 0.1 * rng.random((size, size, 1)), 0, 1)
    im = bpy.data.images.new(name, size, size)
    im.pixels = numpy.concatenate([img, numpy.ones((size, size, 1))], -1).ravel().tolist()
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = im
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 0, 0))
floor = bpy.context.active_object
floor.data.materials.append(noise_material("floor", 512, 0, numpy.array([0.55, 0.5, 0.45])))
bpy.ops.mesh.primitive_plane_add(size=40, location=(0, 12, 10), rotation=(1.5708, 0, 0))
wall = bpy.context.active_object
wall.data.materials.append(noise_material("wall", 512, 1, numpy.array([0.35, 0.45, 0.6])))
for ob in (floor, wall):
    for p in ob.data.polygons:
        p.use_smooth = False
    ob.data.uv_layers.active.data.foreach_set("uv", [c * 6 for uv in ob.data.uv_layers.active.data for c in uv.uv])

sun = bpy.data.lights.new("sun", "SUN")
sun.energy = 3.0
sun_ob = bpy.data.objects.new("sun", sun)
sun_ob.rotation_euler = (0.7, 0.2, 0.4)
scene.collection.objects.link(sun_ob)
cd = bpy.data.cameras.new("camera")
cd.lens, cd.sensor_width, cd.sensor_fit = cam["lens_mm"], cam["sensor_mm"], "HORIZONTAL"
cam_ob = bpy.data.objects.new("camera", cd)
scene.collection.objects.link(cam_ob)
scene.camera = cam_ob
scene.render.engine = "BLENDER_WORKBENCH"
scene.display.shading.light = "STUDIO"
scene.display.shading.color_type = "TEXTURE"
scene.display.shading.show_shadows = True
scene.render.resolution_x = scene.render.resolution_y = int(cam["size"])
scene.render.image_settings.file_format = "PNG"
for f in range(int(cam["frames"])):
    scene.frame_set(f)
    p, t = blender(cam["position"][f]), blender(cam["target"][f])
    cam_ob.location = p
    cam_ob.rotation_euler = (t - p).to_track_quat("-Z", "Y").to_euler()
    scene.render.filepath = f"{out_dir}/frame_{f:04d}.png"
    bpy.ops.render.render(write_still=True)
print("anima-render: done", int(cam["frames"]))
