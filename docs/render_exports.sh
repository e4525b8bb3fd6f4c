#!/usr/bin/env bash
# Renders the README's export picture (docs/exports.png): one simulated take of the flower (with
# its leaf layer) baked by frond-gltf and exported by `frond take export --bvh` and `--usd`, each
# file opened by Blender's own importer and rendered side by side at the same frame: the three
# poses agree (the tests daemon/cli/tests/bvh.rs and usd.rs check that at every frame).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p frond-cli -p frond-gltf
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
export FROND_TAKES_DIR="$tmp"
target/debug/frond take simulate gust --rig flower --wind speed=7,dir=0,gust=0.6,seed=3 --duration 4
target/debug/frond-gltf bake --take gust --rig flower --fps 30 -o "$tmp/gust.glb"
target/debug/frond take export gust --bvh --fps 30 -o "$tmp/gust.bvh"
target/debug/frond take export gust --usd --fps 30 -o "$tmp/gust.usda"
tests/python/.venv/bin/python docs/render_exports.py "$tmp/gust.glb" "$tmp/gust.bvh" \
    "$tmp/gust.usda" "$PWD/docs/exports.png" "${1:-75}"
