"""Run inside Blender, not imported by anima (``blender -b --factory-startup --python fbx_from_gltf.py -- IN.glb
OUT.fbx UNITS FPS TEXTURE_PX``; :func:`anima.export.fbx.export_fbx` does): import anima's ``avatar.glb`` with
Blender's own glTF importer and write it with Blender's own FBX exporter as binary FBX 7.4: the skinned
character, its shape keys (the face morphs, ARKit's 52 names) as blend shapes, the armature's action and the shape
keys' animation baked on every frame of the clip, the take's frames as the file's time span.

* Axes: +Y up, -Z forward (the character faces +Z), converted in the data: the armature's and the mesh's nodes
  carry no rotation (an importer shows no turned root and adds no root bone).
* Units: ``m``: the file's unit is the metre and every value is in metres, no node scaled (Unity imports it at
  1 unit = 1 m, Unreal converts it to centimetres, Blender 1:1); ``cm``: the file's unit is the centimetre
  (Maya, MotionBuilder, Cascadeur scenes in cm), the armature node scaled by 100, as Blender writes it.
* Look: the character's colours (glTF ``COLOR_0``, one colour a vertex) baked into a ``TEXTURE_PX`` square
  base-colour texture over a UV set (each part of the body unwrapped by Blender's Smart UV Project, the face's
  texels finer), embedded in the file, on one material (Principled BSDF, the texture into Base Color); the vertex
  colours stay too.

Blender 3.4 from Debian runs on Python 3.11 and numpy >= 1.24, where its bundled glTF importer fails on
``numpy.bool``: the shim below makes it run (as ``tools/blender_inspect.py`` does).
"""

import math
import sys
import warnings
from pathlib import Path

import numpy

with warnings.catch_warnings():  # numpy's FutureWarning on np.bool: not in Blender's last words
    warnings.simplefilter("ignore")
    for _name, _type in (("bool", bool), ("int", int), ("float", float), ("object", object)):
        if not hasattr(numpy, _name) or _name == "bool":
            setattr(numpy, _name, _type)

import bmesh
import bpy
from bpy_extras.io_utils import axis_conversion
from io_scene_fbx import export_fbx_bin, fbx_utils

np = numpy
TEXTURE_NAME = "character_basecolor"
MARGIN_PX = 8  # between UV islands: their edges' colours filtered or mipmapped stay their own
FACE_TEXELS = 2.0  # the face's part of the body (its morphs' vertices) has this many texels a metre more
FORWARD, UP = "-Z", "Y"  # the file's axes
TO_FILE = axis_conversion(to_forward=FORWARD, to_up=UP).to_4x4()  # Blender's +Z up -> the file's +Y up


def armature_in_file_axes(arm) -> None:
    """The armature's bones turned into the file's axes and its object turned back by as much: the same pose
    in Blender, and the exporter, which turns every root object into the file's axes, writes the armature's node
    unturned (its ``bake_space_transform`` does that for meshes only). The pose channels, relative to the bones'
    rest, keep their values; the objects parented to it keep their place."""
    kids = [(c, c.matrix_world.copy()) for c in arm.children]
    bpy.ops.object.select_all(action="DESELECT")
    arm.select_set(True)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    for eb in arm.data.edit_bones:
        eb.transform(TO_FILE, scale=True, roll=True)
    bpy.ops.object.mode_set(mode="OBJECT")
    arm.matrix_world = arm.matrix_world @ TO_FILE.inverted()
    bpy.context.view_layer.update()
    for c, mw in kids:
        c.matrix_world = mw


BOXES = np.array([1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048,
                  3072, 4096, 6144, 8192])  # fmt: skip


