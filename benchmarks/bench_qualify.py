"""Total wall time of the default qualification of one DUT, lockstep (``hil qualify``).

Runs ``hil qualify PROFILE --bus BUS --out TMP`` (default suites ``fast,robustness``, lockstep)
as a subprocess, one round per case, and prints its wall time: the whole command, from the
interpreter's start to the report (the firmware's build is done, cached, before the timing);
then the suites' time by ``record.json`` (pytest session, without start-up and report.html)
and the sum of its scenario runs' wall times (what lockstep speed can still win).
Issue 7's target: < 60 s per DUT (printed, never asserted)::

    python -m pytest benchmarks/bench_qualify.py -s -p no:cacheprovider
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest

from hil.dut.build import ensure_built
from hil.dut.profile import load_profile

ROOT = Path(__file__).resolve().parents[1]
PROFILES = ROOT / "dut_profiles"
#: case -> (profile, bus)
CASES = {
    "daemon-softbus": (PROFILES / "fertilizer-piecewise-pid-daemon.toml", "softbus"),
    "firmware-softbus": (PROFILES / "fertilizer-piecewise-pid-firmware.toml", "softbus"),
    "daemon-inline": (PROFILES / "fertilizer-piecewise-pid-daemon.toml", "inline"),
}
TARGET_S = 60.0
TIMEOUT_S = 600.0


@pytest.mark.parametrize("case", list(CASES))
def test_default_qualification_wall_time(benchmark: Any, timed_rounds: Any, case: str) -> None:
    """Wall time of ``hil qualify`` (default suites, lockstep) for one DUT on one bus."""
    path, bus = CASES[case]
    profile = load_profile(path)
    if profile.build is not None and bus != "inline":
        if shutil.which("cmake") is None or not any(
                shutil.which(cc) for cc in ("cc", "gcc", "clang")):
            pytest.skip(f"{profile.name} needs a host build: cmake or a C compiler is missing")
        ensure_built(profile)                             # build (or find cached) untimed
    results: dict[str, Any] = {}

    def qualify() -> None:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(path),
                                   "--bus", bus, "--out", str(out), "--quiet"],
                                  cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT_S,
                                  check=False)
            results["proc"] = proc
            record = out / "record.json"
            results["record"] = json.loads(record.read_text()) if record.exists() else None

    benchmark.pedantic(qualify, rounds=1, iterations=1)
    proc, record = results["proc"], results["record"]
    assert record is not None, proc.stdout[-2000:] + proc.stderr[-2000:]
    wall = timed_rounds()[0]
    verdict = record["verdict"]
    suites_s = record.get("wall_s")
    benchmark.extra_info.update(wall_s=round(wall, 2), verdict=verdict, suites_wall_s=suites_s,
                                exit_code=proc.returncode, target_s=TARGET_S,
                                loadavg=os.getloadavg())
    runs = record.get("runs", [])
    runs_wall, runs_sim = (sum(r["wall_s"] for r in runs), sum(r["sim_s"] for r in runs))
    benchmark.extra_info.update(scenario_runs=len(runs), runs_wall_s=round(runs_wall, 2),
                                runs_sim_s=round(runs_sim, 1))
    inner = (f", suites {suites_s:.1f} s by the record, of which {len(runs)} scenario runs "
             f"{runs_wall:.1f} s for {runs_sim:.0f} s simulated" if suites_s is not None else "")
    print(f"\nhil qualify {path.name} --bus {bus} (default suites, lockstep): {wall:.1f} s "
          f"wall{inner}, {verdict.upper()} (target < {TARGET_S:.0f} s; load "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())})")
    last = proc.stderr.strip().splitlines()[-1:] if proc.stderr else []
    if last:
        print(f"  {last[0]}")
