#!/usr/bin/env python3
"""Headless test of frond's Blender add-on (exporters/osc/blender/frond_receiver.py) drawing a
whole live field: Blender's glTF importer brings in the field GLB frond-gltf baked (one
armature per plant, `grass_000` .. `grass_399`), the add-on listens with no armature picked,
and frond-osc sends the running field whole (`/frond/field/<f>/def`, `/layout`, `/frame`): the
add-on evaluates every plant itself and drives every plant's armature, the announced ones and
all the others.

Each update that drove every plant (`frond_receiver.poll_once`, as Blender's timer calls it)
is reported on --out for the plants of --report, one line each: {"seq", "tau", "plant",
"armature", "angles" (the add-on's 12 evaluated angles), "heads", "dirs" (its armature's bones
in armature space, as Blender computes them)}, for the Rust test to compare with the SDK's
evaluation of the same field frame and with forward kinematics. A last line {"timing"} gives
the median time an update took to evaluate and to set the bones. Then Record keys --record
updates, and each reported plant's armature must have its own new action with one key per
update on each of its 16 channels. Prints `port N` when listening. Exit 0 on success, 1 on
failure.
"""

import argparse
import json
import os
import statistics
import sys
import time

import bpy

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "blender"))
sys.path.insert(0, here)
import frond_receiver  # noqa: E402
from bpy_pump import failer  # noqa: E402

fail = failer("blender meadow check")


def bound_meshes(arm):
    """The meshes armature `arm` deforms, by name."""
    return sorted(
        (o for o in bpy.data.objects if o.type == "MESH"
         and any(m.type == "ARMATURE" and m.object == arm for m in o.modifiers)),
        key=lambda o: o.name,
    )


def placements(arms):
    """Each plant armature's world matrix and those of the meshes it deforms, as Blender's
    glTF importer placed them."""
    return {name: [list(map(list, o.matrix_world)) for o in [arm, *bound_meshes(arm)]] for name, arm in arms.items()}


def remove_all_but_plant_0(arms):
    """Where the importer placed every plant; then every plant but the first removed."""
    imported = placements(arms)
    first = min(arms)
    for name, arm in arms.items():
        if name != first:
            for mesh in bound_meshes(arm):
                bpy.data.objects.remove(mesh, do_unlink=True)
            bpy.data.objects.remove(arm, do_unlink=True)
    bpy.context.view_layer.update()
    return imported


