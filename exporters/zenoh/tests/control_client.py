#!/usr/bin/env python3
"""An independent remote-control client for frond-zenoh, written from the README's "Remote
control" section and frond_sdk::control_auth's documented envelope only (no frond code): it
frames one control request as MessagePack, signs it with HMAC-SHA256 and sends it as a Zenoh
query to frond/<stage>/<source>/control, then prints the decoded reply as one JSON line.

    control_client.py --connect tcp/10.0.0.1:7447 --key frond/stage1/glove-a \\
        --as director --key-hex 00..ff --request '{"SetFilter": {"spec": "none"}}'

With --replay it sends the very same signed query twice (the second must be refused).
"""

import argparse
import hashlib
import hmac
import json
import os
import struct
import sys
import time

import msgpack
import zenoh

PROTOCOL_VERSION = 3


def frame(message) -> bytes:
    body = bytes([PROTOCOL_VERSION]) + msgpack.packb(message, use_bin_type=True)
    return struct.pack("<I", len(body)) + body


def unframe(payload: bytes):
    (n,) = struct.unpack_from("<I", payload, 0)
    if n != len(payload) - 4 or payload[4] != PROTOCOL_VERSION:
        raise ValueError(f"not one frame: prefix {n}, {len(payload)} bytes, version {payload[4]}")
    return msgpack.unpackb(payload[5:], raw=False)


def envelope(key: bytes, principal: str, key_expr: str, issued_ms: int, nonce: bytes, req: bytes) -> bytes:
    mac = hmac.new(key, digestmod=hashlib.sha256)
    mac.update(b"frond-control-v1\0" + key_expr.encode() + b"\0")
    mac.update(struct.pack("<Q", issued_ms) + nonce + req)
    name = principal.encode()
    return bytes([1, len(name)]) + name + struct.pack("<Q", issued_ms) + nonce + mac.digest()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--connect", required=True)
    ap.add_argument("--key", required=True, help="frond/<stage>/<source>")
    ap.add_argument("--as", dest="principal", required=True)
    ap.add_argument("--key-hex", required=True)
    ap.add_argument("--request", required=True, help="the request as JSON, e.g. {\"SetFilter\": {\"spec\": \"none\"}}")
    ap.add_argument("--replay", action="store_true")
    args = ap.parse_args()

    config = zenoh.Config()
    config.insert_json5("mode", json.dumps("peer"))
    config.insert_json5("connect/endpoints", json.dumps([args.connect]))
    session = zenoh.open(config)
    # Wait for the source's bridge (its liveliness token), so the request is sent once.
    deadline = time.time() + 10
    while not any(r.ok is not None for r in session.liveliness().get(f"{args.key}/alive", timeout=1.0)):
        if time.time() > deadline:
            print("no bridge", file=sys.stderr)
            return 1
        time.sleep(0.05)

    key_expr = f"{args.key}/control"
    req = frame(json.loads(args.request))
    env = envelope(bytes.fromhex(args.key_hex), args.principal, key_expr, time.time_ns() // 1_000_000, os.urandom(16), req)
    for _ in range(2 if args.replay else 1):
        replies = list(session.get(key_expr, payload=req, attachment=env, timeout=10.0))
        if len(replies) != 1 or replies[0].ok is None:
            print(f"expected one reply, got {len(replies)}", file=sys.stderr)
            return 1
        print(json.dumps(unframe(replies[0].ok.payload.to_bytes())), flush=True)
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
