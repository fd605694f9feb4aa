"""What bus conformance adds to a qualification's wall time (issue 17's target: < 5 %).

Runs ``hil qualify PROFILE --bus BUS`` (default suites, lockstep) once as a subprocess; the
plugin computes conformance for every run in it. Then times, in this process, the same
computation over every run directory of that qualification (``run_conformance`` on each run's
``bus.log`` and record, the databases' caches cleared first so each round pays what one
qualification pays) and prints it as a share of the qualification's wall time without it::

    python -m pytest benchmarks/bench_conformance.py -s -p no:cacheprovider
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from hil.conformance import declared, run_conformance
from hil.dut.build import ensure_built
from hil.dut.profile import load_profile
from hil.rig import load_rig

ROOT = Path(__file__).resolve().parents[1]
PROFILES = ROOT / "dut_profiles"
#: case -> (profile, bus)
CASES = {
    "fertilizer-daemon-inline": (PROFILES / "fertilizer-piecewise-pid-daemon.toml", "inline"),
    "fertilizer-firmware-softbus": (PROFILES / "fertilizer-piecewise-pid-firmware.toml",
                                    "softbus"),
    "depth-firmware-softbus": (PROFILES / "sowing-depth-fuzzy-pid-firmware.toml", "softbus"),
}
TARGET_PCT = 5.0


@pytest.fixture(scope="module")
def qualifications() -> Iterator[dict[str, tuple[float, Path, dict[str, Any]]]]:
    """case -> (wall time of ``hil qualify``, its output directory, its record)."""
    done: dict[str, tuple[float, Path, dict[str, Any]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        def qualify(case: str) -> tuple[float, Path, dict[str, Any]]:
            if case not in done:
                path, bus = CASES[case]
                out = Path(tmp) / case
                start = time.perf_counter()
                proc = subprocess.run([sys.executable, "-m", "hil", "qualify", str(path),
                                       "--bus", bus, "--out", str(out), "--quiet"], cwd=ROOT,
                                      capture_output=True, text=True, timeout=900, check=False)
                wall = time.perf_counter() - start
                record_path = out / "record.json"
                assert record_path.exists(), proc.stdout[-2000:] + proc.stderr[-2000:]
                done[case] = (wall, out, json.loads(record_path.read_text()))
            return done[case]
        yield qualify  # type: ignore[misc]


@pytest.mark.parametrize("case", list(CASES))
def test_conformance_share_of_a_qualification(benchmark: Any, timed_rounds: Any,
                                              qualifications: Any, case: str) -> None:
    path, bus = CASES[case]
    profile = load_profile(path)
    if profile.build is not None and bus != "inline":
        if shutil.which("cmake") is None or not any(
                shutil.which(cc) for cc in ("cc", "gcc", "clang")):
            pytest.skip(f"{profile.name} needs a host build: cmake or a C compiler is missing")
        ensure_built(profile)                             # build (or find cached) untimed
    wall, out, record = qualifications(case)
    rig = load_rig(profile.dut.rig)
    # the DUT's runs (a comparison suite's baseline runs are another controller's)
    runs = [out / r["dir"] for r in record["runs"]
            if (out / r["dir"] / "conformance.json").exists()]
    measured = [m for m in record["measurements"] if m["name"].startswith("bus.")]
    assert runs and measured, "the qualification recorded no conformance"
    found: dict[str, int] = {}

    def conformance() -> None:
        declared._load_dbc.cache_clear()
        declared._eds.cache_clear()
        n = 0
        for run_dir in runs:
            run_record = json.loads((run_dir / "record.json").read_text())
            n += len(run_conformance(run_record, run_dir, profile,
                                     physics_period_s=rig.physics_period_s).measurements)
        found["n"] = n

    benchmark.pedantic(conformance, rounds=3, iterations=1)
    assert found["n"] == len(measured), (found["n"], len(measured))
    cost = min(timed_rounds())
    share = 100.0 * cost / (wall - cost)
    benchmark.extra_info.update(qualify_wall_s=round(wall, 2), conformance_s=round(cost, 3),
                                share_pct=round(share, 2), runs=len(runs),
                                measurements=len(measured), loadavg=os.getloadavg())
    print(f"\n{case}: conformance of {len(runs)} runs ({len(measured)} measurements) "
          f"{cost * 1000:.0f} ms; hil qualify {wall:.1f} s wall: +{share:.2f} % "
          f"(target < {TARGET_PCT:g} %; load "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())})")
