"""Drive a field with section control and an ideal implement: the reference run.

:func:`drive_field` samples the path every ``dt_s``, asks :class:`~.coverage.SectionControl`
for the commanded section states, and plays an implement that realises each command exactly
its declared turn-on (turn-off) time later and applies a rate that follows the prescription at
each section's position through a pure delay and a first-order lag. The coverage is built from
the implement's actual states, as a TC builds it from the reported work states.

It is what the Task Controller does each period, without a bus, so the pieces can be checked
together and the metrics of :mod:`hil.metrics.application_map` have a known-good (and, with the
implement's parameters changed, a known-bad) record to judge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hil.isobus.field.as_applied import AsAppliedRecord
from hil.isobus.field.boom import Boom
from hil.isobus.field.path import Field
from hil.isobus.field.prescription import PrescriptionMap
from hil.isobus.field.task import FieldTask

__all__ = ["ImplementModel", "drive_field"]


@dataclass(frozen=True)
class ImplementModel:
    """How the emulated implement follows commands (all >= 0).

    ``switch_delay_scale`` multiplies the declared turn-on/off times (1: exactly as declared,
    > 1 a late implement); ``obey_sections=False`` applies everywhere (never switches) and
    ``follow_map=False`` applies ``fixed_rate`` whatever the set-point.
    """

    rate_delay_s: float = 0.0
    rate_time_constant_s: float = 0.3
    switch_delay_scale: float = 1.0
    obey_sections: bool = True
    follow_map: bool = True
    fixed_rate: float = 0.0


def drive_field(fld: Field, boom: Boom, rx_map: PrescriptionMap, *, dt_s: float = 0.1,
                implement: ImplementModel | None = None,
                overlap_tolerance_pct: float = 50.0) -> AsAppliedRecord:
    """Drive ``fld.path`` to its end; return what was applied, per sample and section.

    The TC side is a :class:`~.task.FieldTask` whose rate look-ahead is the implement's
    ``rate_delay_s``: the set-point sent at ``t`` is the map's rate where the section will be
    when the implement applies it.
    """
    imp = implement or ImplementModel()
    task = FieldTask(fld, rx_map, boom, overlap_tolerance_pct=overlap_tolerance_pct,
                     rate_lookahead_s=imp.rate_delay_s)
    n_sec = len(boom.sections)
    pending: list[tuple[float, int, bool]] = []   # (time it takes effect, section, state)
    actual = [False] * n_sec
    commanded = [False] * n_sec
    rate = np.zeros(n_sec)
    setpoints: list[np.ndarray] = []              # kept to play the pure delay back
    alpha = 1.0 - math.exp(-dt_s / imp.rate_time_constant_s) if imp.rate_time_constant_s else 1.0
    delay_steps = round(imp.rate_delay_s / dt_s)
    for t in np.arange(0.0, fld.path.duration_s + dt_s, dt_s):
        cmd = task.command(float(t))
        for j in range(n_sec):
            if cmd.sections_on[j] != commanded[j]:
                lag = boom.turn_on_s if cmd.sections_on[j] else boom.turn_off_s
                pending.append((t + lag * imp.switch_delay_scale - 1e-9, j, cmd.sections_on[j]))
                commanded[j] = cmd.sections_on[j]
        for item in [p for p in pending if p[0] <= t]:
            pending.remove(item)
            actual[item[1]] = item[2]
        applying = list(actual) if imp.obey_sections else [True] * n_sec
        setpoints.append(cmd.rates)
        target = setpoints[max(len(setpoints) - 1 - delay_steps, 0)]
        if not imp.follow_map:
            target = np.full(n_sec, imp.fixed_rate)
        rate = rate + alpha * (target - rate)
        task.report(cmd.pose, applying, np.where(applying, rate, 0.0))
    return task.as_applied
