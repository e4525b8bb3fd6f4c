#!/usr/bin/env bash
# Installs eclipse-zenoh and msgpack into the tests' shared venv at tests/python/.venv, for the
# independent Python reader of frond's Zenoh stream (tests/e2e/stage_net.rs runs zenoh_reader.py).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
# shellcheck source=../../../tests/python/venv.sh
source "$root/tests/python/venv.sh"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$here/requirements.txt"
"$venv/bin/python" -c "import zenoh, msgpack; print('eclipse-zenoh', zenoh.__version__ if hasattr(zenoh, '__version__') else '', 'and msgpack installed in $venv')"
