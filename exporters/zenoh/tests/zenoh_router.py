#!/usr/bin/env python3
"""Runs a Zenoh router from a zenohd configuration file (frond's exporters/zenoh/config/router.json5)
in Zenoh's own runtime, eclipse-zenoh, which is the runtime zenohd wraps: the file is read as zenohd
reads it, and nothing in it is changed. Prints `routing <zid>` once the router listens, then routes
until its standard input closes or it is killed (tests/e2e/stage_router.rs).

  zenoh_router.py exporters/zenoh/config/router.json5
"""

import sys

import zenoh


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    config = zenoh.Config.from_file(sys.argv[1])
    session = zenoh.open(config)
    print(f"routing {session.zid()}", flush=True)
    sys.stdin.read()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
