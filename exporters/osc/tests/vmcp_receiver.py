#!/usr/bin/env python3
"""Receives frond-osc's VMC stream with vmcp (a third-party VMC implementation from PyPI, on its
osc4py3 backend), as a marionette would, and writes what it understood.

Usage: python vmcp_receiver.py PORT COUNT OUT.jsonl [TIMEOUT_S]
Listens on 127.0.0.1:PORT; prints "listening" when ready; writes one JSON object per frame
(a frame ends with /VMC/Ext/T): {"t", "bones": {name: [px, py, pz, qx, qy, qz, qw]}, "root",
"state"}; exits 0 after COUNT frames, 1 when vmcp refused something (a bone name that is not a
HumanBodyBones name raises in vmcp's parser), 2 on timeout.
"""

import json
import sys
import time

from vmcp.events import BoneTransformEvent, RelativeTimeEvent, RootTransformEvent, StateEvent
from vmcp.osc import OSC
from vmcp.osc.backend.osc4py3 import as_comthreads as backend

port, count, out_path = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
timeout = float(sys.argv[4]) if len(sys.argv) > 4 else 30.0
frames, current, errors = [], {"bones": {}}, []


def guarded(fn):
    def run(event):
        try:
            fn(event)
        except Exception as e:  # vmcp raised while parsing: the stream is not what VMC wants
            errors.append(repr(e))
    return run


def vec(p):
    return [p.x, p.y, p.z]


def quat(q):
    return [q.x, q.y, q.z, q.w]


@guarded
def on_bone(e):
    current["bones"][e.joint.value] = vec(e.position) + quat(e.rotation)


@guarded
def on_root(e):
    current["root"] = vec(e.position) + quat(e.rotation)


@guarded
def on_state(e):
    parts = (e.model_state, e.calibration_state, e.calibration_mode, e.tracking_state)
    current["state"] = [getattr(p, "value", None) for p in parts]


@guarded
def on_time(e):
    current["t"] = float(e.delta)
    frames.append(dict(current))
    current["bones"] = {}


def on_receive_guarded(receiver, event, handler):
    """vmcp.facades.on_receive, but an event vmcp cannot build (a bone name that is no
    HumanBodyBones name raises in its parser) is recorded as an error, not lost in a log."""

    def build(*args):
        try:
            return handler(event.from_message_data(*args))
        except Exception as e:
            errors.append(f"{event.__name__}: {e!r}")

    b = receiver.system.backend
    receiver.register_handler(event.ADDRESS_PATTERN, build, b.ARG_READERNAME + b.ARG_ADDRESS + b.ARG_DATA)


osc = OSC(backend)
with osc.open():
    rx = osc.create_receiver("127.0.0.1", port, "frond").open()
    for event, handler in [(BoneTransformEvent, on_bone), (RootTransformEvent, on_root),
                           (StateEvent, on_state), (RelativeTimeEvent, on_time)]:
        on_receive_guarded(rx, event, handler)
    print("listening", flush=True)
    deadline = time.monotonic() + timeout
    while len(frames) < count and not errors and time.monotonic() < deadline:
        osc.run()
        time.sleep(0.001)
with open(out_path, "w") as out:
    for f in frames[:count]:
        out.write(json.dumps(f) + "\n")
if errors:
    print(f"vmcp refused the stream: {errors[:3]}", file=sys.stderr)
    sys.exit(1)
if len(frames) < count:
    print(f"timeout: {len(frames)} of {count} frames", file=sys.stderr)
    sys.exit(2)
