#!/usr/bin/env bash
# Creates (or reuses) the shared Python venv of frond's tests at tests/python/.venv (relative to
# the repository root) and installs frond-gltf's read-back requirements (pygltflib) into it.
# Other crates install their own packages into the same venv; this script only adds its own.
#
# Usage: exporters/gltf/tests/install-python.sh
#   PYTHON=python3.11   interpreter to create the venv with (default: python3.11, else python3)
#
# Without the venv or pygltflib the read-back test skips with a message, unless CI=true or
# FROND_REQUIRE_TOOLS=1, where it fails.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
# shellcheck source=../../../tests/python/venv.sh
source "$root/tests/python/venv.sh"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements.txt"
"$venv/bin/python" -c 'import pygltflib; print("pygltflib", pygltflib.__version__, "installed in '"$venv"'")'
