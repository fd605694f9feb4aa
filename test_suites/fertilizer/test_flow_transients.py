"""Speed transients in the field: the mass a flow controller loses while the ground speed
changes (headland slow-down and acceleration, speed steps: ``field-headland``).

The target flow follows the true ground speed ([F] eq. 1); the controller sees it through its
speed source. Judged on the true flow at the meters against the target, over one window per
speed change (from 1 s before it until the next one, at most 10 s after it), as the lag that
mass error amounts to (:func:`hil.metrics.transient_lag`: a controller following speed
through a pure delay or a low-pass of τ reads τ). Its limit (hil/limits.py) comes from the
rig's own delays.
"""

from __future__ import annotations

import itertools

import pytest

from hil.metrics import transient_lag
from test_suites.fertilizer.traces import ENABLE_S, row_mean, trace

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("fast")]

SCENARIO = "field-headland"
BEFORE_S = 1.0          # a window opens this long before its speed change starts
SETTLE_S = 10.0         # and closes at the next change, at most this long after it ends


def transient_windows(profile: tuple[tuple[float, float], ...], end_s: float,
                      ) -> list[tuple[float, float]]:
    """One (start, end) window per run of changing breakpoints of a speed profile."""
    changes: list[list[float]] = []
    for (t0, v0), (t1, v1) in itertools.pairwise(profile):
        if v1 == v0:
            continue
        if changes and changes[-1][1] == t0:
            changes[-1][1] = t1
        else:
            changes.append([t0, t1])
    windows = []
    for i, (start, stop) in enumerate(changes):
        nxt = changes[i + 1][0] - BEFORE_S if i + 1 < len(changes) else end_s
        windows.append((start - BEFORE_S, min(nxt, stop + SETTLE_S)))
    return [w for w in windows if w[0] >= ENABLE_S + 2.0]


def test_field_transients(hil_run, hil_rig, hil_measure) -> None:
    scenario = hil_rig.load_scenario(SCENARIO)
    result = hil_run(SCENARIO)
    t, delivered = row_mean(result, "flow_at_meter")
    _, target = trace(result, "target_flow_row_gps")
    windows = transient_windows(scenario.speed_profile, float(t[-1]))
    m = transient_lag(t, delivered, target, windows)
    hil_measure("flow.field.transient_lag", m.lag_s, run=result,
                conditions={"transients": len(windows)},
                note=f"{m.mass_error_pct:.2f} % mass error over the transient windows; per "
                     "window (g per row, target step g/s): " + ", ".join(
                         f"{e:+.1f} ({s:+.1f})" for e, s in zip(m.window_errors_g,
                                                                m.window_steps_gps,
                                                                strict=True)))
