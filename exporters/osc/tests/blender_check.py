#!/usr/bin/env python3
"""Headless test of exporters/osc/blender/frond_receiver.py with Blender as a Python module (bpy).

Imports the GLB that frond-gltf baked for the daemon's rig with Blender's own glTF importer (the
armature a user gets), registers the add-on, starts its receiver on 127.0.0.1 (printed as `port N` on
stdout; importers print other lines before it) and polls it as Blender's timer would, while frond-osc sends frames to it.
Checks, independently of frond's Rust code:
- the add-on learns the rig's joint names from the stream (`/frond/rig`) and drives exactly the
  imported bones of those names;
- the posed bones' world directions and heads equal frond's convention computed here from the
  /frond/pose angles (stem +Y, R = R_yaw(Z) R_pitch(X) R_roll(Y), chained root to top, joints at
  the rig's heights), mapped to Blender's Z-up world as (x, y, z) -> (x, -z, y);
- Record keys every received frame into a new action (one key per frame per channel, equal to
  the received quaternions).
Writes {"seq", "heads"} per checked frame (bone heads in Blender's world) to --out for the Rust
test to compare with forward kinematics of the daemon's poses. Exit 0 on success, 1 on failure.
"""

import argparse
import json
import os
import socket
import sys
import time

import bpy

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "blender"))
sys.path.insert(0, os.path.join(here, "..", "..", "..", "tests", "python"))
import frond_receiver  # noqa: E402
from bpy_pump import failer, import_armature, pump as pump_until  # noqa: E402
from frond_convention import joint_matrix, mat_mul  # noqa: E402



fail = failer("blender check")


def close(a, b, tol, what):
    if any(abs(x - y) > tol for x, y in zip(a, b)):
        fail(f"{what}: {list(a)} != {list(b)}")


def check_geometry(obj, frame, names, heights):
    """Directions and heads of the posed bones against frond's forward kinematics; the heads."""
    bpy.context.view_layer.update()
    angles = frame["angles"]
    r = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    point = [0.0, heights[0], 0.0]
    heads = []
    for i, name in enumerate(names):
        pb = obj.pose.bones[name]
        head = obj.matrix_world @ pb.head
        close(head, (point[0], -point[2], point[1]), 1e-4, f"world head of {name} at seq {frame['seq']}")
        heads.append(list(head))
        r = mat_mul(r, joint_matrix(*angles[3 * i : 3 * i + 3]))
        stem = [r[0][1], r[1][1], r[2][1]]  # R * (0, 1, 0) in frond's Y-up frame
        expected = (stem[0], -stem[2], stem[1])  # Blender Z-up world
        m = (obj.matrix_world @ pb.matrix).to_3x3()
        close(m.col[1].normalized(), expected, 1e-4, f"world direction of {name} at seq {frame['seq']}")
        if i + 1 < len(names):
            seg = heights[i + 1] - heights[i]
            point = [point[k] + stem[k] * seg for k in range(3)]
    return heads


def check_layer(scene, flower_glb):
    """A secondary element: announced as layer `leaf#1` (python-osc builds the bundles, as
    frond-osc sends them), its pose drives both leaf instances of frond-gltf's flower."""
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder

    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=flower_glb)
    flower = [o for o in bpy.data.objects if o not in before and o.type == "ARMATURE"][0]
    scene.frond_receiver.armature = flower
    port = frond_receiver.start("127.0.0.1", 0)

    def bundle(address, args):
        m = OscMessageBuilder(address=address)
        for a in args:
            m.add_arg(a)
        b = OscBundleBuilder(IMMEDIATELY)
        b.add_content(m.build())
        return b.build().dgram

    angles = [12.0, -20.0, 5.0, 30.0, 8.0, -15.0, -7.0, 25.0, 40.0, 3.0, -33.0, 10.0]
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    names = ["stem0", "stem1", "stem2", "stem3"]
    sock.sendto(bundle("/frond/element/3/info", ["leaf#1", "layer", "flower", *names]), ("127.0.0.1", port))
    sock.sendto(bundle("/frond/element/3/pose", [7, 1.5, *angles]), ("127.0.0.1", port))
    sock.close()
    deadline = time.monotonic() + 5
    frames = []
    while not frames and time.monotonic() < deadline:
        frames = frond_receiver._state["receiver"].poll()
        time.sleep(0.01)
    if not frames or frames[0].get("element") != 3:
        fail(f"the element frame did not arrive: {frames}")
    frond_receiver.process(scene, frames)
    driven = 0
    for k in range(2):
        for j in range(4):
            pb = flower.pose.bones[f"leaf{k}_joint{j}"]
            got = pb.rotation_quaternion.to_matrix()
            want = joint_matrix(*angles[3 * j : 3 * j + 3])
            for a in range(3):
                close(got[a], want[a], 1e-5, f"leaf{k}_joint{j} rotation row {a}")
            driven += 1
    for name in ("root", "stem_low", "stem_high", "head"):
        q = flower.pose.bones[name].rotation_quaternion
        close(q, (1, 0, 0, 0), 1e-6, f"{name}: the layer must not move the stem")
    frond_receiver.stop()
    print(f"layer check ok: {driven} leaf bones driven by layer leaf#1", file=sys.stderr)


