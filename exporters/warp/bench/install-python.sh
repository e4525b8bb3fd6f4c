#!/usr/bin/env bash
# Installs the warp benchmark's Python tools (numpy, OpenCV headless) into tests/python/.venv,
# keeping numpy at the version the other exporters' tools (bpy) use.
set -euo pipefail
source "$(dirname "$0")/../../../tests/python/venv.sh"
"$venv/bin/python" -m pip install -q "numpy==1.26.4" "opencv-python-headless==4.11.0.86"
