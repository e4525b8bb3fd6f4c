#!/usr/bin/env python3
"""An OSC receiver written independently of frond-osc, on python-osc, for the end-to-end tests.

Binds a UDP port on 127.0.0.1 (printed as the first stdout line), receives datagrams until it has
--count frames, checks them against the OSC 1.0 spec and frond's documented namespace (or VMC),
writes one JSON object per frame to --out and exits 0; on a violation it prints what is wrong to
stderr and exits 1; without enough frames before --timeout it exits 2.

frond mode, per datagram: a bundle (timetag non-decreasing) holding /frond/pose ',idffffffffffff',
/frond/joint/0..3/quat ',ffff' with unit norm and /frond/status ',i'; sequence numbers must be
consecutive (every frame, in order) unless --allow-gaps (then only strictly increasing). The names
bundle (timetag "immediately" (0, 1): /frond/rig ',sssss', /frond/element/<e>/info ',sssssss')
must arrive before --count frames have: its rig and joint names go to the first line of --out as
{"names": ...}.
vmc mode: every datagram at most 1200 bytes and a bundle; a frame starts with the bundle holding
/VMC/Ext/Root/Pos and is complete when its /VMC/Ext/T arrives (timetags may all be "immediately",
so they cannot group frames); Root/Pos ',sfffffff' "root", Bone/Pos ',sfffffff', OK ',iiii'
(loaded 1), T ',f'; bone rotations of unit norm.
"""

import argparse
import json
import math
import socket
import struct
import sys
import time

from pythonosc.osc_bundle import OscBundle
from pythonosc.osc_message import OscMessage


class Violation(Exception):
    pass


def type_tags(dgram):
    """Type-tag string of a raw OSC message, parsed here from the bytes (not by python-osc)."""
    end = dgram.index(b"\0")
    start = (end + 4) & ~3  # address, null, padding to 4
    tags_end = dgram.index(b"\0", start)
    tags = dgram[start:tags_end].decode("ascii")
    if not tags.startswith(","):
        raise Violation(f"type tags {tags!r} do not start with ','")
    return tags


def timetag(dgram):
    seconds, fraction = struct.unpack(">II", dgram[8:16])
    return seconds, fraction


def messages(bundle):
    for i in range(bundle.num_contents):
        item = bundle.content(i)
        if isinstance(item, OscBundle):
            raise Violation("nested bundle")
        yield item


def expect(cond, what):
    if not cond:
        raise Violation(what)


def unit(q, what):
    n = math.sqrt(sum(c * c for c in q))
    expect(abs(n - 1.0) < 1e-5, f"{what}: quaternion norm {n} is not 1 ({q})")


def names_bundle(dgram):
    """The names of a names bundle, or None for another datagram."""
    if not OscBundle.dgram_is_bundle(dgram):
        return None
    found = list(messages(OscBundle(dgram)))
    if not found or not (found[0].address == "/frond/rig" or found[0].address.endswith("/info")):
        return None
    expect(tuple(timetag(dgram)) == (0, 1), f"names bundle timetag {timetag(dgram)} is not 'immediately'")
    names = {"elements": {}}
    for m in found:
        tags = type_tags(m.dgram)
        if m.address == "/frond/rig":
            expect(tags == ",sssss", f"/frond/rig type tags {tags}")
            names["rig"], names["joints"] = m.params[0], list(m.params[1:5])
        elif m.address.startswith("/frond/element/") and m.address.endswith("/info"):
            expect(tags == ",sssssss", f"{m.address} type tags {tags}")
            names["elements"][m.address.split("/")[3]] = list(m.params)
        else:
            raise Violation(f"unexpected address {m.address} in the names bundle")
    expect("rig" in names, "names bundle without /frond/rig")
    return names


def frond_frame(dgram):
    expect(OscBundle.dgram_is_bundle(dgram), "datagram is not a bundle")
    frame = {"timetag": list(timetag(dgram)), "quats": [None] * 4}
    for m in messages(OscBundle(dgram)):
        tags = type_tags(m.dgram)
        if m.address == "/frond/pose":
            expect(tags == ",idffffffffffff", f"/frond/pose type tags {tags}")
            frame["seq"] = m.params[0]
            frame["t"] = m.params[1]
            frame["joints"] = list(m.params[2:14])
        elif m.address.startswith("/frond/joint/") and m.address.endswith("/quat"):
            i = int(m.address.split("/")[3])
            expect(0 <= i < 4, f"joint index {i}")
            expect(tags == ",ffff", f"{m.address} type tags {tags}")
            unit(m.params, m.address)
            frame["quats"][i] = list(m.params)
        elif m.address == "/frond/status":
            expect(tags == ",i", f"/frond/status type tags {tags}")
            frame["flags"] = m.params[0]
        else:
            raise Violation(f"unexpected address {m.address}")
    for key in ("seq", "t", "joints", "flags"):
        expect(key in frame, f"bundle without {key}")
    expect(all(q is not None for q in frame["quats"]), "bundle without all 4 joint quaternions")
    return frame


