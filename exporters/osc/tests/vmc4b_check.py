#!/usr/bin/env python3
"""A third-party VMC receiver in Blender: VMC4B (vendored unchanged in third_party/VMC4B, see the
README there) receives frond-osc's default VMC stream, headless (bpy from PyPI).

Set up as a user does in VMC4B's panel: Blender's glTF importer brings in the GLB frond-gltf baked
for the daemon's rig; the armature is VMC4B's target; the humanoid bones frond sends (Hips, Spine,
Chest, Neck) are mapped to the armature's bones (--bones); address and port typed in; Connect
(VMC4B's own operator) starts its OSC server. In a Blender window VMC4B's modal operator then
applies the queued messages on a timer; a background bpy has no window events, so this script
does what that modal does: pops VMC4B's queue and hands each message to VMC4B's `Applier`.

After each complete frame (`/VMC/Ext/T`, the last message of frond's bundle) it writes a line
{"t", "heads", "dirs"} to --out: the posed bones' world heads and world Y axes (the direction a
bone points) as Blender computes them, for the Rust test to compare with forward kinematics of the
daemon's pose of that device time. Prints `listening` once the server is bound. Exit 0 after
--frames frames, 1 on failure or timeout.
"""

import argparse
import json
import os
import sys
import time

import bpy

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "third_party"))
sys.path.insert(0, here)
import VMC4B  # noqa: E402
from VMC4B.core import state  # noqa: E402
from VMC4B.core.applier import Applier  # noqa: E402
from bpy_pump import failer, import_armature  # noqa: E402


fail = failer("vmc4b check")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--glb", required=True, help="frond-gltf's GLB of the daemon's rig")
    ap.add_argument("--port", type=int, required=True, help="the port typed into VMC4B's panel")
    ap.add_argument("--bones", required=True, help="humanoid=bone,... as mapped in VMC4B's panel")
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    mapping = [pair.split("=", 1) for pair in args.bones.split(",")]

    obj = import_armature(args.glb, fail)
    for _, bone in mapping:
        if bone not in obj.pose.bones:
            fail(f"the imported armature has no bone {bone!r}: {[b.name for b in obj.pose.bones]}")

    VMC4B.register()
    scene = bpy.context.scene
    scene.vmc4b_target_armature = obj.name
    for humanoid, bone in mapping:
        setattr(scene, "vmc4b_bones_" + humanoid, bone)
    scene.vmc4b_performer_address = "127.0.0.1"
    scene.vmc4b_performer_port = str(args.port)
    result = bpy.ops.vmc4b.connect()
    if result != {"FINISHED"}:
        fail(f"VMC4B's Connect returned {result}")
    deadline = time.monotonic() + 10
    while state.server.server is None:
        if time.monotonic() > deadline:
            fail("VMC4B's OSC server did not start")
        time.sleep(0.01)
    print("listening", flush=True)

    applier = Applier()
    out = open(args.out, "w")
    written = 0
    deadline = time.monotonic() + args.timeout
    while written < args.frames:
        if time.monotonic() > deadline:
            fail(f"timeout: {written} of {args.frames} frames")
        if not state.server.queue:
            time.sleep(0.002)
            continue
        item = state.server.queue.popleft()
        applier.update(item["address"], item["args"])
        if item["address"] != "/VMC/Ext/T":
            continue
        bpy.context.view_layer.update()
        heads, dirs = [], []
        for _, bone in mapping:
            m = obj.matrix_world @ obj.pose.bones[bone].matrix
            heads.append(list(m.translation))
            dirs.append(list(m.to_3x3().col[1].normalized()))
        out.write(json.dumps({"t": item["args"][0], "heads": heads, "dirs": dirs}) + "\n")
        written += 1
    out.close()
    state.server.stop()
    print(f"vmc4b check ok: {written} frames", file=sys.stderr, flush=True)
    os._exit(0)


if __name__ == "__main__":
    main()
