"""The outdoor set the README's Blender renders share (docs/render_grove.py, docs/render_exports.py):
ground, sun, sky, a camera looking at the plants from the front, Cycles on the CPU."""

import math

import bpy


def material(name, rgb):
    """A plain Principled material of colour `rgb`."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*rgb, 1)
    return mat


def render_outdoors(out, ground_size, camera_location, camera_pitch_deg, resolution):
    """Adds the set to the current scene and renders it to the PNG `out`."""
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=ground_size, location=(0, 0, 0))
    bpy.context.object.data.materials.append(material("ground", (0.32, 0.26, 0.18)))
    bpy.ops.object.light_add(type="SUN", location=(2, -2, 4))
    bpy.context.object.data.energy = 4.0
    bpy.context.object.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.7, 0.9, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.8
    scene.world = world
    bpy.ops.object.camera_add(location=camera_location, rotation=(math.radians(camera_pitch_deg), 0, 0))
    scene.camera = bpy.context.object
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 24
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.filepath = out
    bpy.ops.render.render(write_still=True)
    print(f"wrote {out}")