def run_frond(sock, args, out):
    frames, last_seq, last_tag, named = 0, None, (0, 0), False
    deadline = time.monotonic() + args.timeout
    while frames < args.count:
        if time.monotonic() > deadline:
            print(f"timeout: {frames} of {args.count} frames", file=sys.stderr)
            return 2
        try:
            dgram = sock.recv(65536)
        except socket.timeout:
            continue
        names = names_bundle(dgram)
        if names is not None:
            if not named:
                out.write(json.dumps({"names": names}) + "\n")
            named = True
            continue
        frame = frond_frame(dgram)
        tag = tuple(frame["timetag"])
        expect(tag >= last_tag, f"timetag went backwards: {last_tag} -> {tag}")
        seq = frame["seq"]
        if last_seq is not None:
            expected = (last_seq + 1) & 0xFFFFFFFF
            if args.allow_gaps:
                expect(seq != last_seq, f"seq {seq} repeated")
                expect(((seq - last_seq) & 0xFFFFFFFF) < 0x80000000, f"seq went backwards: {last_seq} -> {seq}")
            else:
                expect(seq & 0xFFFFFFFF == expected, f"frame out of order or lost: seq {seq} after {last_seq}")
        last_seq, last_tag = seq, tag
        out.write(json.dumps(frame) + "\n")
        frames += 1
    expect(named, f"no names bundle among {frames} frames")
    return 0


def run_vmc(sock, args, out):
    frames, pending, last_tag = 0, {}, (0, 0)
    deadline = time.monotonic() + args.timeout
    while frames < args.count:
        if time.monotonic() > deadline:
            print(f"timeout: {frames} of {args.count} frames", file=sys.stderr)
            return 2
        try:
            dgram = sock.recv(65536)
        except socket.timeout:
            continue
        expect(len(dgram) <= 1200, f"datagram of {len(dgram)} bytes exceeds 1200")
        expect(OscBundle.dgram_is_bundle(dgram), "datagram is not a bundle")
        tag = timetag(dgram)
        expect(tag >= last_tag, f"timetag went backwards: {last_tag} -> {tag}")
        last_tag = tag
        found = list(messages(OscBundle(dgram)))
        if any(m.address == "/VMC/Ext/Root/Pos" for m in found):
            expect(pending.get("frame") is None, "a frame began before the previous one's T")
            pending["frame"] = {"timetag": list(tag), "bones": {}, "datagrams": 0}
        frame = pending.get("frame")
        expect(frame is not None, "a datagram outside a frame (no Root/Pos before it)")
        frame["datagrams"] += 1
        for m in found:
            tags = type_tags(m.dgram)
            if m.address == "/VMC/Ext/Root/Pos":
                expect(tags == ",sfffffff", f"Root/Pos type tags {tags}")
                expect(m.params[0] == "root", f"root name {m.params[0]!r}")
                unit(m.params[4:8], "root")
                frame["root"] = list(m.params[1:])
            elif m.address == "/VMC/Ext/Bone/Pos":
                expect(tags == ",sfffffff", f"Bone/Pos type tags {tags}")
                unit(m.params[4:8], f"bone {m.params[0]}")
                frame["bones"][m.params[0]] = list(m.params[1:])
            elif m.address == "/VMC/Ext/OK":
                expect(tags[:2] == ",i" and set(tags[1:]) == {"i"}, f"OK type tags {tags}")
                expect(m.params[0] == 1, f"OK loaded = {m.params[0]}")
                frame["ok"] = list(m.params)
            elif m.address == "/VMC/Ext/T":
                expect(tags == ",f", f"T type tags {tags}")
                frame["t"] = m.params[0]
            else:
                raise Violation(f"unexpected address {m.address}")
        if "t" in frame:
            pending["frame"] = None
            expect("root" in frame and "ok" in frame, f"frame {tag} without Root/Pos or OK")
            expect(len(frame["bones"]) == 4, f"frame {tag} has {len(frame['bones'])} bones")
            out.write(json.dumps(frame) + "\n")
            frames += 1
    return 0


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--mode", choices=["frond", "vmc"], default="frond")
    p.add_argument("--count", type=int, required=True)
    p.add_argument("--timeout", type=float, default=30.0)
    p.add_argument("--out", required=True)
    p.add_argument("--allow-gaps", action="store_true")
    args = p.parse_args()

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    # A large buffer so a receiver starved of CPU for a moment loses nothing; FORCE (root only)
    # passes the rmem_max cap.
    try:
        sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_RCVBUFFORCE", 33), 8 << 20)
    except OSError:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.2)
    print(sock.getsockname()[1], flush=True)
    with open(args.out, "w") as out:
        try:
            code = (run_frond if args.mode == "frond" else run_vmc)(sock, args, out)
        except (Violation, ValueError, IndexError, UnicodeDecodeError) as e:
            print(f"violation: {e}", file=sys.stderr)
            code = 1
    sys.exit(code)


if __name__ == "__main__":
    main()
