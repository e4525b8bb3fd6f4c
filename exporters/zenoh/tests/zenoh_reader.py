#!/usr/bin/env python3
"""An independent reader of frond's Zenoh stream (issue 20), sharing no code with frond: Zenoh's
own Python binding (eclipse-zenoh) and a plain MessagePack decoder, following only the documented
wire format (README, "Socket protocol" and "Stage across machines"):

  payload = u32 little-endian length N, then N bytes: protocol version byte (3), MessagePack body
  body    = {"Pose": {"seq", "device_time_us", "host_monotonic_ns", "flags", "element",
             "joints_deg": [[p, y, r] x 4], "hand": {"t", "wrist_deg", "thumb_deg"}}}
          | {"Field": {"Frame": {"seq", "poses", "field", "tau_s", ...}}}

A field frame (docs/protocol.md: a running field's driving motion) is not evaluated here, as the
docs allow a reader that is not on the SDK: it is numbered `seq ..= seq + poses - 1` in the pose
sequence (its announced plants' numbers), so the next frame is `seq + max(poses, 1)`, and a gap
is counted only past that span.

Subscribes `frond/<stage>/<source>/poses` and prints one JSON line per frame on stdout:
{"seq":..,"t":..,"joints":[[p,y,r] x4],"element":..,"flags":..} for a pose and
{"seq":..,"field":..,"poses":..,"tau_s":..} for a field frame, and on stderr the hello it got
from the `.../hello` queryable, each gap ("gap: N frames missing before seq S") and a last line
"ok: ..." (exit 0) or "error: ..." (exit 1) when a payload does not decode or frames go backwards.
Once a second, and once more after it stops reading, it reports its counts to the bridge as
docs/zenoh.md's replay wire says (a `.../replay` query whose payload is `from`, `to` (equal: asks
nothing), `frames`, `missing`, `recovered`, each u64 little-endian, then its `--name`), so that
`frond status --from zenoh:...` lists it beside the SDK's subscribers.

  zenoh_reader.py --connect tcp/10.0.0.1:7447 --key frond/stage1/glove-a --seconds 10
  zenoh_reader.py --connect ... --key ... --seconds 10 --never-read
      subscribes through a one-slot channel it never drains: once the slot is full, Zenoh's
      receive path for this session blocks, so this peer stops reading its TCP link (a peer that
      subscribes and never reads, seen from the bridge).
"""

import argparse
import json
import os
import struct
import sys
import threading
import time

import msgpack
import zenoh

PROTOCOL_VERSION = 3


def decode(payload: bytes, variant: str) -> dict:
    """The message body of one frame, which must be the `variant` of the message enum."""
    name, body = decode_any(payload)
    if name != variant:
        raise ValueError(f"expected a {variant} message, got {str({name: body})[:80]}")
    return body


def decode_any(payload: bytes) -> tuple:
    """(variant, body) of one frame of any message."""
    if len(payload) < 5:
        raise ValueError(f"{len(payload)} bytes, shorter than a frame header")
    (n,) = struct.unpack_from("<I", payload, 0)
    if n != len(payload) - 4:
        raise ValueError(f"length prefix {n} but {len(payload) - 4} bytes follow")
    if payload[4] != PROTOCOL_VERSION:
        raise ValueError(f"protocol version {payload[4]}, expected {PROTOCOL_VERSION}")
    body = msgpack.unpackb(payload[5:], raw=False)
    if not isinstance(body, dict) or len(body) != 1:
        raise ValueError(f"expected one message, got {str(body)[:80]}")
    return next(iter(body.items()))


def frame_line(payload: bytes) -> tuple:
    """The stdout line of a pose or field frame, and the last sequence number it covers."""
    name, body = decode_any(payload)
    if name == "Pose":
        line = {
            "seq": body["seq"],
            "t": body["hand"]["t"],
            "joints": body["joints_deg"],
            "element": body["element"],
            "flags": body["flags"],
        }
        return line, line["seq"]
    if name == "Field" and isinstance(body, dict) and list(body) == ["Frame"]:
        f = body["Frame"]
        poses = f["poses"]
        if not isinstance(poses, int) or not 0 <= poses <= 255:
            raise ValueError(f"field frame {f['seq']}: poses {poses!r} is not a u8")
        line = {"seq": f["seq"], "field": f["field"], "poses": poses, "tau_s": f["tau_s"]}
        return line, f["seq"] + max(poses, 1) - 1
    raise ValueError(f"expected a Pose or Field frame on poses, got {str({name: body})[:80]}")


