"""Tracking over the rig file's set-point profile: RMS and largest error of the truth against
the set-point, from the profile's second breakpoint on (its first segment is the approach
from rest)."""

from __future__ import annotations

import numpy as np
import pytest

from hil.ownrig.scenarios import tracking_scenario
from test_suites.own_rig.judge import Recorder, own_plan, smoothed, traces


@pytest.mark.hil_suite("fast")
def test_tracking(hil_rig, hil_run, hil_measure, hil_session) -> None:
    plan = own_plan(hil_rig)
    record = Recorder(plan, hil_session, hil_measure)
    judged = 0
    for c in plan.controlled.values():
        scenario = tracking_scenario(hil_rig, c)
        if scenario is None:
            continue
        result = hil_run(scenario, label=scenario.name)
        t, setpoint, truth, _ = traces(result, c)
        start = c.spec.profile[1][0] if len(c.spec.profile) > 1 else c.spec.profile[0][0]
        window = t >= start
        error = smoothed(t, truth, c)[window] - setpoint[window]
        record(c, "tracking.rms_error", float(np.sqrt(np.mean(error ** 2))), run=result,
               scenario=scenario.name, note=f"judged from {start:g} s")
        record(c, "tracking.max_error", float(np.max(np.abs(error))), run=result,
               scenario=scenario.name, note=f"judged from {start:g} s")
        judged += 1
    if not judged:
        pytest.skip("no controlled quantity has a set-point profile (profile = [...])")
