#!/usr/bin/env python3
"""Checks frond's USD export with Pixar's own library (usd-core from PyPI), independently of
frond's Rust code, and optionally with Blender's USD importer (bpy, another process).

Usage: python usd_check.py SPEC.json      (prints "ok ..." and exits 0, or says why and exits 1)
       python usd_check.py --blender SPEC.json

SPEC: {"usd": FILE.usda or FILE.usdc, "same_as": optional FILE.usda (every attribute compared), "poses": JSONL FILE (`frond take export --fps F`: {"t", "joints"} lines),
       "names": [4 joint names], "heights_m": [h0, h1, h2, h3], "fps": F}

usd-core: the layer passes every validator of USD's validation registry (what `usdchecker`
runs) with no error or warning;
the stage is Y up, metres, at F time codes per second; the Skeleton's joints are the rig's chain;
at every time code the joints' skeleton-space transforms (UsdSkel's own evaluation of rest
transforms and the animation) put each joint where frond's convention puts it (stem +Y, joint
rotation R = R_yaw(Z) R_pitch(X) R_roll(Y) relative to its parent, chained root to top); the
mesh is bound to the skeleton with 4 influences per point and UsdSkel skins it.
Blender: File > Import > USD makes an armature whose bones' heads follow the same positions (in
Blender's Z-up world: (x, y, z) -> (x, -z, y)).
"""

import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "tests", "python"))
from frond_convention import fk, to_blender


def fail(msg):
    print(f"usd check failed: {msg}", file=sys.stderr, flush=True)
    os._exit(1)








def close(a, b, tol):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def check_usd(spec, poses):
    from pxr import Usd, UsdGeom, UsdSkel, UsdValidation

    stage = Usd.Stage.Open(spec["usd"])
    # What `usdchecker` runs: every registered validator (stage metadata, UsdSkel bindings, ...).
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    issues = UsdValidation.ValidationContext(validators).Validate(stage)
    if issues:
        fail("validation: " + "; ".join(f"{e.GetName()}: {e.GetMessage()}" for e in issues))
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.y or UsdGeom.GetStageMetersPerUnit(stage) != 1.0:
        fail("the stage is not Y up in metres")
    if stage.GetTimeCodesPerSecond() != spec["fps"]:
        fail(f"{stage.GetTimeCodesPerSecond()} time codes per second, not {spec['fps']}")
    root = stage.GetDefaultPrim()
    if not root or not root.IsA(UsdSkel.Root):
        fail("the default prim is not a SkelRoot")
    skel = UsdSkel.Skeleton(root.GetChild("Skeleton"))
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(root), Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(skel)
    order = [str(j) for j in query.GetJointOrder()]
    chain = "/".join(spec["names"][:1])
    want_chain = [chain]
    for n in spec["names"][1:]:
        want_chain.append(want_chain[-1] + "/" + n)
    if order[:4] != want_chain:
        fail(f"joints {order[:4]}, expected {want_chain}")
    worst = 0.0
    for k, pose in enumerate(poses):
        xforms = query.ComputeJointSkelTransforms(Usd.TimeCode(k))
        want = fk(pose["joints"], spec["heights_m"])
        for j in range(4):
            got = list(xforms[j].ExtractTranslation())
            worst = max(worst, max(abs(a - b) for a, b in zip(got, want[j])))
            if not close(got, want[j], 1e-5):
                fail(f"time {k} joint {j}: {got} != forward kinematics {want[j]}")
    mesh = root.GetChild("Mesh")
    skinning = cache.GetSkinningQuery(mesh)
    if not skinning or not skinning.HasJointInfluences() or skinning.GetNumInfluencesPerComponent() != 4:
        fail("the mesh is not skinned with 4 influences per point")
    points = UsdGeom.Mesh(mesh).GetPointsAttr().Get()
    xforms = query.ComputeSkinningTransforms(Usd.TimeCode(len(poses) - 1))
    skinned = points
    if not skinning.ComputeSkinnedPoints(xforms, skinned, Usd.TimeCode(len(poses) - 1)):
        fail("UsdSkel could not skin the mesh")
    same = ""
    if spec.get("same_as"):
        same = f"; {same_layers(stage, Usd.Stage.Open(spec['same_as']))} attributes equal to {spec['same_as']}'s"
    print(f"ok: usd-core: {len(validators)} validators clean; {len(poses)} time codes, joints within {worst:.1e} m; "
          f"{len(points)} points skinned{same}", flush=True)


