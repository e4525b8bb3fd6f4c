# Sourced by the exporters' install scripts: creates (or reuses) the one Python venv of frond's
# tests at tests/python/.venv and sets $venv to it. Each script then installs only its own
# packages into it. PYTHON picks the interpreter (default: python3.11, else python3).
# shellcheck shell=bash
venv="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/.venv"
if [ ! -x "$venv/bin/python" ]; then
    python="${PYTHON:-}"
    if [ -z "$python" ]; then
        if command -v python3.11 >/dev/null 2>&1; then python=python3.11; else python=python3; fi
    fi
    echo "creating $venv with $($python --version 2>&1)"
    "$python" -m venv "$venv"
fi
