#!/usr/bin/env python3
"""Renders the README's live picture (docs/live.png): Blender receiving frond live from two
frond-osc processes at once. frond's add-on (exporters/osc/blender/frond_receiver.py) drives a
field of grass imported from frond-gltf's field GLB (one armature per plant, from the daemon's
`frond field start`), and the third-party VMC4B add-on drives a flower imported from frond-gltf's
GLB from frond-osc's VMC stream of the live glove. Usage (docs/render_live.sh runs it):
    python docs/render_live.py field.glb flower.glb OUT.png SECONDS
Prints `ports FROND VMC` when both receivers listen, then receives for SECONDS and renders the
pose of that moment with Cycles on the CPU."""

import os
import socket
import sys
import time

import bpy

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
sys.path.insert(0, os.path.join(here, "..", "exporters", "osc", "blender"))
sys.path.insert(0, os.path.join(here, "..", "exporters", "osc", "tests", "third_party"))
from blender_stage import render_outdoors  # noqa: E402
import frond_receiver  # noqa: E402
import VMC4B  # noqa: E402
from VMC4B.core import state  # noqa: E402
from VMC4B.core.applier import Applier  # noqa: E402

field_glb, flower_glb, out, seconds = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=field_glb)
before = set(bpy.data.objects)
bpy.ops.import_scene.gltf(filepath=flower_glb)
flower = next(o for o in bpy.data.objects if o not in before and o.type == "ARMATURE")
for o in bpy.data.objects:
    if o.name.startswith("Icosphere"):
        o.hide_render = True  # the importer's bone shapes
scene = bpy.context.scene

frond_receiver.register()
frond_port = frond_receiver.start("127.0.0.1", 0)
probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
probe.bind(("127.0.0.1", 0))
vmc_port = probe.getsockname()[1]
probe.close()
VMC4B.register()
scene.vmc4b_target_armature = flower.name
for humanoid, bone in zip(["Hips", "Spine", "Chest", "Neck"], ["root", "stem_low", "stem_high", "head"]):
    setattr(scene, "vmc4b_bones_" + humanoid, bone)
scene.vmc4b_performer_address, scene.vmc4b_performer_port = "127.0.0.1", str(vmc_port)
bpy.ops.vmc4b.connect()
while state.server.server is None:
    time.sleep(0.01)
print(f"ports {frond_port} {vmc_port}", flush=True)

applier = Applier()
end = time.monotonic() + seconds
while time.monotonic() < end:
    frond_receiver.poll_once(scene)
    while state.server.queue:
        item = state.server.queue.popleft()
        applier.update(item["address"], item["args"])
    time.sleep(0.005)
state.server.stop()
frond_receiver.stop()
render_outdoors(out, 14, (0.85, -3.3, 0.5), 84, (800, 400))
os._exit(0)