def same_layers(stage, other):
    """Every prim, its type, every attribute with its metadata, default and time samples, equal in
    both stages (usd-core reads each from its own file); the number of attributes compared."""
    from pxr import Usd

    prims = [p.GetPath() for p in stage.Traverse()]
    if prims != [p.GetPath() for p in other.Traverse()]:
        fail(f"prims differ: {prims} vs {[p.GetPath() for p in other.Traverse()]}")
    if stage.GetRootLayer().customLayerData != other.GetRootLayer().customLayerData:
        fail("customLayerData differs")
    n = 0
    for path in prims:
        a, b = stage.GetPrimAtPath(path), other.GetPrimAtPath(path)
        if a.GetTypeName() != b.GetTypeName():
            fail(f"{path}: type {a.GetTypeName()} vs {b.GetTypeName()}")
        names = sorted(x.GetName() for x in a.GetAuthoredAttributes())
        if names != sorted(x.GetName() for x in b.GetAuthoredAttributes()):
            fail(f"{path}: attributes {names} vs {sorted(x.GetName() for x in b.GetAuthoredAttributes())}")
        for name in names:
            x, y = a.GetAttribute(name), b.GetAttribute(name)
            what = f"{path}.{name}"
            if x.GetTypeName() != y.GetTypeName() or x.GetVariability() != y.GetVariability():
                fail(f"{what}: type or variability differs")
            if x.GetAllMetadata() != y.GetAllMetadata():
                fail(f"{what}: metadata {x.GetAllMetadata()} vs {y.GetAllMetadata()}")
            times = x.GetTimeSamples()
            if times != y.GetTimeSamples():
                fail(f"{what}: time samples at {times[:5]}.. vs {y.GetTimeSamples()[:5]}..")
            for t in [Usd.TimeCode.Default()] + [Usd.TimeCode(t) for t in times]:
                if x.Get(t) != y.Get(t):
                    fail(f"{what} at {t}: {x.Get(t)} vs {y.Get(t)}")
            n += 1
        for rel in a.GetAuthoredRelationships():
            if rel.GetTargets() != b.GetRelationship(rel.GetName()).GetTargets():
                fail(f"{path}.{rel.GetName()}: targets differ")
    return n


def check_blender(spec, poses):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=spec["usd"])
    arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    if len(arms) != 1:
        fail(f"Blender imported {[o.name for o in bpy.data.objects]}, expected one armature")
    arm = arms[0]
    scene = bpy.context.scene
    names = spec["names"]
    missing = [n for n in names if n not in arm.pose.bones]
    if missing:
        fail(f"bones {missing} missing from {[b.name for b in arm.data.bones]}")
    worst = 0.0
    for k in range(0, len(poses), max(1, len(poses) // 20)):
        scene.frame_set(k)
        bpy.context.view_layer.update()
        want = fk(poses[k]["joints"], spec["heights_m"])
        for j, name in enumerate(names):
            head = arm.matrix_world @ arm.pose.bones[name].head
            w = to_blender(want[j])
            worst = max(worst, max(abs(a - b) for a, b in zip(head, w)))
            if not close(head, w, 1e-4):
                fail(f"Blender frame {k} {name}: head {tuple(head)}, forward kinematics {w}")
    print(f"ok: Blender's USD importer: bones follow the take (worst {worst:.1e} m)", flush=True)


def main():
    blender = sys.argv[1] == "--blender"
    spec = json.load(open(sys.argv[-1]))
    poses = [json.loads(line) for line in open(spec["poses"]) if line.strip()]
    if blender:
        check_blender(spec, poses)
    else:
        check_usd(spec, poses)
    os._exit(0)


main()
