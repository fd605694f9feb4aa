"""Lockstep real-time factor of whole rig runs (physics + devices + bus + in-process DUT)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

from hil.dut import InProcessDut
from hil.rig import RunOptions, load_rig, run_scenario

CASES = [("fertilizer", "field-6kmh", "pi"), ("sowing_depth", "depth-step", "pi")]


@pytest.mark.parametrize("bus", ["inline", "virtual", "softbus"])
@pytest.mark.parametrize(("rig_name", "scenario_name", "controller"), CASES)
def test_lockstep_realtime_factor(benchmark, timed_rounds, rig_name: str, scenario_name: str,
                                  controller: str, bus: str) -> None:
    rig = load_rig(rig_name)
    scenario = rig.load_scenario(scenario_name)
    results = []

    def run() -> None:
        with tempfile.TemporaryDirectory() as out:
            dut = InProcessDut(rig.builtin_controllers()[controller]())
            results.append(run_scenario(rig, scenario, dut,
                                        RunOptions(out_dir=Path(out), bus=bus)))

    benchmark.pedantic(run, rounds=3, iterations=1)
    assert all(r.record["error"] is None for r in results)
    wall = float(np.median(timed_rounds()))
    factor = scenario.duration_s / wall
    benchmark.extra_info.update(sim_s=scenario.duration_s, realtime_factor=factor)
    print(f"\n{rig_name}/{scenario_name} lockstep, in-process {controller} on {bus}: "
          f"{scenario.duration_s:.0f} s simulated in {wall:.2f} s (x{factor:.0f})")
