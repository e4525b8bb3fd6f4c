#!/usr/bin/env bash
# Installs frond-hands, the webcam hand source's landmark helper: a Python venv with the pinned
# packages of requirements.txt (MediaPipe Hands 0.10.21, whose wheel carries the hand models;
# nothing is downloaded when it runs) and a launcher, `frond-hands`, that frondd's `webcam`
# source starts. Needs CPython 3.9 to 3.12 (mediapipe 0.10.21 has wheels for those; x86_64 or
# aarch64 Linux).
#
# Usage: daemon/device/webcam/install.sh [--venv DIR] [--link DIR | --no-link]
#   --venv DIR   where the venv goes (default ${XDG_DATA_HOME:-~/.local/share}/frond/hands-venv)
#   --link DIR   where the `frond-hands` command is linked (default ~/.local/bin), so frondd
#                finds it on PATH; or set FROND_HANDS to the launcher the script prints.
# PYTHON picks the interpreter (default python3.11, else python3).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="${XDG_DATA_HOME:-$HOME/.local/share}/frond/hands-venv"
link="$HOME/.local/bin"
while [ $# -gt 0 ]; do
    case "$1" in
        --venv) venv="$2"; shift 2 ;;
        --link) link="$2"; shift 2 ;;
        --no-link) link=""; shift ;;
        *) echo "install.sh: unknown argument $1 (see the comment at the top)" >&2; exit 2 ;;
    esac
done
if [ ! -x "$venv/bin/python" ]; then
    python="${PYTHON:-}"
    if [ -z "$python" ]; then
        if command -v python3.11 >/dev/null 2>&1; then python=python3.11; else python=python3; fi
    fi
    echo "creating $venv with $($python --version 2>&1)"
    mkdir -p "$(dirname "$venv")"
    "$python" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps -r "$here/requirements.txt"
launcher="$venv/bin/frond-hands"
cat >"$launcher" <<LAUNCH
#!/bin/sh
exec "$venv/bin/python" "$here/frond_hands.py" "\$@"
LAUNCH
chmod +x "$launcher"
# The models must be inside the package: the helper never fetches one.
"$venv/bin/python" - <<'CHECK'
import os, mediapipe
root = os.path.dirname(mediapipe.__file__)
for model in ("modules/palm_detection/palm_detection_full.tflite", "modules/hand_landmark/hand_landmark_full.tflite"):
    path = os.path.join(root, model)
    assert os.path.getsize(path) > 1_000_000, path
print("mediapipe", mediapipe.__version__, "with its hand models in", root)
CHECK
if [ -n "$link" ]; then
    mkdir -p "$link"
    ln -sf "$launcher" "$link/frond-hands"
    echo "frond-hands installed: $link/frond-hands -> $launcher"
    case ":$PATH:" in *":$link:"*) ;; *) echo "note: $link is not on PATH; add it, or run frondd with FROND_HANDS=$launcher" ;; esac
else
    echo "frond-hands installed: $launcher (frondd finds it with FROND_HANDS=$launcher)"
fi
