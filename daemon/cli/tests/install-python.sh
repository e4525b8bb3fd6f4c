#!/usr/bin/env bash
# Installs Pixar's usd-core (the reference USD library, from PyPI) into the tests' shared venv at
# tests/python/.venv, for daemon/cli/tests/usd.rs (`frond take export --usd` read back by
# usd-core; Blender's USD importer comes with bpy, installed by exporters/osc/tests/install-python.sh).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
# shellcheck source=../../../tests/python/venv.sh
source "$root/tests/python/venv.sh"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements.txt"
echo "usd-core installed in $venv"
