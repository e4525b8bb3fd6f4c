#!/usr/bin/env bash
# Renders the README's morph picture (docs/morph.png): the sample shrub morphed towards the heart
# sketch rig-files/images/shrub-heart-sketch.json, frames t = 0, 0.5 and 1 side by side.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p frond-warp
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
target/debug/frond-warp morph --image rig-files/images/shrub-background.png \
    --layer rig-files/images/shrub.png --sketch rig-files/images/shrub-heart-sketch.json \
    --frames 3 -o "$tmp/" --report "$tmp/quality.json" --quiet
python3 docs/morph_strip.py docs/morph.png "$tmp"/frame_0000{0,1,2}.png
cat "$tmp/quality.json"; echo
