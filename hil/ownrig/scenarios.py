"""The scenarios the standard suites run on a rig of your own, made from its controlled
quantities (the built-in scenario format: ``hil rig scenarios FILE --write DIR`` writes them).

Per controlled quantity ``c``:

* ``c-step-<i>``: the target steps from ``start`` to ``steps[i]`` at ``step_at_s``;
* ``c-tracking``: the target follows ``profile`` (linear between breakpoints, set every
  control period);
* ``c-sensor-dropout``, ``c-sensor-frozen``, ``c-controller-silent``: after the first step,
  the device that sends the sensed value goes silent or repeats its last frames, or the
  controller's frames stop reaching the rig, from ``fault_at_s`` for ``fault_duration_s``;
* ``c-restart``: the controller is power-cycled at ``fault_at_s``.
"""

from __future__ import annotations

import itertools
import json

from hil.ownrig.plan import ControlledPlan
from hil.rig.scenario import Event, Scenario

FAULT_KINDS = ("sensor_dropout", "sensor_frozen", "controller_silent", "restart")


def sensed_device(cls: type, c: ControlledPlan) -> str:
    """The device that sends ``c``'s sensed quantity."""
    plan = cls.plan()   # type: ignore[attr-defined]
    return next(m.device for m in plan.sent for s in m.sent if s.quantity == c.sensed)


def step_scenario(cls: type, c: ControlledPlan, i: int) -> Scenario:
    spec = c.spec
    return Scenario(name=f"{c.name}-step-{i + 1}",
                    description=f"{c.target} steps {spec.start:g} -> {spec.steps[i]:g} {c.unit} "
                                f"at {spec.step_at_s:g} s",
                    rig=cls.name, duration_s=spec.step_duration_s,  # type: ignore[attr-defined]
                    initial={c.target: spec.start},
                    events=(Event(at_s=spec.step_at_s, set={c.target: spec.steps[i]}),),
                    tags=("own-rig", "step"))


def profile_value(points: tuple[tuple[float, float], ...], t: float) -> float:
    """The profile's set-point at ``t`` (linear between breakpoints, held outside)."""
    if t <= points[0][0]:
        return points[0][1]
    for (t0, v0), (t1, v1) in itertools.pairwise(points):
        if t <= t1:
            return v1 if t1 == t0 else v0 + (v1 - v0) * (t - t0) / (t1 - t0)
    return points[-1][1]


def tracking_scenario(cls: type, c: ControlledPlan) -> Scenario | None:
    points = c.spec.profile
    if not points:
        return None
    period = cls.control_period_s    # type: ignore[attr-defined]
    duration = points[-1][0]
    events, last = [], profile_value(points, 0.0)
    k = 1
    while k * period < duration - 1e-9:
        t = round(k * period, 9)
        value = round(profile_value(points, t), 9)
        if value != last:
            events.append(Event(at_s=t, set={c.target: value}))
            last = value
        k += 1
    return Scenario(name=f"{c.name}-tracking",
                    description=f"{c.target} follows the set-point profile of the rig file",
                    rig=cls.name, duration_s=duration,  # type: ignore[attr-defined]
                    initial={c.target: profile_value(points, 0.0)}, events=tuple(events),
                    tags=("own-rig", "tracking"))


def fault_scenario(cls: type, c: ControlledPlan, kind: str) -> Scenario:
    spec = c.spec
    start, end = spec.fault_at_s, spec.fault_at_s + spec.fault_duration_s
    events = [Event(at_s=spec.step_at_s, set={c.target: spec.steps[0]})]
    if kind == "restart":
        events.append(Event(at_s=start, dut="restart"))
        what = f"the controller is power-cycled at {start:g} s"
    else:
        fault = {"sensor_dropout": f"{sensed_device(cls, c)}_silent",
                 "sensor_frozen": f"{sensed_device(cls, c)}_frozen",
                 "controller_silent": "controller_silent"}[kind]
        events += [Event(at_s=start, fault=fault), Event(at_s=end, clear=fault)]
        what = f"{fault} from {start:g} s to {end:g} s"
    return Scenario(name=f"{c.name}-{kind.replace('_', '-')}",
                    description=f"{c.target} at {spec.steps[0]:g} {c.unit}; {what}",
                    rig=cls.name, duration_s=spec.step_duration_s,  # type: ignore[attr-defined]
                    initial={c.target: spec.start}, events=tuple(events),
                    tags=("own-rig", "robustness"))


def suite_scenarios(cls: type) -> list[Scenario]:
    """Every scenario the standard suites run on the rig ``cls``."""
    out: list[Scenario] = []
    for c in cls.plan().controlled.values():   # type: ignore[attr-defined]
        out += [step_scenario(cls, c, i) for i in range(len(c.spec.steps))]
        tracking = tracking_scenario(cls, c)
        if tracking is not None:
            out.append(tracking)
        out += [fault_scenario(cls, c, kind) for kind in FAULT_KINDS]
    return out


def scenario_toml(scenario: Scenario) -> str:
    """A scenario as a scenario file says it."""
    def value(v: object) -> str:
        return json.dumps(v)

    lines = [f"name = {value(scenario.name)}", f"description = {value(scenario.description)}",
             f"rig = {value(scenario.rig)}", f"duration_s = {scenario.duration_s!r}",
             f"seed = {scenario.seed}", f"tags = {value(list(scenario.tags))}", "[initial]"]
    lines += [f"{k} = {v!r}" for k, v in scenario.initial.items()]
    for e in scenario.events:
        lines += ["[[events]]", f"at_s = {e.at_s!r}"]
        if e.set is not None:
            lines.append("set = { " + ", ".join(f"{k} = {v!r}" for k, v in e.set.items()) + " }")
        for key in ("fault", "clear", "dut"):
            if getattr(e, key) is not None:
                lines.append(f"{key} = {value(getattr(e, key))}")
        if e.target is not None:
            lines.append(f"target = {e.target}")
    return "\n".join(lines) + "\n"