def build_and_compare(scene, receiver, imported, plants, deadline):
    """Once the field's layout is whole, the add-on builds the missing plants from plant 0:
    each must stand where Blender's importer had placed it, armature and meshes."""
    while True:
        frond_receiver.poll_once(scene)
        fields = [f for f in receiver.fields.fields.values() if f.eval is not None]
        if fields:
            break
        if time.monotonic() > deadline:
            fail("timeout: the field's layout never arrived whole")
        time.sleep(0.002)
    started = time.monotonic()
    made = frond_receiver.build_field(scene, fields[0])
    took = time.monotonic() - started
    bpy.context.view_layer.update()
    if made != plants - 1:
        fail(f"built {made} plants, {plants - 1} were missing")
    arms = {o.name: o for o in bpy.data.objects if o.type == "ARMATURE"}
    if sorted(arms) != sorted(imported):
        fail(f"built armatures {sorted(set(arms) ^ set(imported))[:5]} differ from the import's names")
    built = placements(arms)
    worst = 0.0
    for name, want in imported.items():
        got = built[name]
        if len(got) != len(want):
            fail(f"{name}: {len(got) - 1} meshes built, {len(want) - 1} imported")
        for g, w in zip(got, want):
            worst = max(worst, max(abs(a - b) for gr, wr in zip(g, w) for a, b in zip(gr, wr)))
    if worst > 1e-5:
        fail(f"built plants stand up to {worst} from where the importer placed them")
    print(f"built {made} plants in {took:.2f} s, within {worst:.1e} of the import", file=sys.stderr, flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--glb", required=True, help="frond-gltf's GLB of the field")
    ap.add_argument("--plants", type=int, required=True, help="plants of the field")
    ap.add_argument("--report", required=True, help="plants to report, comma-separated")
    ap.add_argument("--updates", type=int, default=10, help="updates to report")
    ap.add_argument("--record", type=int, default=5, help="updates to record")
    ap.add_argument("--timeout", type=float, default=60)
    ap.add_argument("--out", required=True)
    ap.add_argument("--build", action="store_true",
                    help="keep only plant 0 of the import; the add-on builds the others from the layout")
    args = ap.parse_args()
    report = [int(p) for p in args.report.split(",")]

    bpy.ops.wm.read_factory_settings(use_empty=True)
    started = time.monotonic()
    # Blender's glTF importer updates the whole view layer before each of the operators it runs
    # per armature (bpy.ops' `_view_layer_update`, for edit mode and back): 400 armatures take
    # a minute that way here, 1 s without (the scene it makes is the same, checked bone by bone
    # against an import left alone). The view layer is updated once after the import instead.
    from bpy.ops import _BPyOpsSubModOp as Op

    view_layer_update = Op._view_layer_update
    Op._view_layer_update = staticmethod(lambda context: None)
    try:
        bpy.ops.import_scene.gltf(filepath=args.glb)
    finally:
        Op._view_layer_update = view_layer_update
    bpy.context.view_layer.update()
    arms = {o.name: o for o in bpy.data.objects if o.type == "ARMATURE"}
    if len(arms) != args.plants:
        fail(f"{args.glb}: {len(arms)} armatures for {args.plants} plants")
    print(f"imported {len(arms)} armatures in {time.monotonic() - started:.1f} s", file=sys.stderr, flush=True)
    imported = remove_all_but_plant_0(arms) if args.build else None
    frond_receiver.register()
    scene = bpy.context.scene
    port = frond_receiver.start("127.0.0.1", 0)
    receiver = frond_receiver._state["receiver"]
    print(f"port {port}", flush=True)

    out = open(args.out, "w")
    deadline = time.monotonic() + args.timeout
    seen = set()
    timings = []

    def whole_updates():
        """The field's newest drive, when it is new and moved every plant."""
        frond_receiver.poll_once(scene)
        fields = receiver.fields.evaluated()
        if len(fields) > 1:
            fail(f"{len(fields)} fields evaluated, one runs")
        drive = fields[0].last_drive if fields else None
        if drive is None or drive["seq"] in seen:
            time.sleep(0.002)
            return None, None
        seen.add(drive["seq"])
        if drive["driven"] != args.plants:
            return None, None  # a plant still waits for stream frames it reads
        return fields[0], drive

    if imported is not None:
        build_and_compare(scene, receiver, imported, args.plants, deadline)

    reported = 0
    while reported < args.updates:
        if time.monotonic() > deadline:
            fields = list(receiver.fields.fields.values())
            state = [(f.definition.plants, len(f.chunks), f.eval is not None, f.frames) for f in fields]
            fail(f"timeout: {reported} of {args.updates} updates; fields (plants, chunks, layout, frames) {state}")
        field, drive = whole_updates()
        if drive is None:
            continue
        # The announced plants' own poses give way to the whole field.
        if not frond_receiver.drawn_whole(scene) >= set(field.definition.announced):
            fail(f"announced plants {field.definition.announced} still driven by their own poses")
        timings.append((drive["evaluate_s"], drive["drive_s"]))
        bpy.context.view_layer.update()
        targets = {i: (obj, bones) for i, obj, bones in field.targets}
        for plant in report:
            obj, bones = targets[plant]
            line = {
                "seq": drive["seq"],
                "tau": drive["tau"],
                "plant": plant,
                "armature": obj.name,
                "angles": [float(a) for a in drive["angles"][plant]],
                "heads": [list(pb.head) for pb in bones],
                "dirs": [list(pb.matrix.to_3x3().col[1].normalized()) for pb in bones],
            }
            out.write(json.dumps(line) + "\n")
        reported += 1
    ms = lambda k: statistics.median(t[k] for t in timings) * 1000  # noqa: E731
    out.write(json.dumps({"timing": {"plants": args.plants, "evaluate_ms": ms(0), "drive_ms": ms(1)}}) + "\n")
    out.close()

    # Record with no armature picked: every plant's armature gets its own action.
    if frond_receiver.start_recording(scene) is not None:
        fail("an action on a picked armature, though none is picked")
    recorded = 0
    while recorded < args.record:
        if time.monotonic() > deadline:
            fail(f"timeout: recording {recorded} of {args.record}")
        if whole_updates()[1] is not None:
            recorded = len(frond_receiver._state["field_keys"][field.id]["at"])
    keys = len(frond_receiver._state["field_keys"][field.id]["at"])
    frond_receiver.stop_recording(scene)
    frond_receiver.stop()
    for plant in report:
        obj = targets[plant][0]
        action = obj.animation_data.action if obj.animation_data else None
        if action is None or action.name != f"frond_take_{obj.name}":
            fail(f"{obj.name}: recorded into {action.name if action else None}, not a new frond_take_{obj.name}")
        fcurves = [fc for fc in frond_receiver._fcurves(obj) if fc.data_path.endswith("rotation_quaternion")]
        if len(fcurves) != 16:
            fail(f"{obj.name}: {len(fcurves)} rotation channels, expected 4 bones x 4")
        counts = {len(fc.keyframe_points) for fc in fcurves}
        if counts != {keys}:
            fail(f"{obj.name}: {counts} keys per channel for {keys} updates recorded")
        frames = [p.co[0] for p in fcurves[0].keyframe_points]
        if frames != sorted(set(frames)):
            fail(f"{obj.name}: keys not at increasing frames: {frames}")
    frond_receiver.unregister()
    print(f"blender meadow check ok: {reported} updates, {keys} recorded; {ms(0):.1f} ms evaluating, "
          f"{ms(1):.1f} ms setting bones", file=sys.stderr, flush=True)
    os._exit(0)


if __name__ == "__main__":
    main()
