#!/usr/bin/env python3
"""Independent read-back of a frond-gltf file: a second implementation of everything involved.

Reads the GLB with pygltflib and the take file with its own parser (the documented record
format), converts the take's poses to quaternions with its own implementation of frond's rotation
convention (stem +Y; pitch about +X, yaw about +Z, roll about +Y; R = R_yaw R_pitch R_roll), and
checks, at sampled key times, that every animated joint's rotation equals the take's pose at that
time (linear interpolation of the raw frames) within the tolerance, and that every vertex's
weights sum to 1.

Usage: readback.py FILE.glb TAKE.take [--tol 1e-4]
Prints a JSON summary on stdout; exits 1 on any mismatch, 2 on bad input.
"""

import json
import math
import re
import struct
import sys
import zlib

import pygltflib

HELD = 1
COMPONENTS = {5120: ("b", 1), 5121: ("B", 1), 5122: ("h", 2), 5123: ("H", 2), 5125: ("I", 4), 5126: ("f", 4)}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def read_take(path):
    """Returns (header dict, {element: [(t, [[p, y, r] x 4])]}) of non-held frames."""
    data = open(path, "rb").read()
    if data[:8] != b"FRONDTK1":
        raise SystemExit(f"{path}: not a take")
    at, header, layers = 8, {}, {}
    while at + 8 <= len(data):
        length, crc = struct.unpack_from("<II", data, at)
        body = data[at + 8 : at + 8 + length]
        if len(body) < length or zlib.crc32(body) != crc:
            break  # torn tail
        kind, payload = body[0], body[1:]
        if kind == 1:
            header = json.loads(payload)
        elif kind == 2:
            _seq, _dev, _host, flags, element, t = struct.unpack_from("<QQQIHd", payload, 0)
            angles = struct.unpack_from("<12f", payload, 38)
            if not flags & HELD:
                layers.setdefault(element, []).append((t, [list(angles[3 * j : 3 * j + 3]) for j in range(4)]))
        at += 8 + length
    return header, layers


def pose_at(frames, t):
    """Linear interpolation of raw frames at absolute time t, held at the ends."""
    if t <= frames[0][0]:
        return frames[0][1]
    for (ta, a), (tb, b) in zip(frames, frames[1:]):
        if t <= tb:
            u = (t - ta) / (tb - ta)
            return [[a[j][c] + u * (b[j][c] - a[j][c]) for c in range(3)] for j in range(4)]
    return frames[-1][1]


def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def axis_angle(axis, deg):
    h = math.radians(deg) / 2
    s = math.sin(h)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(h))


def convention(pitch, yaw, roll):
    """frond's convention: R = R_yaw(about +Z) * R_pitch(about +X) * R_roll(about +Y)."""
    return qmul(qmul(axis_angle((0, 0, 1), yaw), axis_angle((1, 0, 0), pitch)), axis_angle((0, 1, 0), roll))


def accessor(gltf, blob, index):
    acc = gltf.accessors[index]
    view = gltf.bufferViews[acc.bufferView]
    fmt, size = COMPONENTS[acc.componentType]
    width = WIDTH[acc.type]
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    stride = view.byteStride or size * width
    out = []
    for i in range(acc.count):
        row = struct.unpack_from("<" + fmt * width, blob, start + i * stride)
        out.append(row if width > 1 else row[0])
    return out


def main():
    args = sys.argv[1:]
    tol = 1e-4
    if "--tol" in args:
        i = args.index("--tol")
        tol = float(args[i + 1])
        del args[i : i + 2]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    glb, take_path = args
    gltf = pygltflib.GLTF2().load(glb)
    blob = gltf.binary_blob()
    header, layers = read_take(take_path)
    t0 = min(f[0] for frames in layers.values() for f in frames)

    # Which layer animates which node: main joints by skin order 0..3 -> layer 0; element
    # joints `<name><instance>_joint<k>` by the header's layer names (else the rig order).
    names = header.get("elements", [])
    if len(gltf.skins) != 1:
        print(f"{glb}: {len(gltf.skins)} skins; readback.py checks one-plant bakes", file=sys.stderr)
        sys.exit(2)
    failures, checked = [], 0
    max_err = 0.0
    for anim in gltf.animations:
        for ch in anim.channels:
            node = gltf.nodes[ch.target.node]
            sampler = anim.samplers[ch.sampler]
            if ch.target.path != "rotation" or sampler.interpolation != "LINEAR":
                failures.append(f"channel on {node.name}: {ch.target.path} {sampler.interpolation}")
                continue
            skin = next(s for s in gltf.skins if ch.target.node in s.joints)
            slot = skin.joints.index(ch.target.node)
            joint = slot % 4
            if slot < 4:
                layer = 0
            else:
                m = re.fullmatch(r"(.*?)(\d+)_joint(\d)", node.name or "")
                kind = m.group(1) if m else None
                layer = names.index(kind) + 1 if kind in names else None
            if layer not in layers:
                failures.append(f"{node.name}: no take layer for it")
                continue
            times = accessor(gltf, blob, sampler.input)
            quats = accessor(gltf, blob, sampler.output)
            if abs(times[0]) > 1e-9:
                failures.append(f"{node.name}: first key at {times[0]}, not 0")
            n = len(times)
            for k in sorted({0, 1, n // 3, n // 2, (2 * n) // 3, n - 1}):
                want = convention(*pose_at(layers[layer], t0 + times[k])[joint])
                got = quats[k]
                norm = math.sqrt(sum(c * c for c in got))
                dot = sum(a * b for a, b in zip(want, got))
                sign = 1.0 if dot >= 0 else -1.0
                err = max(abs(a * sign - b) for a, b in zip(want, got))
                max_err = max(max_err, err)
                checked += 1
                if err > tol or abs(norm - 1.0) > 1e-5:
                    failures.append(f"{node.name} key {k} (t={times[k]:.4f}): {got} vs {want} (err {err:.2e})")

    weights_checked = 0
    for mesh in gltf.meshes:
        for prim in mesh.primitives:
            for w in accessor(gltf, blob, prim.attributes.WEIGHTS_0):
                weights_checked += 1
                if abs(sum(w) - 1.0) > 1e-6 or min(w) < 0:
                    failures.append(f"weights {w} do not sum to 1")
                    break

    summary = {
        "file": glb,
        "animations": len(gltf.animations),
        "rotations_checked": checked,
        "max_rotation_error": max_err,
        "vertices_checked": weights_checked,
        "failures": failures[:20],
    }
    print(json.dumps(summary))
    if failures or checked == 0 or weights_checked == 0:
        sys.exit(1)


if __name__ == "__main__":
    main()
