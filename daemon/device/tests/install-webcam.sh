#!/usr/bin/env bash
# Installs frond-hands (MediaPipe Hands, pinned) for the webcam tests into tests/python/.venv-hands,
# a venv of its own (mediapipe 0.10.21 needs numpy < 2, which other test tools may not want).
# tests/e2e/webcam.rs starts it through FROND_HANDS=tests/python/.venv-hands/bin/frond-hands.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
bash "$root/daemon/device/webcam/install.sh" --venv "$root/tests/python/.venv-hands" --no-link
# A real hand to test the model on: the photographs inside the npm package fingerpose 0.1.0
# (MIT, (c) 2020 Andreas Schallwig): assets/nocurl.jpg, a hand with its index finger up.
assets="$root/tests/python/.venv-hands/fingerpose"
if [ ! -f "$assets/package/assets/nocurl.jpg" ]; then
    mkdir -p "$assets"
    (cd "$assets" && npm pack --silent fingerpose@0.1.0 >/dev/null && tar xzf fingerpose-0.1.0.tgz)
fi
echo "test photographs of a hand: $assets/package/assets"
