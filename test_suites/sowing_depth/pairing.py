"""Paired runs on the sowing-depth rig: a run and its *twin* without the events.

The rig draws the soil, terrain and outliers along distance and each sensor's noise per
sample from the run's seed, whatever the DUT does. Two runs of one scenario and seed, one
with its events (a set-point step, a sensor fault, a cut wire, a DUT restart) and one
without, see the same field and the same sensor noise; their difference is what the DUT did
because of the events, with the soil's ripple (~1.5 mm SD of true depth) removed. In
lockstep the twins share their disturbance exactly; in real time the DUT's timing differs
between them and a residual remains (the suites report it).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hil.rig import RunResult
from hil.rig.scenario import Scenario
from test_suites.sowing_depth.traces import trace


def hold_twin(scenario: Scenario) -> Scenario:
    """``scenario`` without its events (set-point held at its initial value, no fault, no
    restart), same seed."""
    target = scenario.initial.get("target_depth_mm")
    held = f"the set-point held at {target:g} mm" if target is not None else "no events"
    return dataclasses.replace(
        scenario, name=f"{scenario.name}-hold", events=(),
        description=f"{scenario.name} with {held} and no events (same seed: same field "
                    "and sensor noise)")


def paired(run: RunResult, twin: RunResult, name: str,
           base: float) -> tuple[np.ndarray, np.ndarray]:
    """``(t, base + x_run - x_twin)`` for the trace ``name`` of both runs."""
    t, x_run = trace(run, name)
    t_twin, x_twin = trace(twin, name)
    if t_twin.shape != t.shape or not np.allclose(t_twin, t, atol=1e-9):
        x_twin = np.interp(t, t_twin, x_twin)      # real-time runs: sample times differ
    return t, base + x_run - x_twin
