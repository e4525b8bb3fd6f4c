#!/usr/bin/env bash
# Creates (or reuses) the Python venv of frond-osc's end-to-end tests at tests/python/.venv
# (relative to the repository root) and installs exporters/osc/tests/requirements*.txt into it.
#
# Usage: exporters/osc/tests/install-python.sh
#   FROND_SKIP_BLENDER=1  do not install bpy (the Blender test then skips, or fails when required)
#   PYTHON=python3.11     interpreter to create the venv with (default: python3.11, else python3)
#
# The Rust tests find the venv at tests/python/.venv/bin/python; without it they skip with a
# message, unless CI=true or FROND_REQUIRE_PYTHON=1, where they fail.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
# shellcheck source=../../../tests/python/venv.sh
source "$root/tests/python/venv.sh"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements.txt"
echo "python-osc installed in $venv"

if [ "${FROND_SKIP_BLENDER:-0}" = "1" ]; then
    echo "FROND_SKIP_BLENDER=1: not installing bpy"
    exit 0
fi
if "$venv/bin/python" -c "import bpy" >/dev/null 2>&1; then
    echo "bpy already installed"
    exit 0
fi
# bpy (Blender as a module) needs a few X/GL client libraries even headless.
if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = "0" ]; then
    missing=""
    for lib in libx11-6 libxrender1 libxxf86vm1 libxfixes3 libxi6 libxkbcommon0 libsm6 libgl1 libegl1 libwayland-client0; do
        dpkg -s "$lib" >/dev/null 2>&1 || missing="$missing $lib"
    done
    if [ -n "$missing" ]; then
        echo "installing system libraries for bpy:$missing"
        (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing) >/dev/null ||
            echo "warning: could not install$missing" >&2
    fi
fi
if "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements-blender.txt"; then
    if "$venv/bin/python" -c "import bpy; print('bpy', bpy.app.version_string)"; then
        exit 0
    fi
fi
echo "warning: bpy could not be installed or imported; the Blender test will skip (or fail under CI)" >&2
if [ "${CI:-}" = "true" ] || [ "${FROND_REQUIRE_PYTHON:-0}" = "1" ]; then
    exit 1
fi
