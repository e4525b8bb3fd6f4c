#!/usr/bin/env python3
"""Fuzz test of frond's Blender add-on's OSC side (exporters/osc/blender/frond_receiver.py), no
Blender needed: what `Receiver.take` does with each datagram the add-on's socket receives.

Valid datagrams are made with python-osc (an encoder independent of frond-osc's): a pose
bundle, an element pose, the rig and element names, a small field's definition, layout and
frames. First each is checked to be taken as meant (a pose frame, a field that evaluates), so
that the mutated ones reach the deep code. Then --iterations mutations of them (bytes flipped,
words set to extremes, cut, extended, spliced, pure noise), plus a datagram of bundles nested
thousands deep: no exception may leave `take`, a frame it returns must hold values of the right
types, finite, that the Blender side can use as they are, and every field it keeps must stay
within its limits and evaluate without an error. Exit 0 on success, 1 with the first failure.
"""

import argparse
import math
import os
import random
import struct
import sys
import zlib

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "blender"))
import frond_receiver as fr  # noqa: E402
from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder  # noqa: E402
from pythonosc.osc_message_builder import OscMessageBuilder  # noqa: E402


def message(address, *typed):
    b = OscMessageBuilder(address=address)
    for value, tag in typed:
        b.add_arg(value, tag)
    return b.build()


def bundle(*messages):
    b = OscBundleBuilder(IMMEDIATELY)
    for m in messages:
        b.add_content(m)
    return b.build().dgram


def field_datagrams():
    """A 2 x 2 field: definition, layout (one chunk), and 3 frames with stream entries."""
    n = 4
    positions = [0.0, 0.0, 0.2, 0.0, 0.0, 0.2, 0.2, 0.2]
    layout = struct.pack(f"<{2 * n}f", *positions) + struct.pack("<4I", 0, 0, 1, 1)
    layout += struct.pack("<4I", 0, 3, 6, 9) + struct.pack("<4f", 1.0, 0.9, 1.1, 1.05)
    key = zlib.crc32(layout)
    signed = key - (1 << 32) if key >= 1 << 31 else key
    d = message(
        "/frond/field/3/def",
        ("field", "s"), ("grass", "s"), (n, "i"), (2, "i"), (2, "i"), (30.0, "d"), (10, "i"),
        (0.0, "d"), (60, "i"), (signed, "i"), (len(layout), "i"), (1000, "i"), (1, "i"),
        (struct.pack("<H", 1), "b"),
    )
    out = [bundle(d, message("/frond/field/3/joints", *[(j, "s") for j in ("root", "lower", "middle", "tip")]))]
    out.append(bundle(message("/frond/field/3/layout", (signed, "i"), (0, "i"), (1, "i"), (layout, "b"))))
    for k in range(3):
        entries = b"".join(
            struct.pack("<Q", i) + struct.pack("<12f", *[float(i + j) for j in range(12)]) for i in range(4 * k, 4 * k + 4)
        )
        frame = message(
            "/frond/field/3/frame",
            (100 + k, "h"), (0, "i"), (1.0 + k / 60, "d"), (0.1 + k / 60, "d"), (10.0, "d"), (1.0, "d"),
            (1.0, "d"), (1.0, "f"), (0.02, "d"), (0.04, "d"), (0.06, "d"), (4 * k + 4, "h"), (entries, "b"),
        )
        out.append(bundle(frame, message("/frond/fields", (3, "i"))))
    return out


def valid_datagrams():
    angles = [(float(i), "f") for i in range(12)]
    pose = bundle(
        message("/frond/pose", (7, "h"), (1.5, "d"), *angles),
        *[message(f"/frond/joint/{j}/quat", (0.0, "f"), (0.0, "f"), (0.0, "f"), (1.0, "f")) for j in range(4)],
        message("/frond/status", (0, "i")),
    )
    element = bundle(message("/frond/element/5/pose", (8, "h"), (1.5, "d"), *angles))
    names = bundle(
        message("/frond/rig", *[(s, "s") for s in ("grass", "root", "lower", "middle", "tip")]),
        message("/frond/element/5/info", *[(s, "s") for s in ("plant0", "field-plant", "grass", "a", "b", "c", "d")]),
    )
    return [pose, element, names, *field_datagrams()]


def check_frame(frame, what):
    if frame is None:
        return
    if not (fr._is_int(frame["seq"]) and fr._is_number(frame["t"]) and fr._is_int(frame["flags"])):
        fail(f"{what}: frame values of the wrong type: {frame!r:.300}")
    quats = frame["quats"]
    if len(quats) != 4 or not all(len(q) == 4 and all(fr._is_number(v) for v in q) for q in quats):
        fail(f"{what}: rotations not 4 x 4 finite numbers: {quats!r:.300}")
    if "element" in frame and not (fr._is_int(frame["element"]) and 0 < frame["element"] < 65536):
        fail(f"{what}: element {frame['element']!r}")
    # What the Blender side does with them.
    _ = frame["flags"] & (fr.HELD | fr.DEVICE_LOST), frame["t"] - 0.0, frame["seq"] + 1


