"""The depth fault suite's own pieces: its scenarios and their shared twin.

(Its verdicts on real DUTs are in test_suites_depth_discrimination.py.)
"""

from __future__ import annotations

import inspect

import test_suites.sowing_depth.test_depth_faults as suite
from plant_emulators.sowing_depth.rig import SowingDepthRig
from test_suites.sowing_depth.pairing import hold_twin

SCENARIOS = ("fault-inclinometer-stuck", "fault-inclinometer-noisy", "fault-inclinometer-lost",
             "fault-inclinometer-open-circuit", "fault-draw-wire-lost", "fault-gnss-fix-lost",
             "fault-controller-silent-recovery", "fault-dut-restart",
             "fault-saturation-recovery")


def test_the_suite_runs_these_scenarios() -> None:
    source = inspect.getsource(suite)
    assert all(f'"{name}"' in source for name in SCENARIOS)


def test_the_fault_scenarios_share_one_twin() -> None:
    twins = set()
    for name in SCENARIOS:
        scenario = SowingDepthRig.load_scenario(name)
        twin = hold_twin(scenario)
        assert twin.events == () and twin.seed == scenario.seed
        assert (twin.duration_s, twin.initial, twin.speed_profile) == (
            scenario.duration_s, scenario.initial, scenario.speed_profile)
        assert scenario.events, name
        twins.add(repr(suite._twin(scenario)))
    assert len(twins) == 1, ("the fault scenarios no longer share one twin run (seed, speed or "
                             "target differ): the suite's docstring and run time say they do")


def test_the_faults_start_at_20_s_and_last_5_s() -> None:
    silence = SowingDepthRig.load_scenario("fault-controller-silent-recovery")
    assert [(e.at_s, e.fault or e.clear) for e in silence.events] == [
        (20.0, "controller_silent"), (25.0, "controller_silent")]
    restart = SowingDepthRig.load_scenario("fault-dut-restart")
    assert [(e.at_s, e.dut) for e in restart.events] == [(20.0, "restart")]
    saturation = SowingDepthRig.load_scenario("fault-saturation-recovery")
    assert [(e.at_s, e.set) for e in saturation.events] == [
        (20.0, {"target_depth_mm": 90.0}), (25.0, {"target_depth_mm": 30.0})]
