#!/usr/bin/env bash
# Build the documentation site from docs/ into docs/_build/html, warnings as errors.
# Extra arguments go to sphinx-build (e.g. -b linkcheck).
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ "${AGRIHIL_NO_VENV:-0}" != "1" ]]; then
    [[ -x .venv/bin/python ]] || bash scripts/setup.sh
    # shellcheck disable=SC1091
    source .venv/bin/activate
fi
exec python -m sphinx -W --keep-going -E -b html docs docs/_build/html "$@"
