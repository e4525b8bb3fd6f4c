#!/usr/bin/env bash
# Installs the warp benchmark's Python tools (numpy, OpenCV headless) into tests/python/.venv,
# keeping numpy at the version the other exporters' tools (bpy) use.
set -euo pipefail
cd "$(dirname "$0")/../../.."
[ -x tests/python/.venv/bin/python ] || python3 -m venv tests/python/.venv
tests/python/.venv/bin/pip install -q "numpy==1.26.4" "opencv-python-headless==4.11.0.86"
