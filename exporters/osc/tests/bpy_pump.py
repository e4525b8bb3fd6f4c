"""What the headless Blender checks (blender_check.py, blender_field_check.py,
blender_layer_check.py, vmc4b_check.py) share: failing with one line on stderr, importing a GLB
into an empty scene, and pumping frond's add-on as Blender's timer would."""

import os
import sys
import time


def failer(name):
    """A `fail(msg)` that prints `NAME failed: msg` and exits 1 at once (not sys.exit: bpy's
    shutdown can hang with an add-on or its server thread still running)."""

    def fail(msg):
        print(f"{name} failed: {msg}", file=sys.stderr, flush=True)
        os._exit(1)

    return fail


def pump(scene, receiver, deadline, fail, done, on_frames, progress):
    """Polls the add-on's `receiver`, has the add-on apply each batch that arrived
    (`frond_receiver.process`) and hands it to `on_frames`, until `done()`; past `deadline`
    (time.monotonic) fails with `timeout: progress()`."""
    import frond_receiver

    while not done():
        if time.monotonic() > deadline:
            fail(f"timeout: {progress()}")
        frames = receiver.poll()
        if not frames:
            time.sleep(0.002)
            continue
        frond_receiver.process(scene, frames)
        on_frames(frames)


def import_armature(path, fail):
    """An empty scene with the GLB at `path` imported by Blender's glTF importer; its one
    armature (fails when there is not exactly one)."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    if len(arms) != 1:
        fail(f"{path}: expected one armature, got {[o.name for o in bpy.data.objects]}")
    return arms[0]
