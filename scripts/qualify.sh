#!/usr/bin/env bash
# The main job: set up, then qualify the reference controller on the embedded software bus
# and write the report into out/ (see README).
set -euo pipefail
cd "$(dirname "$0")/.."
# setuptools' "Editable installation" warning says a folder named like the package in the
# working directory may take precedence on import; in an editable install from the project's
# root that folder is the package itself, so the block only alarms a new user (issue 31.7)
PYTHONWARNINGS="${PYTHONWARNINGS:+$PYTHONWARNINGS,}ignore:Editable installation" \
    bash scripts/setup.sh
if [[ "${AGRIHIL_NO_VENV:-0}" != "1" ]]; then source .venv/bin/activate; fi
exec hil qualify dut_profiles/fertilizer-piecewise-pid-daemon.toml --bus softbus --out out "$@"
