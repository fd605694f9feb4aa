"""What the own-rig suites share: the rig's plan, its traces by role, and recording a
measurement with the source of its limit."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from hil.ownrig.measurements import limit_source, measurement_name
from hil.ownrig.plan import ControlledPlan, RigPlan
from hil.ownrig.rig import OwnRig, trace_name


def own_plan(rig: type) -> RigPlan:
    """The plan of the DUT's rig; the test is skipped for a built-in rig."""
    if not (isinstance(rig, type) and issubclass(rig, OwnRig)):
        pytest.skip(f"a suite of rigs of your own; the DUT drives the built-in "
                    f"{getattr(rig, 'name', rig)} rig")
    plan = rig.plan()
    if not plan.controlled:
        pytest.skip(f"the rig file {plan.loaded.path.name} declares no controlled quantity")
    return plan


def traces(result: Any, c: ControlledPlan) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     np.ndarray]:
    """(time, set-point, truth, sensed) of controlled quantity ``c`` in a run."""
    arrays, _ = result.traces()
    return (arrays["time_s"], arrays[c.target], arrays[trace_name("true", c.truth.text)],
            arrays[trace_name("sensed", c.sensed)])


def filter_args(c: ControlledPlan) -> dict[str, Any]:
    """The step metrics' smoothing the rig file asks for (``filter``, ``filter_s``)."""
    return {"filter_kind": c.spec.filter, "filter_s": c.spec.filter_s}


def smoothed(t: np.ndarray, y: np.ndarray, c: ControlledPlan) -> np.ndarray:
    """``y`` smoothed as the step metrics smooth it (for the errors judged outside them)."""
    from hil.metrics.step import smooth

    if c.spec.filter == "none" or len(t) < 2:
        return y
    samples = max(1, round(c.spec.filter_s / float(np.median(np.diff(t)))))
    return smooth(y, samples | 1, c.spec.filter)         # centred: an odd count


class Recorder:
    """Records ``<rig>.<quantity>.<suffix>`` measurements; a limit taken from the rig file is
    recorded with that source (the catalogue's default of a rig of your own is its file's)."""

    def __init__(self, plan: RigPlan, session: Any, measure: Callable[..., Any]) -> None:
        self.plan, self.session, self.measure = plan, session, measure

    def __call__(self, c: ControlledPlan, suffix: str, value: float, *, run: Any,
                 scenario: str, fault: str = "", note: str = "") -> Any:
        name = measurement_name(self.plan.name, c.name, suffix)
        conditions: dict[str, Any] = {"scenario": scenario}
        if fault:
            conditions["fault"] = fault
        m = self.measure(name, float(value), conditions=conditions, run=run, note=note)
        source = limit_source(self.plan, name)
        if source and m.limit_source.startswith("catalogue"):
            for entry in reversed(self.session.measurements):
                if entry.get("name") == name:
                    entry["limit_source"] = source
                    break
        return m
