#!/usr/bin/env bash
# Renders the README's live picture (docs/live.png; see docs/render_live.py): frondd on the
# virtual glove plays a field of grass (`frond field start`) while frond-osc streams the frond
# namespace to frond's Blender add-on and the VMC protocol to the VMC4B add-on, both in one
# Blender (bpy from tests/python/.venv), which renders the pose after SECONDS (default 4).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -q -p frondd -p frond-cli -p frond-gltf -p frond-osc
tmp="$(mktemp -d)"
pids=()
trap 'kill "${pids[@]}" 2>/dev/null; rm -rf "$tmp"' EXIT
export FROND_SOCKET_DIR="$tmp/run" FROND_TAKES_DIR="$tmp/takes"
target/debug/frond take simulate gust --rig grass --wind speed=7,dir=0,gust=0.6,seed=3 --duration 6
target/debug/frond take simulate bloom --rig flower --wind speed=3,dir=0,gust=0.2,seed=1 --duration 1
target/debug/frond take field gust --rows 2 --cols 3 --cell 0.6 --speed 1.5 --seed 2 -o "$tmp/field.json"
target/debug/frond-gltf bake -q --rig grass --take gust --field "$tmp/field.json" --duration 1 -o "$tmp/field.glb"
target/debug/frond-gltf bake -q --rig flower --take bloom -o "$tmp/flower.glb"
target/debug/frondd --source in-process --rig grass --log-level warn & pids+=($!)
for _ in $(seq 100); do [ -S "$tmp/run/control.sock" ] && break; sleep 0.05; done
target/debug/frond field start --take gust --field "$tmp/field.json" --plants 6
coproc BLENDER { tests/python/.venv/bin/python docs/render_live.py "$tmp/field.glb" "$tmp/flower.glb" \
    "$PWD/docs/live.png" "${1:-4}" 2>&1; }
pids+=("$BLENDER_PID")
while read -r line <&"${BLENDER[0]}"; do
    case "$line" in
        ports\ *) set -- $line; break ;;
    esac
done
target/debug/frond-osc --target "127.0.0.1:$2" & pids+=($!)
target/debug/frond-osc --protocol vmc --target "127.0.0.1:$3" & pids+=($!)
cat <&"${BLENDER[0]}"
