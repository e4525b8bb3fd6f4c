#!/usr/bin/env python3
"""frond's Blender add-on's field side without Blender: its `Receiver` (exporters/osc/blender/
frond_receiver.py, numpy only) listens on UDP for frond-osc, puts each running field together
(definition, layout chunks, field frames) and evaluates every plant with its port of
`frond_motion::field_eval`. For --updates field frames once every plant of --report can be
evaluated, prints one JSON line a plant: {"seq", "tau", "plant", "plants", "angles" (12)}, for
the Rust test to compare with the SDK's evaluation of the same frame. Prints `port N` when
listening. Exit 0 on success, 1 on a timeout.
"""

import argparse
import json
import os
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "blender"))
import frond_receiver as fr  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--report", required=True, help="plants to report, comma-separated")
    ap.add_argument("--updates", type=int, default=8)
    ap.add_argument("--timeout", type=float, default=60)
    args = ap.parse_args()
    report = [int(p) for p in args.report.split(",")]
    receiver = fr.Receiver("127.0.0.1", 0)
    print(f"port {receiver.port}", flush=True)
    deadline = time.monotonic() + args.timeout
    seen = set()
    while len(seen) < args.updates:
        if time.monotonic() > deadline:
            state = [(f.definition.plants, len(f.chunks), f.eval is not None, f.frames)
                     for f in receiver.fields.fields.values()]
            print(f"timeout: {len(seen)} of {args.updates} updates; fields {state}; "
                  f"malformed {receiver.malformed}, refused {receiver.fields.refused}", file=sys.stderr)
            sys.exit(1)
        receiver.poll()
        fields = receiver.fields.evaluated()
        if len(fields) != 1 or fields[0].frame["seq"] in seen:
            time.sleep(0.002)
            continue
        field = fields[0]
        angles, ok = field.eval.evaluate(field.frame["tau"])
        if not all(ok[p] for p in report):
            continue  # the history does not reach back far enough yet
        seen.add(field.frame["seq"])
        for p in report:
            line = {"seq": field.frame["seq"], "tau": field.frame["tau"], "plant": p,
                    "plants": field.definition.plants, "angles": [float(a) for a in angles[p]]}
            print(json.dumps(line), flush=True)
    receiver.close()


if __name__ == "__main__":
    main()
