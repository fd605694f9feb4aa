#!/usr/bin/env bash
# The main job: set up, then qualify the reference controller on the embedded software bus
# and write the report into out/ (see README).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [[ "${AGRIHIL_NO_VENV:-0}" != "1" ]]; then source .venv/bin/activate; fi
exec hil qualify dut_profiles/fertilizer-piecewise-pid-daemon.toml --bus softbus --out out "$@"
