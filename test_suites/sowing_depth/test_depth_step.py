"""[D] step simulation on the rig: depth setpoint 30 -> 40 -> 20 -> 30 mm at 4 km/h.

Judged on the true depth (mean over the rows) with the same definitions as the flow steps:
response time into and staying in a +/-5 % band (of the step), overshoot % of the step,
steady-state error over the last 5 s of each 15 s segment.
"""

from __future__ import annotations

import pytest

from hil.metrics import step_response
from test_suites.sowing_depth.traces import trace

pytestmark = [pytest.mark.hil_rig("sowing_depth"), pytest.mark.hil_suite("fast")]

#: (start s, end s, from mm, to mm) of the depth-step scenario
STEPS = ((15.0, 30.0, 30.0, 40.0), (30.0, 45.0, 40.0, 20.0), (45.0, 60.0, 20.0, 30.0))


@pytest.mark.parametrize(("t0", "t_end", "start_mm", "target_mm"), STEPS)
def test_depth_step(hil_run, hil_measure, t0: float, t_end: float, start_mm: float,
                    target_mm: float) -> None:
    result = hil_run("depth-step")
    t, depth = trace(result, "mean_true_depth_mm")
    m = step_response(t, depth, t0=t0, t_end=t_end, target=target_mm)
    conditions = {"from_mm": start_mm, "to_mm": target_mm}
    hil_measure("depth.step.response_time", m.response_time_s, conditions=conditions,
                run=result, note="; ".join(m.notes))
    hil_measure("depth.step.overshoot", m.overshoot_pct, conditions=conditions, run=result)
    hil_measure("depth.step.steady_state_error", m.steady_state_error_pct,
                conditions=conditions, run=result)