def check_receiver(receiver, what):
    fields = receiver.fields.fields
    if len(fields) > fr.MAX_FIELDS or len(receiver.elements) > 65535:
        fail(f"{what}: {len(fields)} fields, {len(receiver.elements)} elements kept")
    for f in fields.values():
        d = f.definition
        if len(f.chunks) > d.chunks or f.history.cap > fr.MAX_HISTORY or d.plants > fr.MAX_FIELD_PLANTS:
            fail(f"{what}: field {f.id} past its limits")
        if f.ready():
            angles, ok = f.eval.evaluate(f.frame["tau"])
            if angles.shape != (d.plants, 12) or ok.shape != (d.plants,):
                fail(f"{what}: field {f.id} evaluated to {angles.shape}")
            _ = f.frame["flags"] & fr.DEVICE_LOST, f.frame["seq"] + 1


EXTREMES = [b"\x7f\xff\xff\xff", b"\x80\x00\x00\x00", b"\xff\xff\xff\xff", b"\x00\x00\x00\x00",
            b"\x7f\xf0\x00\x00", b"\xff\xf8\x00\x00", b",ddd", b"\x00\x00\x00\x01"]


def mutate(rng, data, pool):
    data = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        kind = rng.randrange(6)
        if kind == 0 and data:
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        elif kind == 1 and len(data) >= 4:
            at = rng.randrange(len(data) // 4) * 4
            data[at : at + 4] = rng.choice(EXTREMES)
        elif kind == 2 and data:
            del data[rng.randrange(len(data)) :]
        elif kind == 3:
            data += bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        elif kind == 4:
            other = rng.choice(pool)
            a = rng.randrange(len(other))
            at = rng.randrange(len(data) + 1)
            data[at:at] = other[a : a + rng.randint(1, 64)]
        else:
            data = bytearray(rng.randrange(256) for _ in range(rng.randint(0, 64)))
    return bytes(data)


def nested_bundles(depth):
    inner = message("/frond/status", (0, "i")).dgram
    for _ in range(depth):
        inner = b"#bundle\0" + b"\0" * 7 + b"\1" + struct.pack(">I", len(inner)) + inner
    return inner


def fail(why):
    print(f"addon fuzz: {why}", file=sys.stderr, flush=True)
    sys.exit(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--iterations", type=int, default=50_000)
    ap.add_argument("--seed", type=int, default=48)
    args = ap.parse_args()
    pool = valid_datagrams()

    # The valid datagrams are taken as meant: the mutations start from inputs that reach deep.
    receiver = fr.Receiver("127.0.0.1", 0)
    frames = [receiver.take(d) for d in pool]
    if receiver.malformed or frames[0] is None or frames[1] is None or frames[1]["element"] != 5:
        fail(f"valid datagrams not taken: malformed {receiver.malformed}, frames {frames[:2]!r:.300}")
    if receiver.rig != "grass" or receiver.elements.get(5, {}).get("kind") != "field-plant":
        fail("the names were not taken")
    ready = receiver.fields.evaluated()
    if len(ready) != 1 or not ready[0].ready():
        fail("the valid field is not evaluated")
    angles, ok = ready[0].eval.evaluate(ready[0].frame["tau"])
    if not ok.all() or not all(math.isfinite(float(a)) for a in angles.flat):
        fail(f"the valid field evaluates to {angles!r}")

    # Bundles nested far deeper than any sender nests them: refused, not a RecursionError.
    before = receiver.malformed
    if receiver.take(nested_bundles(3000)) is not None or receiver.malformed != before + 1:
        fail("a datagram of 3000 nested bundles was not refused as malformed")

    rng = random.Random(args.seed)
    refused = 0
    for k in range(args.iterations):
        # Now and then a fresh receiver, so that mutated definitions meet empty state too.
        if k % 500 == 0:
            if k % 1000 == 0:
                receiver.close()
                receiver = fr.Receiver("127.0.0.1", 0)
            for d in pool[3:5]:
                receiver.take(d)
        data = mutate(rng, rng.choice(pool), pool)
        before = receiver.malformed
        try:
            frame = receiver.take(data)
        except Exception as e:  # noqa: BLE001 - any escape is the failure looked for
            fail(f"iteration {k}: {type(e).__name__}: {e} from {data.hex()}")
        refused += receiver.malformed - before
        what = f"iteration {k} ({data.hex()[:400]})"
        check_frame(frame, what)
        try:
            check_receiver(receiver, what)
        except Exception as e:  # noqa: BLE001
            fail(f"{what}: the kept state fails: {type(e).__name__}: {e}")
    receiver.close()
    print(f"addon fuzz: {args.iterations} mutated datagrams, {refused} refused as malformed, no escape")


if __name__ == "__main__":
    main()