def rasterize(uv: np.ndarray, rgb: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Triangles ``uv [T, 3, 2]`` (0-1, v up) with colours ``rgb [T, 3, 3]`` at their corners -> an image
    ``[size, size, 3]`` (row 0 at v = 0) of the colours interpolated over each triangle at the pixels' centres, and
    the mask of the pixels a triangle covers. The triangles go in groups of one box size (:data:`BOXES` a side),
    every pixel of each one's box tested at once."""
    img = np.zeros((size, size, 3), np.float32)
    hit = np.zeros((size, size), bool)
    P = uv.astype(np.float64) * size - 0.5  # pixel centres on integers
    lo = np.floor(P.min(1)).astype(np.int64)
    box = BOXES[np.searchsorted(BOXES, np.maximum(np.ceil(P.max(1)).astype(np.int64) - lo + 1, 1))]
    Q = (P - lo[:, None, :]).astype(np.float32)  # each triangle from its box's corner
    for bw, bh in np.unique(box, axis=0):
        ids = np.flatnonzero((box[:, 0] == bw) & (box[:, 1] == bh))
        yy, xx = (g.ravel() for g in np.mgrid[0:bh, 0:bw])
        gx, gy = xx.astype(np.float32)[None], yy.astype(np.float32)[None]
        step = max(1, 1_000_000 // (bw * bh))
        for c0 in range(0, len(ids), step):
            t = ids[c0 : c0 + step]
            a = Q[t, 0]
            e1, e2 = Q[t, 1] - a, Q[t, 2] - a
            den = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
            den = np.where(np.abs(den) < 1e-12, 1e-12, den)[:, None]
            dx, dy = gx - a[:, 0, None], gy - a[:, 1, None]
            w1 = (dx * e2[:, 1, None] - dy * e2[:, 0, None]) / den
            w2 = (e1[:, 0, None] * dy - e1[:, 1, None] * dx) / den
            w0 = 1.0 - w1 - w2
            n, k = np.nonzero((w0 >= -1e-5) & (w1 >= -1e-5) & (w2 >= -1e-5))
            x, y = lo[t[n], 0] + xx[k], lo[t[n], 1] + yy[k]
            ok = (x >= 0) & (x < size) & (y >= 0) & (y < size)
            n, k, x, y = n[ok], k[ok], x[ok], y[ok]
            W = np.stack([w0[n, k], w1[n, k], w2[n, k]], -1)
            img[y, x] = np.einsum("pk,pkc->pc", W, rgb[t[n]])
            hit[y, x] = True
    return img, hit


def fill(img: np.ndarray, hit: np.ndarray) -> np.ndarray:
    """The pixels no triangle covers (``img`` a power of 2 a side) filled from the covered ones around them
    (push-pull: the covered pixels' means over blocks of 2, 4, 8, ... pixels, each hole taking the finest
    block's mean that has one): next to an island its edge's colours, so that filtering and mipmaps across a UV
    seam bring in no foreign colour; far from every island, a blend of the nearest ones."""
    sums, counts = [img * hit[..., None]], [hit.astype(np.float32)]
    while sums[-1].shape[0] > 1:
        s, c = sums[-1], counts[-1]
        sums.append(s[0::2, 0::2] + s[1::2, 0::2] + s[0::2, 1::2] + s[1::2, 1::2])
        counts.append(c[0::2, 0::2] + c[1::2, 0::2] + c[0::2, 1::2] + c[1::2, 1::2])
    out = sums[-1] / np.maximum(counts[-1], 1e-9)[..., None]
    for s, c in zip(sums[-2:0:-1], counts[-2:0:-1]):
        out = np.repeat(np.repeat(out, 2, 0), 2, 1)
        have = c > 0
        out[have] = s[have] / c[have, None]
    out = np.repeat(np.repeat(out, 2, 0), 2, 1)
    out[hit] = img[hit]
    return out.astype(np.float32)


def to_srgb(linear: np.ndarray, steps: int = 4096) -> np.ndarray:
    """Scene-linear values (0-1) encoded as sRGB, through a table of ``steps`` linear steps (under a level of
    8 bits everywhere)."""
    x = np.linspace(0.0, 1.0, steps + 1)
    table = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055).astype(np.float32)
    return table[np.rint(np.clip(linear, 0.0, 1.0) * steps).astype(np.int32)]


def body_parts(obj, arm) -> np.ndarray:
    """Each polygon's part of the body: the chain of bones (an arm from its shoulder to its hand, a leg, the
    spine, the neck and head, a finger) whose bones its first vertices follow most, by their skin weights. A
    chain starts where the armature branches, so the parts are what any rig's names call them."""

    def chain(b):
        while b.parent is not None and len(b.parent.children) == 1:
            b = b.parent
        return b.name

    part_of = {b.name: chain(b) for b in arm.data.bones}
    names = {g.index: g.name for g in obj.vertex_groups}
    me = obj.data
    ids: dict = {}
    vpart = np.zeros(len(me.vertices), np.int64)
    for v in me.vertices:
        g = max(v.groups, key=lambda g: g.weight, default=None)
        vpart[v.index] = ids.setdefault(part_of.get(names.get(g.group)) if g else None, len(ids))
    start = np.zeros(len(me.polygons), np.int64)
    me.polygons.foreach_get("loop_start", start)
    lv = np.zeros(len(me.loops), np.int64)
    me.loops.foreach_get("vertex_index", lv)
    a, b, c = (vpart[lv[start + k]] for k in range(3))
    return np.where(b == c, b, a)


def unwrap(obj, arm, margin: float) -> None:
    """A UV set on ``obj``'s mesh: each part of the body (:func:`body_parts`) cut into islands by Blender's Smart
    UV Project on its own, the islands at one texel density, the face's part's :data:`FACE_TEXELS` times as
    fine (the eyes and lips are small), packed into the square ``margin`` apart."""
    me = obj.data
    part = body_parts(obj, arm) if arm is not None else np.zeros(len(me.polygons), np.int64)
    nv = len(me.vertices)
    moved = np.zeros(nv, bool)
    keys = me.shape_keys.key_blocks if me.shape_keys else []
    if len(keys) > 1:
        basis = np.zeros(nv * 3, np.float32)
        keys[0].data.foreach_get("co", basis)
        co = np.zeros(nv * 3, np.float32)
        for k in keys[1:]:
            k.data.foreach_get("co", co)
            moved |= np.abs(co - basis).reshape(-1, 3).max(1) > 1e-4
    start = np.zeros(len(me.polygons), np.int64)
    me.polygons.foreach_get("loop_start", start)
    lv = np.zeros(len(me.loops), np.int64)
    me.loops.foreach_get("vertex_index", lv)
    face_part = np.bincount(part[moved[lv[start]]]).argmax() if moved[lv[start]].any() else -1
    bpy.ops.object.select_all(action="DESELECT")
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    bm = bmesh.from_edit_mesh(me)
    bm.faces.ensure_lookup_table()
    for p in np.unique(part):
        bpy.ops.mesh.select_all(action="DESELECT")
        for i in np.flatnonzero(part == p):
            bm.faces[int(i)].select_set(True)
        bmesh.update_edit_mesh(me)
        bpy.ops.uv.smart_project(angle_limit=math.radians(66), island_margin=0.0, area_weight=0.0,
                                 correct_aspect=True, scale_to_bounds=False)  # fmt: skip
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.select_all(action="SELECT")
    bpy.ops.uv.average_islands_scale()
    bpy.ops.object.mode_set(mode="OBJECT")
    uv = me.uv_layers.active
    luv = np.zeros(len(me.loops) * 2, np.float32)
    uv.data.foreach_get("uv", luv)
    total = np.zeros(len(me.polygons), np.int64)
    me.polygons.foreach_get("loop_total", total)
    fine = np.repeat(part == face_part, total)  # each island in one part: scaled whole
    luv = luv.reshape(-1, 2)
    luv[fine] *= FACE_TEXELS
    uv.data.foreach_set("uv", luv.ravel())
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.select_all(action="SELECT")
    bpy.ops.uv.pack_islands(rotate=True, margin=margin)
    bpy.ops.object.mode_set(mode="OBJECT")
    uv.name = "UVMap"


def texture_from_vertex_colours(obj, arm, size: int, folder: Path):
    """A UV set (:func:`unwrap`) on ``obj``'s mesh and its colour attribute baked over it into a PNG in
    ``folder``; returns the image."""
    me = obj.data
    unwrap(obj, arm, MARGIN_PX / size)
    uv_layer = me.uv_layers.active
    me.calc_loop_triangles()
    tris = me.loop_triangles
    loops = np.zeros(len(tris) * 3, np.int64)
    tris.foreach_get("loops", loops)
    luv = np.zeros(len(me.loops) * 2, np.float32)
    uv_layer.data.foreach_get("uv", luv)
    luv = luv.reshape(-1, 2)
    colour = me.color_attributes.active_color or (me.color_attributes[0] if len(me.color_attributes) else None)
    lcol = np.ones((len(me.loops), 4), np.float32)
    if colour is not None:
        buf = np.zeros(len(colour.data) * 4, np.float32)
        colour.data.foreach_get("color", buf)  # scene-linear RGBA
        buf = buf.reshape(-1, 4)
        if colour.domain == "POINT":
            vi = np.zeros(len(me.loops), np.int64)
            me.loops.foreach_get("vertex_index", vi)
            buf = buf[vi]
        lcol = buf
    else:
        lcol[:, :3] = 0.8
    img, hit = rasterize(luv[loops].reshape(-1, 3, 2), lcol[loops, :3].reshape(-1, 3, 3), size)
    img = to_srgb(fill(img, hit))
    image = bpy.data.images.new(TEXTURE_NAME, size, size, alpha=False)
    rgba = np.ones((size, size, 4), np.float32)
    rgba[..., :3] = img
    image.pixels.foreach_set(rgba.ravel())
    image.filepath_raw = str(folder / f"{TEXTURE_NAME}.png")
    image.file_format = "PNG"
    image.save()
    return image


def textured_material(image) -> bpy.types.Material:
    """A Principled BSDF with ``image`` into its Base Color."""
    mat = bpy.data.materials.new("character")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 0.6
    bsdf.inputs["Specular"].default_value = 0.3
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def main():
    src, out, units, fps, size = sys.argv[sys.argv.index("--") + 1 :][:5]
    fps, size, out = float(fps), int(size), Path(out)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = round(fps), round(fps) / fps  # before the import: keys on frames
    bpy.ops.import_scene.gltf(filepath=src)
    for o in [o for o in bpy.data.objects if o.type == "EMPTY" and not o.children]:
        bpy.data.objects.remove(o)  # the glTF's skin root, exported as nothing: its name back to the mesh
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    if len(meshes) == 1:
        meshes[0].name = "character"
    ranges = []
    for o in bpy.data.objects:
        ad = o.animation_data
        if ad and ad.action:
            ranges.append(ad.action.frame_range)
        sk = o.data.shape_keys if o.type == "MESH" and o.data.shape_keys else None
        if sk and sk.animation_data and sk.animation_data.action:
            ranges.append(sk.animation_data.action.frame_range)
    first = int(round(min(r[0] for r in ranges))) if ranges else 0
    last = int(round(max(r[1] for r in ranges))) if ranges else 0
    scene.frame_start, scene.frame_end = first, last
    scene.unit_settings.system, scene.unit_settings.scale_length = "METRIC", 1.0
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    for o in arms:
        armature_in_file_axes(o)
    for o in meshes:
        arm = next((m.object for m in o.modifiers if m.type == "ARMATURE" and m.object), arms[0] if arms else None)
        mat = textured_material(texture_from_vertex_colours(o, arm, size, out.parent))
        o.data.materials.clear()
        o.data.materials.append(mat)

    # the file's time span (Blender writes 0-1 s whatever the scene): the take's frames
    ktime = fbx_utils.FBX_KTIME
    span = {b"TimeSpanStart": int(round(first / fps * ktime)), b"TimeSpanStop": int(round(last / fps * ktime))}
    props_set = export_fbx_bin.elem_props_set

    def _props_set(elem, ptype, name, value=None, *args, **kwargs):
        return props_set(elem, ptype, name, span.get(name, value), *args, **kwargs)

    export_fbx_bin.elem_props_set = _props_set
    bpy.ops.export_scene.fbx(
        filepath=str(out),
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
        axis_forward=FORWARD,
        axis_up=UP,
        bake_space_transform=True,
        path_mode="COPY",
        embed_textures=True,
    )
    print(f"anima-fbx: wrote {out} frames {scene.frame_start}-{scene.frame_end}")


main()
