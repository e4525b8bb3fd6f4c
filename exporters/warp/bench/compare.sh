#!/usr/bin/env bash
# Warp time per 1920x1080 RGBA frame, frond-warp against OpenCV's cv2.remap (bilinear, replicated
# border, one thread) on the same frame and displacement field, alternating the two ROUNDS times in
# one run so that both see the same machine load. Prints one line per measurement and the ratios
# (cv2 time / ours: above 1 means frond-warp is faster).
#
# Usage: exporters/warp/bench/compare.sh [ROUNDS] [ITERATIONS]
# Needs a release build (cargo build --release -p frond-warp) and numpy + opencv-python-headless in
# $PYTHON (default tests/python/.venv/bin/python; exporters/warp/bench/install-python.sh installs them).
set -euo pipefail
cd "$(dirname "$0")/../../.."
ROUNDS=${1:-5}
ITERS=${2:-30}
PYTHON=${PYTHON:-tests/python/.venv/bin/python}
BIN=target/release/frond-warp
DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT
"$BIN" bench --json --pipeline-frames 0 --iterations 1 --write-field "$DIR" >/dev/null
for r in $(seq "$ROUNDS"); do
    "$BIN" bench --json --pipeline-frames 0 --iterations "$ITERS" >"$DIR/ours.$r.json"
    "$PYTHON" exporters/warp/bench/remap.py "$DIR" --iterations "$ITERS" >"$DIR/cv2.$r.json"
done
"$PYTHON" - "$DIR" "$ROUNDS" <<'PY'
import json, statistics, sys
d, n = sys.argv[1], int(sys.argv[2])
rows = []
for r in range(1, n + 1):
    o = json.load(open(f"{d}/ours.{r}.json"))["warp"]
    c = json.load(open(f"{d}/cv2.{r}.json"))
    rows.append((o, c))
    print(f"round {r}: frond-warp ({o['kernel']}) median {o['median_ms']:.2f} ms, min {o['min_ms']:.2f} ms, "
          f"cpu {o['median_cpu_ms']:.2f} ms | cv2.remap ({c['opencv']}, {c['threads']} thread) median "
          f"{c['median_ms']:.2f} ms, min {c['min_ms']:.2f} ms, cpu {c['median_cpu_ms']:.2f} ms | "
          f"max diff {c['max_abs_diff_vs_frond']}")
def ratio(key):
    return statistics.median(c[key] / o[key] for o, c in rows)
print(f"cv2/ours (median over rounds): median-time {ratio('median_ms'):.2f}x, min-time {ratio('min_ms'):.2f}x, "
      f"cpu-time {ratio('median_cpu_ms'):.2f}x")
PY
