#!/usr/bin/env python3
"""Renders one take through its three file exports, each opened by Blender's own importer, side by
side at one frame, for the README's picture: frond-gltf's GLB (glTF importer), `frond take export
--bvh` (Motion Capture importer; a BVH holds only the skeleton, so its bones are drawn as sticks)
and `frond take export --usd` (USD importer). Usage:
    python docs/render_exports.py TAKE.glb TAKE.bvh TAKE.usda OUT.png FRAME
(with bpy from PyPI: tests/python/.venv/bin/python after exporters/osc/tests/install-python.sh).
docs/render_exports.sh makes the three files from a simulated take and calls this."""

import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_stage import material, render_outdoors  # noqa: E402

glb, bvh, usd, out = sys.argv[1:5]
frame = int(sys.argv[5]) if len(sys.argv) > 5 else 30
SPACING = 0.55  # metres between the three plants, along Blender's X
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
# The exports' rate, before any importer turns seconds into frames.
scene.render.fps, scene.render.fps_base = 30, 1.0


def imported(run):
    """Runs one importer; returns the top-level objects it made."""
    before = set(bpy.data.objects)
    run()
    return [o for o in bpy.data.objects if o not in before and o.parent is None]


def label(text, x):
    bpy.ops.object.text_add(location=(x, -0.15, 0.005))
    obj = bpy.context.object
    obj.data.body = text
    obj.data.align_x = "CENTER"
    obj.data.size = 0.065
    obj.data.materials.append(material(f"label {text}", (0.95, 0.95, 0.9)))


parts = [
    ("glTF  (frond-gltf)", lambda: bpy.ops.import_scene.gltf(filepath=glb)),
    ("BVH", lambda: bpy.ops.import_anim.bvh(filepath=bvh, global_scale=1.0, rotate_mode="NATIVE",
                                           use_fps_scale=False, update_scene_fps=False,
                                           update_scene_duration=True)),
    ("USD  (UsdSkel)", lambda: bpy.ops.wm.usd_import(filepath=usd)),
]
groups = []
for i, (name, run) in enumerate(parts):
    x = (i - 1) * SPACING
    objs = imported(run)
    for o in objs:
        o.location.x += x
    groups.append(objs)
    label(name, x)
# Blender's BVH importer keys from frame 1 at the least; the other two start at frame 0.
for arm in [o for o in groups[1] if o.type == "ARMATURE"]:
    for fc in arm.animation_data.action.fcurves:
        for key in fc.keyframe_points:
            key.co.x -= 1
            key.handle_left.x -= 1
            key.handle_right.x -= 1
scene.frame_set(frame)
bpy.context.view_layer.update()
# The three skeletons' top joints (the flower's `head`), each from its own root: they agree.
def armatures(objs):
    return [a for o in objs for a in [o, *o.children_recursive] if a.type == "ARMATURE"]


for (name, _), objs in zip(parts, groups):
    for arm in armatures(objs):
        bones = arm.pose.bones
        root, top = arm.matrix_world @ bones["root"].head, arm.matrix_world @ bones["head"].head
        print(f"{name}: head at {tuple(round(v, 4) for v in top - root)} from root")

# The BVH armature has no mesh: a stick per bone, from its posed head to its tail, at this frame.
stick = material("bvh bones", (0.85, 0.55, 0.2))
for arm in armatures(groups[1]):
    for pb in arm.pose.bones:
        head = arm.matrix_world @ pb.head
        tail = arm.matrix_world @ pb.tail
        mid, d = (head + tail) / 2, tail - head
        bpy.ops.mesh.primitive_cylinder_add(radius=0.008, depth=d.length, location=mid)
        cyl = bpy.context.object
        cyl.rotation_mode = "QUATERNION"
        cyl.rotation_quaternion = d.to_track_quat("Z", "Y")
        cyl.data.materials.append(stick)
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.014, location=head)
        bpy.context.object.data.materials.append(stick)

# A USD mesh without a material renders white; give it the plant's green.
green = material("usd plant", (0.25, 0.55, 0.2))
for o in bpy.data.objects:
    if o.type == "MESH" and not o.data.materials and any(o in g or o.parent in g for g in groups[2:]):
        o.data.materials.append(green)

render_outdoors(out, 6, (0.0, -2.3, 0.45), 84, (720, 300))
