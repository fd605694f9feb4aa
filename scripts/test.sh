#!/usr/bin/env bash
# The test command: set up, lint, then run the fast test set (long campaigns are marked slow) on
# both cores.
# Pass -m "" to run everything, or any other pytest arguments.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if [[ "${AGRIHIL_NO_VENV:-0}" != "1" ]]; then source .venv/bin/activate; fi
ruff check .
# A machine that sets PYTHONDONTWRITEBYTECODE (this project's VMs do) makes every new
# interpreter the run starts (each hil qualify, DUT daemon, campaign sample: hundreds) compile
# every project module it imports again, and pytest rewrite the suites again: ~0.75 s of CPU
# per process (measured on a depth sample; tests/hil/reliability 50.6-53.1 -> 48.0 s CPU).
# The run keeps its bytecode in a cache of its own instead, outside the tree (as the variable
# wants: no .pyc beside the sources); a PYTHONPYCACHEPREFIX the user set is kept.
if [[ -n "${PYTHONDONTWRITEBYTECODE:-}" && -z "${PYTHONPYCACHEPREFIX:-}" ]]; then
    unset PYTHONDONTWRITEBYTECODE
    export PYTHONPYCACHEPREFIX="${XDG_CACHE_HOME:-$HOME/.cache}/agrihil/pycache"
fi
set +e
# both cores: pytest-xdist workers (AGRIHIL_TEST_WORKERS, default 3; 0 runs in this process),
# the longest tests handed out first (tests/conftest.py), the guest beside the host tests.
# Three workers on two cores, because much of the run waits rather than computes (real-time
# runs, the guest's boot, hil subprocesses, qualifications copied between docs units): on the
# 2-vCPU VM (speed index 132 ms) the same tree took 7:55 of pytest with 2 workers and 6:15
# with 3, both with 0 failures.
workers="${AGRIHIL_TEST_WORKERS:-3}"
parallel=()
if [[ "$workers" != "0" ]]; then parallel=(-n "$workers" --dist loadgroup); fi
python -m pytest -q -m "not slow" "${parallel[@]}" "$@"
status=$?
set -e
# pytest exits 5 when it collected no tests: that is a broken test run, say so
if [[ $status -eq 5 ]]; then echo "test.sh: pytest collected no tests" >&2; exit 1; fi
exit $status
