#!/usr/bin/env bash
# Installs the Khronos glTF validator (npm package gltf-validator, pinned in package-lock.json)
# into exporters/gltf/tests/node_modules for frond-gltf's tests (tests/validator.rs runs
# validate.mjs with node). Needs node and npm (Debian: apt-get install nodejs npm).
#
# Without node or the package the validator tests skip with a message, unless CI=true or
# FROND_REQUIRE_TOOLS=1, where they fail.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
cd "$here"
if ! command -v npm >/dev/null 2>&1; then
    if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = "0" ]; then
        echo "installing node and npm (apt-get)"
        (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm) >/dev/null
    else
        echo "error: npm not found; install node and npm" >&2
        exit 1
    fi
fi
if [ -f package-lock.json ]; then
    npm ci --no-audit --no-fund --loglevel=error
else
    npm install --no-audit --no-fund --loglevel=error
fi
node -e 'import("gltf-validator").then((v) => console.log("gltf-validator", v.default.version()))'
