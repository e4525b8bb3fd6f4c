#!/usr/bin/env python3
"""Headless test of frond's Blender add-on (exporters/osc/blender/frond_receiver.py) on a live
field: Blender's glTF importer brings in the field GLB frond-gltf baked (one armature per plant,
`grass_0` .. `grass_3`), the add-on listens with no armature picked, and frond-osc streams the
daemon's `frond field start` plants (`/frond/element/<e>/info` kind `field-plant`, name
`plant<i>`; `/frond/element/<e>/pose`).

For each batch of frames the add-on applied, the last frame of each plant is reported on --out as
{"element", "name", "armature", "seq", "heads", "dirs"}: the armature the add-on drove and its
bones' heads and Y axes in armature space, as Blender computes them, for the Rust test to compare
with forward kinematics of the daemon's pose with that sequence number. Then Record keys
--record frames and each driven plant must have its own new action with a key per device time
its frames carried. Prints `port N` when listening. Exit 0 on success, 1 on failure.
"""

import argparse
import json
import os
import sys
import time

import bpy

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "blender"))
sys.path.insert(0, here)
import frond_receiver  # noqa: E402
from bpy_pump import failer, pump  # noqa: E402

fail = failer("blender field check")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--glb", required=True, help="frond-gltf's GLB of the field")
    ap.add_argument("--plants", type=int, required=True, help="plants the daemon publishes")
    ap.add_argument("--frames", type=int, default=200, help="plant frames to report")
    ap.add_argument("--record", type=int, default=100, help="plant frames to record")
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=args.glb)
    arms = sorted(o.name for o in bpy.data.objects if o.type == "ARMATURE")
    if len(arms) < args.plants:
        fail(f"{args.glb}: {len(arms)} armatures for {args.plants} plants: {arms}")
    frond_receiver.register()
    scene = bpy.context.scene
    port = frond_receiver.start("127.0.0.1", 0)
    receiver = frond_receiver._state["receiver"]
    print(f"port {port}", flush=True)

    out = open(args.out, "w")
    deadline = time.monotonic() + args.timeout
    reported = [0]
    driven = set()

    def report(frames):
        last = {}
        for f in frames:
            if f.get("element", 0) != 0 and not f["flags"] & frond_receiver.DEVICE_LOST:
                last[f["element"]] = f
        if not last:
            return
        bpy.context.view_layer.update()
        for element, f in last.items():
            target = frond_receiver.plant_armature(scene, element)
            info = receiver.elements.get(element)
            if target is None:
                if info is not None and info["kind"] == "field-plant":
                    fail(f"field plant {info['name']} drove no armature of {arms}")
                continue
            driven.add(target.name)
            names = info["joints"]
            heads = [list(target.pose.bones[n].head) for n in names]
            dirs = [list(target.pose.bones[n].matrix.to_3x3().col[1].normalized()) for n in names]
            line = {"element": element, "name": info["name"], "armature": target.name, "seq": f["seq"],
                    "heads": heads, "dirs": dirs}
            out.write(json.dumps(line) + "\n")
            reported[0] += 1

    pump(scene, receiver, deadline, fail, lambda: reported[0] >= args.frames, report,
         lambda: f"{reported[0]} of {args.frames} plant frames")
    out.close()
    if len(driven) != args.plants:
        fail(f"{len(driven)} armatures driven ({sorted(driven)}), expected {args.plants}")

    # Record with no armature picked: each plant gets its own action, a key per frame it got.
    if frond_receiver.start_recording(scene) is not None:
        fail("an action on a picked armature, though none is picked")
    got = {}
    recorded = lambda: sum(len(ts) for ts in got.values())  # noqa: E731

    def note(frames):
        for f in frames:
            if f.get("element", 0) != 0 and not f["flags"] & (frond_receiver.HELD | frond_receiver.DEVICE_LOST):
                target = frond_receiver.plant_armature(scene, f["element"])
                got.setdefault(target.name, set()).add(f["t"])

    pump(scene, receiver, deadline, fail, lambda: recorded() >= args.record, note,
         lambda: f"recording: {recorded()} of {args.record}")
    frond_receiver.stop_recording(scene)
    frond_receiver.stop()
    # Frames are keyed at their device time (shared by every element of a tick): one key per
    # distinct time a plant's frames carried.
    for name, times in got.items():
        count = len(times)
        if count < 2:
            fail(f"{name}: frames at {count} distinct device times (stage frames must carry the tick's time)")
        obj = bpy.data.objects[name]
        action = obj.animation_data.action if obj.animation_data else None
        if action is None or action.name != f"frond_take_{name}":
            fail(f"{name}: recorded into {action.name if action else None}, not a new frond_take_{name}")
        fcurves = [fc for fc in action.fcurves if fc.data_path.endswith("rotation_quaternion")]
        if len(fcurves) != 16:
            fail(f"{name}: {len(fcurves)} rotation channels, expected 4 bones x 4")
        keys = {len(fc.keyframe_points) for fc in fcurves}
        if keys != {count}:
            fail(f"{name}: {keys} keys per channel for {count} frames received")
    frond_receiver.unregister()
    print(f"blender field check ok: {reported} plant frames, {len(got)} plants recorded", file=sys.stderr, flush=True)
    os._exit(0)


if __name__ == "__main__":
    main()
