#!/usr/bin/env python3
"""Imports frond's BVH files with Blender's own BVH importer (bpy, io_anim_bvh) and checks them
against forward kinematics computed here, independently of frond's Rust code.

Usage: python bvh_blender.py SPEC.json   (prints "ok ..." and exits 0, or a reason and exits 1)

SPEC: {"bvh": FILE, "poses": JSONL FILE (`frond take export --fps F`: {"t", "joints"} lines),
       "names": [4 joint names], "heights_m": [h0, h1, h2, h3, top],
       "field": optional {"bvh": FILE, "fps", "frames", "plants": [{"prefix", "position_m": [x, z],
                  "scale", "start_frame", "delay_s"}]}}

Checks, for the take: one bone per joint with the rig's names, the scene's frame rate, and at
every frame each bone's head (and the top bone's tail) in world space equal to frond's convention
(stem +Y; joint rotation R = R_yaw(Z) R_pitch(X) R_roll(Y) relative to its parent, chained root to
top) mapped to Blender's Z-up world by the importer's default axes: (x, y, z) -> (x, -z, y).
For the field: every plant's root bone stands at its position and its segments have its scale,
and at every frame its bones follow the take delayed as Eq. 6 says (worked out here from the
field's start frame and delay of each plant and the take's poses).
"""

import json
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tests", "python"))
from frond_convention import fk, to_blender


def fail(msg):
    print(f"bvh check failed: {msg}", file=sys.stderr, flush=True)
    os._exit(1)












def import_bvh(path):
    before = set(bpy.data.objects)
    bpy.ops.import_anim.bvh(filepath=path, global_scale=1.0, rotate_mode="NATIVE",
                            use_fps_scale=False, update_scene_fps=True, update_scene_duration=True)
    new = [o for o in bpy.data.objects if o not in before]
    arms = [o for o in new if o.type == "ARMATURE"]
    if len(arms) != 1:
        fail(f"{path}: expected one armature, got {[o.name for o in new]}")
    return arms[0]


def close(a, b, tol):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def main():
    spec = json.load(open(sys.argv[1]))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    poses = [json.loads(line) for line in open(spec["poses"]) if line.strip()]
    heights = spec["heights_m"]
    names = spec["names"]
    arm = import_bvh(spec["bvh"])
    bones = [b.name for b in arm.data.bones]
    if sorted(bones) != sorted(names):
        fail(f"bones {bones}, expected the rig's joints {names}")
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    want_fps = round(1.0 / (poses[1]["t"] - poses[0]["t"]))
    if abs(fps - want_fps) > 1e-3:
        fail(f"scene runs at {fps} fps, the BVH at {want_fps}")
    start = scene.frame_start
    first, last = arm.animation_data.action.frame_range
    if round(last - first) + 1 != len(poses) or round(first) != start:
        fail(f"keys on frames {first}..{last}, {len(poses)} exported from frame {start}")
    worst = 0.0
    for k, pose in enumerate(poses):
        scene.frame_set(start + k)
        want = [to_blender(p) for p in fk(pose["joints"], heights)]
        mw = arm.matrix_world
        for j, name in enumerate(names):
            pb = arm.pose.bones[name]
            head = mw @ pb.head
            worst = max(worst, max(abs(a - b) for a, b in zip(head, want[j])))
            if not close(head, want[j], 1e-4):
                fail(f"frame {k} {name}: head {tuple(head)}, forward kinematics {want[j]}")
        tail = mw @ arm.pose.bones[names[3]].tail
        if not close(tail, want[4], 1e-4):
            fail(f"frame {k}: top {tuple(tail)}, forward kinematics {want[4]}")
    report = f"ok: {len(poses)} frames, {len(names)} bones, worst head error {worst:.2e} m"

    field = spec.get("field")
    if field:
        arm = import_bvh(field["bvh"])
        scene.frame_set(scene.frame_start)
        for plant in field["plants"]:
            root = arm.pose.bones.get(f"{plant['prefix']}_{names[0]}")
            if root is None:
                fail(f"field: no root bone for {plant['prefix']} in {[b.name for b in arm.data.bones]}")
            x, z = plant["position_m"]
            want = to_blender([x, heights[0] * plant["scale"], z])
            head = arm.matrix_world @ arm.data.bones[root.name].head_local
            if not close(head, want, 1e-4):
                fail(f"field plant {plant['prefix']}: rests at {tuple(head)}, expected {want}")
            lower = arm.data.bones[f"{plant['prefix']}_{names[1]}"]
            seg = (lower.head_local - arm.data.bones[root.name].head_local).length
            if abs(seg - (heights[1] - heights[0]) * plant["scale"]) > 1e-4:
                fail(f"field plant {plant['prefix']}: first segment {seg} m, scale {plant['scale']}")
        # Animation: plant i plays the take delayed (seed 000, Eq. 6): at time t it shows the take
        # at fractional frame start_frame + (t - delay_s) * fps, interpolated linearly between
        # frames and held at the ends, scaled and placed at its position.
        field_fps = field["fps"]

        def take_at(f):
            if f <= 0:
                return poses[0]["joints"]
            if f >= len(poses) - 1:
                return poses[-1]["joints"]
            k = int(f)
            u = f - k
            a, b = poses[k]["joints"], poses[k + 1]["joints"]
            return [[a[j][c] + (b[j][c] - a[j][c]) * u for c in range(3)] for j in range(4)]

        start, frames = scene.frame_start, field["frames"]
        moved = 0
        for k in range(frames):
            scene.frame_set(start + k)
            t = k / field_fps
            for plant in field["plants"]:
                joints = take_at(plant["start_frame"] + (t - plant["delay_s"]) * field_fps)
                x, z = plant["position_m"]
                s = plant["scale"]
                want = [to_blender([x + s * p[0], s * p[1], z + s * p[2]]) for p in fk(joints, heights)]
                for j, name in enumerate(names):
                    head = arm.matrix_world @ arm.pose.bones[f"{plant['prefix']}_{name}"].head
                    if not close(head, want[j], 2e-4):
                        fail(f"field plant {plant['prefix']} frame {k} {name}: head {tuple(head)}, expected {want[j]}")
                if math.hypot(want[3][0] - want[0][0], want[3][1] - want[0][1]) > 1e-3:
                    moved += 1
        if moved == 0:
            fail("no field plant ever leans: the check would not see a wrong delay")
        report += f"; field of {len(field['plants'])} plants placed, scaled and animated over {frames} frames"
    print(report, flush=True)
    os._exit(0)


main()