def open_session(connect: str) -> "zenoh.Session":
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps("peer"))
    config.insert_json5("connect/endpoints", json.dumps([connect]))
    return zenoh.open(config)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--connect", required=True, help="the bridge's Zenoh endpoint, e.g. tcp/10.0.0.1:7447")
    ap.add_argument("--key", required=True, help="frond/<stage>/<source>")
    ap.add_argument("--seconds", type=float, required=True, help="how long to read")
    ap.add_argument("--never-read", action="store_true", help="subscribe and never read")
    ap.add_argument("--name", default="zenoh_reader.py", help="the name it reports its counts under")
    args = ap.parse_args()

    session = open_session(args.connect)
    if args.never_read:
        _sub = session.declare_subscriber(f"{args.key}/poses", zenoh.handlers.FifoChannel(1))
        print("subscribed, never reading", file=sys.stderr, flush=True)
        time.sleep(args.seconds)
        print("ok: subscribed and never read", file=sys.stderr, flush=True)
        # The session's receive task is blocked on the full channel; leave without closing it.
        os._exit(0)

    state = {"last": None, "frames": 0, "fields": 0, "gaps": 0, "missing": 0, "bad": []}
    lock = threading.Lock()
    out = sys.stdout

    def on_sample(sample: "zenoh.Sample") -> None:
        try:
            line, covers = frame_line(sample.payload.to_bytes())
        except Exception as e:  # a bad payload is the finding, not a crash of the reader
            with lock:
                state["bad"].append(str(e))
            return
        with lock:
            last = state["last"]
            if last is not None and line["seq"] <= last:
                state["bad"].append(f"seq {line['seq']} after {last}")
            elif last is not None and line["seq"] > last + 1:
                state["gaps"] += 1
                state["missing"] += line["seq"] - last - 1
                print(f"gap: {line['seq'] - last - 1} frames missing before seq {line['seq']}", file=sys.stderr, flush=True)
            state["last"] = covers
            state["frames"] += 1
            state["fields"] += "field" in line
            out.write(json.dumps(line, separators=(",", ":")) + "\n")
            out.flush()

    _sub = session.declare_subscriber(f"{args.key}/poses", on_sample)
    # The hello, from the bridge's queryable (a late joiner's way in).
    hello = None
    for _ in range(50):
        for reply in session.get(f"{args.key}/hello", timeout=1.0):
            if reply.ok is not None:
                hello = decode(reply.ok.payload.to_bytes(), "Hello")
        if hello is not None:
            break
        time.sleep(0.1)
    if hello is None:
        print("error: no reply from the hello queryable", file=sys.stderr, flush=True)
        os._exit(1)
    print(
        f"hello: rig={hello['rig_name']} joints={','.join(hello['joint_names'])} "
        f"rate={hello['tick_rate_hz']} protocol={hello['protocol_version']}",
        file=sys.stderr,
        flush=True,
    )
    def report(timeout: float) -> None:
        """The counts so far, to the bridge (a report asks for no frames: from == to)."""
        with lock:
            counts = (state["frames"], state["missing"])
        payload = struct.pack("<QQQQQ", 0, 0, counts[0], counts[1], 0) + args.name.encode()[:64]
        for _ in session.get(f"{args.key}/replay", payload=payload, timeout=timeout):
            pass  # the bridge answers a report with one reply of no frames

    end = time.monotonic() + args.seconds
    while (left := end - time.monotonic()) > 0:
        time.sleep(min(1.0, left))
        report(0.5)
    _sub.undeclare()
    report(2.0)
    with lock:
        s = dict(state)
    if s["bad"]:
        print(f"error: {len(s['bad'])} bad frames, first: {s['bad'][0]}", file=sys.stderr, flush=True)
        os._exit(1)
    print(
        f"ok: {s['frames']} frames ({s['fields']} field frames), {s['gaps']} gaps ({s['missing']} missing)",
        file=sys.stderr,
        flush=True,
    )
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