def pump(scene, receiver, want, deadline, on_frames):
    got = [0]

    def count(frames):
        on_frames(frames)
        got[0] += len(frames)

    pump_until(scene, receiver, deadline, fail, lambda: got[0] >= want, count, lambda: f"{got[0]} of {want} frames")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--record", type=int, default=200)
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out", required=True)
    ap.add_argument("--glb", required=True, help="frond-gltf's GLB of the daemon's rig")
    ap.add_argument("--flower-glb", required=True, help="frond-gltf's GLB of the flower (two leaves)")
    ap.add_argument("--heights", required=True, help="the rig's joint heights h0,h1,h2,h3 (metres)")
    args = ap.parse_args()
    heights = [float(h) for h in args.heights.split(",")]

    obj = import_armature(args.glb, fail)
    frond_receiver.register()
    scene = bpy.context.scene
    scene.frond_receiver.armature = obj
    # The panel's own buttons: Listen on a free port.
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    scene.frond_receiver.port = probe.getsockname()[1]
    probe.close()
    if bpy.ops.frond.listen() != {"FINISHED"}:
        fail("the Listen button did not start the receiver")
    receiver = frond_receiver._state["receiver"]
    port = receiver.port
    if port != scene.frond_receiver.port:
        fail(f"listening on {port}, the panel says {scene.frond_receiver.port}")
    # Malformed datagrams are counted and dropped, never raised.
    junk = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for data in (b"", b"#bundle\0", b"#bundle\0" + bytes(8) + b"\xff\xff\xff\xff", b"/frond/pose\0,i\0\0", b"\xff\xfe"):
        junk.sendto(data, ("127.0.0.1", port))
    junk.close()
    time.sleep(0.05)
    if receiver.poll() or receiver.malformed != 5:
        fail(f"malformed datagrams: {receiver.malformed} counted of 5")
    print(f"port {port}", flush=True)  # only now: frond-osc starts sending when it reads the port

    deadline = time.monotonic() + args.timeout
    out = open(args.out, "w")
    checked = [0]

    def live(frames):
        if receiver.joint_names is None:
            return  # the names bundle comes first; frames before it drive nothing to check
        names = list(receiver.joint_names)
        if frond_receiver.bone_names(obj) != names:
            fail(f"the add-on drives {frond_receiver.bone_names(obj)}, the stream names {names}")
        heads = check_geometry(obj, frames[-1], names, heights)
        out.write(json.dumps({"seq": frames[-1]["seq"], "heads": heads}) + "\n")
        checked[0] += 1

    pump(scene, receiver, args.frames, deadline, live)

    # Record, then Record again to stop, then Stop: the panel's buttons.
    if bpy.ops.frond.record() != {"FINISHED"} or not scene.frond_receiver.recording:
        fail("the Record button did not start recording")
    action = obj.animation_data.action
    if action is None or not action.name.startswith("frond_take"):
        fail(f"recording into {action}, not a new frond_take action")
    recorded = []
    pump(scene, receiver, args.record, deadline, recorded.extend)
    bpy.ops.frond.record()
    if scene.frond_receiver.recording:
        fail("the Record button did not stop recording")
    bpy.ops.frond.stop()
    if frond_receiver._state["receiver"] is not None:
        fail("the Stop button left the receiver open")

    keyed = [f for f in recorded if not f["flags"] & (frond_receiver.HELD | frond_receiver.DEVICE_LOST)]
    if not keyed:
        fail("no frame to key arrived while recording")
    fcurves = {(fc.data_path, fc.array_index): fc for fc in action.fcurves}
    names = list(receiver.joint_names)
    for name in names:
        for k in range(4):
            fc = fcurves.get((f'pose.bones["{name}"].rotation_quaternion', k))
            if fc is None:
                fail(f"no fcurve for {name} rotation_quaternion[{k}]")
            if len(fc.keyframe_points) != len(keyed):
                fail(f"{name}[{k}]: {len(fc.keyframe_points)} keys for {len(keyed)} keyable frames")
            # frond (x, y, z, w) -> Blender (w, x, y, z), every key
            j = names.index(name)
            for point, frame in zip(fc.keyframe_points, keyed):
                x, y, z, w = frame["quats"][j]
                if abs(point.co[1] - (w, x, y, z)[k]) > 1e-6:
                    fail(f"{name}[{k}] key at frame {point.co[0]}: {point.co[1]} != {(w, x, y, z)[k]}")
    frames = [p.co[0] for p in fcurves[(f'pose.bones["{names[0]}"].rotation_quaternion', 0)].keyframe_points]
    if any(b <= a for a, b in zip(frames, frames[1:])):
        fail("key frames are not strictly increasing")
    if checked[0] == 0:
        fail("no frame was checked (no names bundle arrived?)")
    check_layer(scene, args.flower_glb)
    out.close()
    frond_receiver.unregister()
    print(f"blender check ok: {checked[0]} polls checked, {len(keyed)} of {len(recorded)} frames keyed", file=sys.stderr)


if __name__ == "__main__":
    main()
