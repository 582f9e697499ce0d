"""Run inside Blender, not imported by anima (``blender -b --factory-startup --python fbx_from_gltf.py -- IN.glb
OUT.fbx UNITS FPS``; :func:`anima.export.fbx.export_fbx` does): import anima's ``avatar.glb`` with Blender's own
glTF importer and write it with Blender's own FBX exporter as binary FBX 7.4: the skinned character, its
shape keys (the 53 face morphs) as blend shapes, the armature's action and the shape keys' animation baked on
every frame of the clip. UNITS ``m``: the file's unit is the metre and every value is in metres, no node scaled
(Unity imports it at 1 unit = 1 m, Unreal converts it to centimetres, Blender 1:1); ``cm``: the file's unit is
the centimetre (Maya, MotionBuilder, Cascadeur scenes in cm), the armature node scaled by 100, as Blender writes
it. Axes: Blender's FBX defaults, +Y up and -Z forward.

Blender 3.4 from Debian runs on Python 3.11 and numpy >= 1.24, where its bundled glTF importer fails on
``numpy.bool``: the shim below makes it run (as ``tools/blender_inspect.py`` does).
"""

import sys

import numpy

for _name, _type in (("bool", bool), ("int", int), ("float", float), ("object", object)):
    if not hasattr(numpy, _name) or _name == "bool":
        setattr(numpy, _name, _type)

import bpy  # noqa: E402

src, out, units, fps = sys.argv[sys.argv.index("--") + 1 :][:4]
fps = float(fps)
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.fps, scene.render.fps_base = round(fps), round(fps) / fps  # before the import: keys land on frames
bpy.ops.import_scene.gltf(filepath=src)
ends = []
for o in bpy.data.objects:
    ad = o.animation_data
    if ad and ad.action:
        ends.append(ad.action.frame_range[1])
    sk = o.data.shape_keys if o.type == "MESH" and o.data.shape_keys else None
    if sk and sk.animation_data and sk.animation_data.action:
        ends.append(sk.animation_data.action.frame_range[1])
scene.frame_start, scene.frame_end = 0, int(round(max(ends))) if ends else 0
scene.unit_settings.system, scene.unit_settings.scale_length = "METRIC", 1.0
bpy.ops.export_scene.fbx(
    filepath=out,
    check_existing=False,
    object_types={"ARMATURE", "MESH"},
    use_mesh_modifiers=False,
    mesh_smooth_type="FACE",
    add_leaf_bones=False,
    primary_bone_axis="Y",
    secondary_bone_axis="X",
    armature_nodetype="NULL",
    bake_anim=True,
    bake_anim_use_all_bones=True,
    bake_anim_use_nla_strips=False,
    bake_anim_use_all_actions=False,
    bake_anim_force_startend_keying=True,
    bake_anim_step=1.0,
    bake_anim_simplify_factor=0.0,
    apply_unit_scale=True,
    apply_scale_options="FBX_SCALE_ALL" if units == "m" else "FBX_SCALE_NONE",
    global_scale=1.0,
    axis_forward="-Z",
    axis_up="Y",
    path_mode="STRIP",
    embed_textures=False,
)
print(f"anima-fbx: wrote {out} frames {scene.frame_start}-{scene.frame_end}")
