#!/usr/bin/env bash
# Install agrihil and its test tools from the project's own files (pyproject.toml).
# Idempotent; uses a virtualenv at .venv unless AGRIHIL_NO_VENV=1 (then the current Python).
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ "${AGRIHIL_NO_VENV:-0}" != "1" ]]; then
    if [[ ! -x .venv/bin/python ]]; then
        python3 -m venv .venv
    fi
    # shellcheck disable=SC1091
    source .venv/bin/activate
fi
python -m pip install --quiet --upgrade pip
python -m pip install --quiet -e '.[dev]'
