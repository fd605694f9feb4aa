"""Robustness: after the first step, the device that senses the controlled quantity goes
silent or freezes, the controller's frames stop reaching the rig, or the controller is
power-cycled. Judged on the truth: the largest error from the fault to the end of the run
(the controller's cut wire is information there: the actuator's timeout behaviour is the
rig's) and the time after the fault until the value is back in its band to stay."""

from __future__ import annotations

import numpy as np
import pytest

from hil.metrics import judged_recovery, recovery_time
from hil.ownrig.scenarios import FAULT_KINDS, fault_scenario
from test_suites.own_rig.judge import Recorder, own_plan, smoothed, traces


@pytest.mark.hil_suite("robustness")
@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_fault(hil_rig, hil_run, hil_measure, hil_session, kind: str) -> None:
    plan = own_plan(hil_rig)
    record = Recorder(plan, hil_session, hil_measure)
    for c in plan.controlled.values():
        spec = c.spec
        scenario = fault_scenario(hil_rig, c, kind)
        result = hil_run(scenario, label=scenario.name)
        t, _, truth, _ = traces(result, c)
        target = spec.steps[0]
        after = t >= spec.fault_at_s
        truth = smoothed(t, truth, c)
        deviation = float(np.max(np.abs(truth[after] - target)))
        record(c, f"fault.{kind}.deviation", deviation, run=result, scenario=scenario.name,
               fault=kind)
        back_at = spec.fault_at_s if kind == "restart" else spec.fault_at_s + \
            spec.fault_duration_s
        band = c.band / abs(target)
        value = recovery_time(t, truth, t0=back_at, target=target, band=band,
                              filter_kind="none")
        value, never = judged_recovery(value, t, t0=back_at, band=band)
        record(c, f"fault.{kind}.recovery_time", value, run=result, scenario=scenario.name,
               fault=kind, note=never)
