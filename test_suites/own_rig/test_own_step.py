"""Step response of every controlled quantity: response time and overshoot of the truth (the
FMU's output), its steady-state error, and the steady-state error and response time as
sensed (what the controller sees through the sensor model)."""

from __future__ import annotations

import pytest

from hil.metrics import judged_recovery, step_response
from hil.ownrig.scenarios import step_scenario
from test_suites.own_rig.judge import Recorder, filter_args, own_plan, traces


@pytest.mark.hil_suite("fast")
def test_step_response(hil_rig, hil_run, hil_measure, hil_session) -> None:
    plan = own_plan(hil_rig)
    record = Recorder(plan, hil_session, hil_measure)
    for c in plan.controlled.values():
        spec = c.spec
        for i, target in enumerate(spec.steps):
            scenario = step_scenario(hil_rig, c, i)
            result = hil_run(scenario, label=scenario.name)
            t, _, truth, sensed = traces(result, c)
            band = c.band / abs(target - spec.start)
            m = step_response(t, truth, t0=spec.step_at_s, target=target, y0=spec.start,
                              band=band, steady_window_s=spec.steady_window_s, **filter_args(c))
            response, never = judged_recovery(m.response_time_s, t, t0=spec.step_at_s,
                                              band=band)
            record(c, "step.response_time", response, run=result, scenario=scenario.name,
                   note=never)
            record(c, "step.overshoot", m.overshoot_pct, run=result, scenario=scenario.name)
            record(c, "step.steady_state_error", abs(m.steady_state_value - target),
                   run=result, scenario=scenario.name,
                   note=f"true value {m.steady_state_value:.4g} {c.unit}")
            s = step_response(t, sensed, t0=spec.step_at_s, target=target, y0=spec.start,
                              band=band, steady_window_s=spec.steady_window_s, **filter_args(c))
            record(c, "step.sensed_steady_state_error", abs(s.steady_state_value - target),
                   run=result, scenario=scenario.name,
                   note=f"sensed value {s.steady_state_value:.4g} {c.unit}")
            sensed_response, never = judged_recovery(s.response_time_s, t, t0=spec.step_at_s,
                                                     band=band)
            record(c, "step.sensed_response_time", sensed_response, run=result,
                   scenario=scenario.name, note=never)
