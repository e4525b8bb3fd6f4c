#!/usr/bin/env python3
"""Headless test of frond's Blender add-on on a live layer: Blender's glTF importer brings in the
flower GLB frond-gltf baked (its two leaves are `leaf0_joint0..3` and `leaf1_joint0..3`), the
flower is picked, and frond-osc streams a daemon whose second hand drives the `leaf` element
(announced as a layer: `/frond/element/<e>/info`).

After each batch the add-on applied, the last layer frame is reported on --out as {"element",
"seq", "quats": per leaf instance, per bone, Blender's (w, x, y, z)} for the Rust test to compare
with the daemon's pose of that sequence number. Prints `port N` when listening. Exit 0 on success, 1 on failure.
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
from bpy_pump import failer, import_armature, pump  # noqa: E402

fail = failer("blender layer check")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--glb", required=True, help="frond-gltf's GLB of the flower")
    ap.add_argument("--frames", type=int, default=100, help="layer frames to report")
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()

    obj = import_armature(args.glb, fail)
    frond_receiver.register()
    scene = bpy.context.scene
    scene.frond_receiver.armature = obj
    port = frond_receiver.start("127.0.0.1", 0)
    receiver = frond_receiver._state["receiver"]
    print(f"port {port}", flush=True)

    out = open(args.out, "w")
    reported = [0]

    def report(frames):
        layer = [f for f in frames if f.get("element", 0) != 0]
        if not layer:
            return
        f = layer[-1]
        sets = frond_receiver.element_bones(obj, f["element"])
        if len(sets) != 2:
            fail(f"layer element {f['element']} drives {sets}, not the flower's two leaves")
        quats = [[list(obj.pose.bones[name].rotation_quaternion) for name in names] for names in sets]
        out.write(json.dumps({"element": f["element"], "seq": f["seq"], "quats": quats}) + "\n")
        reported[0] += 1

    pump(scene, receiver, time.monotonic() + args.timeout, fail, lambda: reported[0] >= args.frames, report,
         lambda: f"{reported[0]} of {args.frames} layer frames")
    out.close()
    frond_receiver.unregister()
    print(f"blender layer check ok: {reported[0]} layer frames", file=sys.stderr, flush=True)
    os._exit(0)


if __name__ == "__main__":
    main()
