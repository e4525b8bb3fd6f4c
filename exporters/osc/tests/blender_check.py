#!/usr/bin/env python3
"""Headless test of exporters/osc/blender/frond_receiver.py with Blender as a Python module (bpy).

Builds an armature with bones joint0..joint3 along +Z (roll 0, as frond-gltf's joints import),
registers the add-on, starts its receiver on 127.0.0.1 (port printed as the first stdout line) and
polls it as Blender's timer would, while frond-osc sends frames to it. Checks, independently of
frond's Rust code:
- each applied frame's bone rotations read back from Blender equal the received quaternions;
- the bones' world directions equal frond's convention computed here from the /frond/pose angles
  (stem +Y, R = R_yaw(Z) R_pitch(X) R_roll(Y), chained root to top), mapped to Blender's Z-up
  world as (x, y, z) -> (x, -z, y);
- Record keys every received frame into a new action (one key per frame per channel, values equal).
Writes {"seq", "quats"} per applied frame (quaternions as read back from the bones) to --out for
the Rust test to compare with the daemon's poses. Exit 0 on success, 1 on a failed check.
"""

import argparse
import json
import math
import os
import socket
import sys
import time

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "blender"))
import frond_receiver  # noqa: E402

HEIGHTS = (0.0, 0.08, 0.16, 0.24, 0.32)  # grass rig; the last is the top bone's tail


def fail(msg):
    print(f"blender check failed: {msg}", file=sys.stderr, flush=True)
    # Not sys.exit: bpy's shutdown can hang with the add-on still registered.
    os._exit(1)


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def frond_matrix(pitch, yaw, roll):
    """frond's convention, written from its documentation: R = Rz(yaw) Rx(pitch) Ry(roll)."""
    p, y, r = (math.radians(a) for a in (pitch, yaw, roll))
    rx = [[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]]
    rz = [[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]]
    ry = [[math.cos(r), 0, math.sin(r)], [0, 1, 0], [-math.sin(r), 0, math.cos(r)]]
    return mat_mul(mat_mul(rz, rx), ry)


def build_armature():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    arm = bpy.data.armatures.new("frond")
    obj = bpy.data.objects.new("frond", arm)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    parent = None
    for i, name in enumerate(frond_receiver.BONE_NAMES):
        b = arm.edit_bones.new(name)
        b.head = (0.0, 0.0, HEIGHTS[i])
        b.tail = (0.0, 0.0, HEIGHTS[i + 1])
        b.roll = 0.0
        if parent is not None:
            b.parent = parent
            b.use_connect = True
        parent = b
    bpy.ops.object.mode_set(mode="OBJECT")
    return obj


def close(a, b, tol, what):
    if any(abs(x - y) > tol for x, y in zip(a, b)):
        fail(f"{what}: {list(a)} != {list(b)}")


def check_geometry(obj, frame):
    bpy.context.view_layer.update()
    angles = frame["angles"]
    r = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    for i, name in enumerate(frond_receiver.BONE_NAMES):
        r = mat_mul(r, frond_matrix(*angles[3 * i : 3 * i + 3]))
        stem = [r[0][1], r[1][1], r[2][1]]  # R * (0, 1, 0) in frond's Y-up frame
        expected = (stem[0], -stem[2], stem[1])  # Blender Z-up world
        m = (obj.matrix_world @ obj.pose.bones[name].matrix).to_3x3()
        got = m.col[1].normalized()
        close(got, expected, 1e-4, f"world direction of {name} at seq {frame['seq']}")


def pump(scene, receiver, want, deadline, on_frames):
    got = 0
    while got < want:
        if time.monotonic() > deadline:
            fail(f"timeout: {got} of {want} frames")
        frames = receiver.poll()
        if not frames:
            time.sleep(0.002)
            continue
        frond_receiver.process(scene, frames)
        on_frames(frames)
        got += len(frames)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--record", type=int, default=200)
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()

    obj = build_armature()
    frond_receiver.register()
    scene = bpy.context.scene
    scene.frond_receiver.armature = obj
    port = frond_receiver.start("127.0.0.1", 0)
    receiver = frond_receiver._state["receiver"]
    # Malformed datagrams are counted and dropped, never raised.
    junk = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for data in (b"", b"#bundle\0", b"#bundle\0" + bytes(8) + b"\xff\xff\xff\xff", b"/frond/pose\0,i\0\0", b"\xff\xfe"):
        junk.sendto(data, ("127.0.0.1", port))
    junk.close()
    time.sleep(0.05)
    if receiver.poll() or receiver.malformed != 5:
        fail(f"malformed datagrams: {receiver.malformed} counted of 5")
    print(port, flush=True)  # only now: frond-osc starts sending when it reads the port

    deadline = time.monotonic() + args.timeout
    out = open(args.out, "w")
    checked = [0]

    def live(frames):
        last = frames[-1]
        for name, (x, y, z, w) in zip(frond_receiver.BONE_NAMES, last["quats"]):
            close(obj.pose.bones[name].rotation_quaternion, (w, x, y, z), 1e-7, f"{name} rotation")
        check_geometry(obj, last)
        quats = [list(obj.pose.bones[n].rotation_quaternion) for n in frond_receiver.BONE_NAMES]
        out.write(json.dumps({"seq": last["seq"], "quats": quats}) + "\n")
        checked[0] += 1

    pump(scene, receiver, args.frames, deadline, live)

    action = frond_receiver.start_recording(scene)
    recorded = []
    pump(scene, receiver, args.record, deadline, recorded.extend)
    frond_receiver.stop_recording(scene)
    frond_receiver.stop()

    keyed = [f for f in recorded if not f["flags"] & (frond_receiver.HELD | frond_receiver.DEVICE_LOST)]
    if not keyed:
        fail("no frame to key arrived while recording")
    fcurves = {(fc.data_path, fc.array_index): fc for fc in action.fcurves}
    for name in frond_receiver.BONE_NAMES:
        for k in range(4):
            fc = fcurves.get((f'pose.bones["{name}"].rotation_quaternion', k))
            if fc is None:
                fail(f"no fcurve for {name} rotation_quaternion[{k}]")
            if len(fc.keyframe_points) != len(keyed):
                fail(f"{name}[{k}]: {len(fc.keyframe_points)} keys for {len(keyed)} keyable frames")
            # frond (x, y, z, w) -> Blender (w, x, y, z)
            for point, frame in zip(fc.keyframe_points, keyed):
                x, y, z, w = frame["quats"][int(frond_receiver.BONE_NAMES.index(name))]
                value = (w, x, y, z)[k]
                if abs(point.co[1] - value) > 1e-6:
                    fail(f"{name}[{k}] key at frame {point.co[0]}: {point.co[1]} != {value}")
    frames = [p.co[0] for p in fcurves[('pose.bones["joint0"].rotation_quaternion', 0)].keyframe_points]
    if any(b <= a for a, b in zip(frames, frames[1:])):
        fail("key frames are not strictly increasing")
    out.close()
    frond_receiver.unregister()
    print(f"blender check ok: {checked[0]} polls checked, {len(keyed)} of {len(recorded)} frames keyed", file=sys.stderr)


if __name__ == "__main__":
    main()
