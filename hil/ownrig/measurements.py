"""The measurements the standard suites record on a rig of your own, and their limits.

Names are ``<rig>.<quantity>.<what>`` (``motor_meter.speed.step.response_time``), registered
in the measurement catalogue (:data:`hil.limits.MEASUREMENTS`) when the rig file is loaded, so
a DUT profile's ``[limits]`` may name them like any other. The default limit of each is the
rig file's (``[controlled.<quantity>] limits``); a measurement judged by it says so in its
``limit_source`` (``rig file motor-meter.rig.toml [controlled.speed.limits.response_time_s]``),
one judged by the profile's says ``profile``.
"""

from __future__ import annotations

from dataclasses import dataclass

from hil.limits import MEASUREMENTS, MeasurementSpec
from hil.ownrig.plan import RigPlan
from hil.ownrig.scenarios import FAULT_KINDS


@dataclass(frozen=True)
class OwnMeasurement:
    """One measurement of a controlled quantity: its suffix, unit, what it is, and the rig
    file's limit key (empty: information only)."""

    suffix: str
    unit: str
    description: str
    limit_key: str = ""


def measurements_of(unit: str) -> list[OwnMeasurement]:
    """The measurements of one controlled quantity in ``unit``."""
    out = [
        OwnMeasurement("step.response_time", "s", "time from the step until the true value "
                       "enters the +/-band around the target and stays", "response_time_s"),
        OwnMeasurement("step.overshoot", "%", "peak of the true value past the target, % of "
                       "the step", "overshoot_pct"),
        OwnMeasurement("step.steady_state_error", unit, "|mean true value - target| over the "
                       "step run's steady window", "steady_state_error"),
        OwnMeasurement("step.sensed_steady_state_error", unit, "|mean sensed value - target| "
                       "over the steady window (what the controller can see)",
                       "sensed_steady_state_error"),
        OwnMeasurement("step.sensed_response_time", "s", "response time of the sensed value "
                       "(information: the sensor's delay and hold included)"),
        OwnMeasurement("tracking.rms_error", unit, "RMS of true value - set-point over the "
                       "tracking profile", "tracking_rms"),
        OwnMeasurement("tracking.max_error", unit, "largest |true value - set-point| over the "
                       "tracking profile", "tracking_max"),
    ]
    for kind in FAULT_KINDS:
        words = kind.replace("_", " ")
        out += [OwnMeasurement(f"fault.{kind}.deviation", unit, f"largest |true value - "
                               f"target| from the {words} until the end of the run"
                               + (" (information: the actuator's timeout behaviour is the "
                                  "rig's)" if kind == "controller_silent" else ""),
                               "" if kind == "controller_silent" else "fault_deviation"),
                OwnMeasurement(f"fault.{kind}.recovery_time", "s", f"time after the {words} "
                               f"ends until the true value is back in the band to stay",
                               "recovery_time_s")]
    return out


def measurement_name(rig: str, quantity: str, suffix: str) -> str:
    return f"{rig}.{quantity}.{suffix}"


def register(plan: RigPlan) -> None:
    """Put the rig's measurements in the catalogue, with the rig file's limits as defaults."""
    for cname, c in plan.controlled.items():
        limits = c.spec.limits
        for m in measurements_of(c.unit):
            high = getattr(limits, m.limit_key) if m.limit_key else None
            name = measurement_name(plan.name, cname, m.suffix)
            stated = f"rig file [controlled.{cname}.limits.{m.limit_key}]"
            MEASUREMENTS[name] = MeasurementSpec(
                name, m.unit, plan.name, f"{cname}: {m.description}", high=high,
                conditions=("scenario", "fault"),
                source=stated if high is not None else "",
                information="" if high is not None else (
                    f"no limit: the rig file states none ({stated})" if m.limit_key else
                    "information: what the controller cannot change or the rig decides"))


def limit_source(plan: RigPlan, name: str) -> str:
    """Where the default limit of ``name`` is stated in the rig file (empty: none)."""
    for cname, c in plan.controlled.items():
        for m in measurements_of(c.unit):
            if measurement_name(plan.name, cname, m.suffix) == name and m.limit_key \
                    and getattr(c.spec.limits, m.limit_key) is not None:
                return (f"rig file {plan.loaded.path.name} "
                        f"[controlled.{cname}.limits.{m.limit_key}]")
    return ""
