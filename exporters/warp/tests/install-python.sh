#!/usr/bin/env bash
# Installs shapely (GEOS) into the tests' shared venv at tests/python/.venv: the independent judge
# of `frond-warp cage build` output (validity, orientation, containment, areas) in
# exporters/warp/tests/cage_check.py. numpy stays at the version bpy uses.
set -euo pipefail
source "$(dirname "$0")/../../../tests/python/venv.sh"
"$venv/bin/python" -m pip install -q --disable-pip-version-check "numpy==1.26.4" "shapely==2.1.1"
echo "shapely installed in $venv"
