#!/usr/bin/env python3
"""Renders a GLB that frond-gltf baked (a grove of walking plants) with Blender's own glTF importer
and Cycles on the CPU, for the README's picture. Usage:
    python docs/render_grove.py grove.glb OUT.png [FRAME]
(with bpy from PyPI: tests/python/.venv/bin/python after exporters/osc/tests/install-python.sh)."""

import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_stage import render_outdoors  # noqa: E402

glb, out = sys.argv[1], sys.argv[2]
frame = int(sys.argv[3]) if len(sys.argv) > 3 else 30
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb)
scene = bpy.context.scene
scene.frame_set(frame)

render_outdoors(out, 12, (0.0, -2.1, 0.55), 80, (640, 360))
