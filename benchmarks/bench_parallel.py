"""Several DUTs qualified at once: wall time one after the other against all at once.

Runs ``hil qualify PROFILE --bus softbus`` (default suites, lockstep) for the fertilizer and
the sowing-depth reference daemons, first one after the other, then both at once as two
processes (each with its own embedded software bus on its own port), and prints the wall
times and each run's verdict. On the 2-core machine the gain is what the second core buys; the
measurements must not change (the runs share no state): the test checks that both verdicts
are PASS both ways and that the judged values agree::

    python -m pytest benchmarks/bench_parallel.py -s -p no:cacheprovider
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
PROFILES = [ROOT / "dut_profiles" / "fertilizer-piecewise-pid-daemon.toml",
            ROOT / "dut_profiles" / "sowing-depth-fuzzy-pid-daemon.toml"]
TIMEOUT_S = 900.0


def _start(profile: Path, out: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "hil", "qualify", str(profile), "--bus",
                             "softbus", "--out", str(out), "--quiet"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(proc: subprocess.Popen[str], out: Path) -> dict[str, Any]:
    stdout, stderr = proc.communicate(timeout=TIMEOUT_S)
    record = out / "record.json"
    assert record.exists(), f"exit {proc.returncode}: {stdout[-1500:]}{stderr[-1500:]}"
    return json.loads(record.read_text())


def _values(record: dict[str, Any]) -> dict[str, Any]:
    """Every judged value, keyed by its name and conditions (a name repeats per condition)."""
    values = {(m["name"], json.dumps(m.get("conditions"), sort_keys=True)): m.get("value")
              for m in record["measurements"]}
    assert values, "a qualification without measurements"
    return values


def test_several_duts_at_once(benchmark: Any) -> None:
    results: dict[str, Any] = {}

    def both_ways() -> None:
        with tempfile.TemporaryDirectory() as tmp:
            base = Path(tmp)
            t0 = time.perf_counter()
            serial = []
            for i, profile in enumerate(PROFILES):
                out = base / f"serial-{i}"
                serial.append(_finish(_start(profile, out), out))
            t1 = time.perf_counter()
            outs = [base / f"parallel-{i}" for i in range(len(PROFILES))]
            procs = [_start(p, o) for p, o in zip(PROFILES, outs, strict=True)]
            parallel = [_finish(p, o) for p, o in zip(procs, outs, strict=True)]
            t2 = time.perf_counter()
            results.update(serial=serial, parallel=parallel, serial_s=t1 - t0,
                           parallel_s=t2 - t1)

    benchmark.pedantic(both_ways, rounds=1, iterations=1)
    serial_s, parallel_s = results["serial_s"], results["parallel_s"]
    verdicts = [r["verdict"] for r in results["serial"] + results["parallel"]]
    benchmark.extra_info.update(serial_s=round(serial_s, 1), parallel_s=round(parallel_s, 1),
                                verdicts=verdicts, cpus=os.cpu_count())
    print(f"\n{len(PROFILES)} DUTs qualified on the software bus: one after the other "
          f"{serial_s:.1f} s, at once {parallel_s:.1f} s (x{serial_s / parallel_s:.2f} on "
          f"{os.cpu_count()} CPUs); verdicts {', '.join(verdicts)}")
    assert verdicts == ["pass"] * len(verdicts)
    for one, other in zip(results["serial"], results["parallel"], strict=True):
        assert _values(one) == _values(other), "a DUT's measurements changed when run at once"
