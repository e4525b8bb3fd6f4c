#!/usr/bin/env bash
# Installs Debian's Chromium and ChromeDriver for frond-warp's headless-browser test
# (exporters/warp/tests/browser.rs). Idempotent: does nothing when both are already present.
# Called by scripts/test; needs root (or sudo) and Debian's package registry.
set -euo pipefail

have() { command -v "$1" >/dev/null 2>&1; }

if have chromium && have chromedriver; then
    echo "install-browser: chromium and chromedriver already present ($(chromium --version 2>/dev/null | head -n1))"
    exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
    if have sudo; then SUDO="sudo"; else
        echo "install-browser: need root (or sudo) to apt-get install chromium chromium-driver" >&2
        exit 1
    fi
fi

export DEBIAN_FRONTEND=noninteractive
# apt can be busy with another install on a shared machine: retry a few times.
for attempt in 1 2 3 4 5; do
    if $SUDO apt-get update -qq && $SUDO apt-get install -y -qq chromium chromium-driver; then
        break
    fi
    if [ "$attempt" -eq 5 ]; then
        echo "install-browser: apt-get failed after $attempt attempts" >&2
        exit 1
    fi
    echo "install-browser: apt-get failed (attempt $attempt), retrying in 10 s" >&2
    sleep 10
done

have chromium && have chromedriver || { echo "install-browser: chromium/chromedriver still missing after install" >&2; exit 1; }
echo "install-browser: installed $(chromium --version 2>/dev/null | head -n1)"
