#!/usr/bin/env bash
# Renders the README's hand-driven cage picture (docs/bend.png): hand samples (wrist yaw +80, 0,
# -80 degrees, one second each) mapped onto the shrub rig by `frond take import`, exactly as the
# daemon maps a glove, then `frond-warp render --mode cage` bends the sample shrub's crown cage by
# the skeleton: the three poses side by side.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p frond-cli -p frond-warp
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
python3 - > "$tmp/hand.jsonl" <<'PY'
import json
for i in range(301):
    t = i / 100
    yaw = 80 if t < 1 else (0 if t < 2 else -80)
    print(json.dumps({"t": t, "wrist": [0, yaw, 0], "thumb": [70, 70, 50]}))
PY
target/debug/frond take import "$tmp/hand.jsonl" bend --rig shrub --kind hand --filter none \
    --takes-dir "$tmp"
target/debug/frond-warp render --mode cage --image rig-files/images/shrub-background.png \
    --layer rig-files/images/shrub.png --take "$tmp/bend.take" --frames 3 --fps 1 -o "$tmp/out/" --quiet
python3 docs/morph_strip.py docs/bend.png "$tmp"/out/frame_0000{0,1,2}.png
