#!/usr/bin/env python3
"""Renders a GLB that frond-gltf baked (a grove of walking plants) with Blender's own glTF importer
and Cycles on the CPU, for the README's picture. Usage:
    python docs/render_grove.py grove.glb OUT.png [FRAME]
(with bpy from PyPI: tests/python/.venv/bin/python after exporters/osc/tests/install-python.sh)."""

import math
import sys

import bpy

glb, out = sys.argv[1], sys.argv[2]
frame = int(sys.argv[3]) if len(sys.argv) > 3 else 30
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb)
scene = bpy.context.scene
scene.frame_set(frame)

# Ground, sun, sky, camera looking down at the grove from the front.
bpy.ops.mesh.primitive_plane_add(size=12, location=(0, 0, 0))
ground = bpy.context.object
mat = bpy.data.materials.new("ground")
mat.use_nodes = True
mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.32, 0.26, 0.18, 1)
ground.data.materials.append(mat)
bpy.ops.object.light_add(type="SUN", location=(2, -2, 4))
bpy.context.object.data.energy = 4.0
bpy.context.object.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
world = bpy.data.worlds.new("sky")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.7, 0.9, 1)
world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.8
scene.world = world
bpy.ops.object.camera_add(location=(0.0, -2.1, 0.55), rotation=(math.radians(80), 0, 0))
scene.camera = bpy.context.object

scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 24
scene.render.resolution_x, scene.render.resolution_y = 640, 360
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
print(f"wrote {out}")
