"""Same seed, same bytes: two lockstep runs of a reference DUT write identical bus logs
(issue #22.7), for both rigs and every DUT kind (inline, Python daemon, C firmware).

The frames a DUT sends unsolicited (the status frame, its heartbeat) used to land in
different 10 ms slots from run to run with a process DUT: they followed the step's command
frame, which is what the rig's SYNC barrier waits for, so whether they were in before the
barrier let go was a race with the process's scheduling. The references now send their
command frame last and run every timer on SYNC counts.

Short scenarios (a setpoint step, and a DUT restart) keep the runs to a few seconds of
simulated time; the depth daemon on a step runs by default, the rest are ``slow``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCENARIOS = {
    ("fertilizer", "step"): """
name = "short-step"
description = "bench step to 23 g/s per row, enabled at 3 s"
rig = "fertilizer"
duration_s = 5.0
seed = 7
[initial]
terminal_mode = 1.0
enable = 0.0
target_flow_gps = 23.0
[[events]]
at_s = 3.0
set = { enable = 1.0 }
""",
    ("fertilizer", "restart"): """
name = "short-dut-restart"
description = "bench run at 34 g/s per row, the controller power-cycled at 4 s"
rig = "fertilizer"
duration_s = 6.0
seed = 7
[initial]
terminal_mode = 1.0
enable = 0.0
target_flow_gps = 34.0
[[events]]
at_s = 3.0
set = { enable = 1.0 }
[[events]]
at_s = 4.0
dut = "restart"
""",
    ("sowing_depth", "step"): """
name = "short-step"
description = "depth setpoint 30 -> 40 mm at 1.5 s, 4 km/h"
rig = "sowing_depth"
duration_s = 3.0
seed = 7
[initial]
target_depth_mm = 30.0
ground_speed_mps = 1.1111
[[events]]
at_s = 1.5
set = { target_depth_mm = 40.0 }
""",
    ("sowing_depth", "restart"): """
name = "short-dut-restart"
description = "the controller power-cycled at 1.5 s, 4 km/h, target 30 mm"
rig = "sowing_depth"
duration_s = 3.0
seed = 7
[initial]
target_depth_mm = 30.0
ground_speed_mps = 1.1111
[[events]]
at_s = 1.5
dut = "restart"
""",
}

PROFILES = {
    "fertilizer": "fertilizer-piecewise-pid-{kind}.toml",
    "sowing_depth": "sowing-depth-fuzzy-pid-{kind}.toml",
}


def _run(profile: Path, scenario: Path, bus: str, out: Path) -> bytes:
    cmd = [sys.executable, "-m", "hil", "run", "--dut", str(profile), "--scenario",
           str(scenario), "--clock", "lockstep", "--bus", bus, "--out", str(out)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env=dict(os.environ), check=False)
    assert proc.returncode in (0, 1), f"hil run exited {proc.returncode}:\n{proc.stderr}"
    return (out / "bus.log").read_bytes()


def _cases() -> list[object]:
    cases: list[object] = []
    for (rig, kind_of_run) in SCENARIOS:
        for dut in ("inline", "daemon", "firmware"):
            fast = rig == "sowing_depth" and kind_of_run == "step" and dut == "daemon"
            marks = () if fast else (pytest.mark.slow,)
            cases.append(pytest.param(rig, kind_of_run, dut, marks=marks,
                                      id=f"{rig}-{kind_of_run}-{dut}"))
    return cases


@pytest.mark.parametrize(("rig", "scenario_kind", "dut"), _cases())
def test_two_lockstep_runs_write_the_same_bus_log(tmp_path: Path, rig: str,
                                                  scenario_kind: str, dut: str) -> None:
    scenario = tmp_path / "scenario.toml"
    scenario.write_text(SCENARIOS[(rig, scenario_kind)])
    # inline: the daemon profile's in-process twin on the inline bus
    kind = "daemon" if dut == "inline" else dut
    profile = ROOT / "dut_profiles" / PROFILES[rig].format(kind=kind)
    bus = "inline" if dut == "inline" else "softbus"
    first = _run(profile, scenario, bus, tmp_path / "a")
    second = _run(profile, scenario, bus, tmp_path / "b")
    assert first.count(b"\n") > 100, "the run logged almost nothing"
    assert b" R\n" in first, "no DUT frame in the log"   # frames received from the DUT
    if first != second:
        a, b = first.splitlines(), second.splitlines()
        where = next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y),
                     min(len(a), len(b)))
        pytest.fail(f"bus logs differ from line {where + 1}: {a[where:where + 3]!r} vs "
                    f"{b[where:where + 3]!r}")
