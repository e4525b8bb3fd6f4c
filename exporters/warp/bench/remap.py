#!/usr/bin/env python3
"""Times OpenCV's cv2.remap (bilinear) on the frame and displacement field written by
`frond-warp bench --write-field DIR`, and compares its output with frond-warp's.

Usage: python3 exporters/warp/bench/remap.py DIR [--iterations N]
Prints one JSON object: median/min milliseconds per frame (single thread; wall time and this
thread's CPU time, which on a shared machine leaves out time other processes held the core), whether
OpenCV was really limited to one thread, and the largest and
mean absolute difference per channel value between cv2's output and ours (`ours.rgba`).
Needs numpy and opencv-python-headless (installed in the bench's Python environment).
"""
import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

try:
    import cv2
except ImportError:
    sys.exit("remap.py: OpenCV is not installed (pip install opencv-python-headless)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--iterations", type=int, default=20)
    args = ap.parse_args()
    with open(os.path.join(args.dir, "meta.json")) as f:
        meta = json.load(f)
    w, h = meta["width"], meta["height"]
    src = np.fromfile(os.path.join(args.dir, "src.rgba"), dtype=np.uint8).reshape(h, w, 4)
    ours = np.fromfile(os.path.join(args.dir, "ours.rgba"), dtype=np.uint8).reshape(h, w, 4)
    map_x = np.fromfile(os.path.join(args.dir, "map_x.f32"), dtype="<f4").reshape(h, w)
    map_y = np.fromfile(os.path.join(args.dir, "map_y.f32"), dtype="<f4").reshape(h, w)
    cv2.setNumThreads(1)  # single thread, like frond-warp's timing
    if cv2.getNumThreads() != 1:
        sys.exit(f"remap.py: OpenCV still uses {cv2.getNumThreads()} threads after setNumThreads(1)")
    out = cv2.remap(src, map_x, map_y, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    times, cpu = [], []
    for _ in range(max(1, args.iterations)):
        t, c = time.perf_counter(), time.thread_time()
        cv2.remap(src, map_x, map_y, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE, dst=out)
        times.append((time.perf_counter() - t) * 1e3)
        cpu.append((time.thread_time() - c) * 1e3)
    diff = np.abs(out.astype(np.int16) - ours.astype(np.int16))
    print(json.dumps({
        "impl": "cv2.remap INTER_LINEAR BORDER_REPLICATE",
        "opencv": cv2.__version__,
        "width": w,
        "height": h,
        "threads": cv2.getNumThreads(),
        "iterations": len(times),
        "median_ms": statistics.median(times),
        "min_ms": min(times),
        "median_cpu_ms": statistics.median(cpu),
        "max_abs_diff_vs_frond": int(diff.max()),
        "mean_abs_diff_vs_frond": float(diff.mean()),
    }))


if __name__ == "__main__":
    main()
