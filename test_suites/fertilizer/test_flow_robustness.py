"""Robustness of a flow controller: what the field does to it.

* a flow module goes silent / reports garbage from 13 s of a 34 g/s bench run: the controller
  must carry on with the other rows (accuracy over the run, eq. 15);
* a flow module reads wrong with good status bits from 8 s (frozen at mid-range, a 30 % gain
  step, a drift of 2 %/s): the controller must tell it from the other rows and leave it out
  (accuracy once a cross-row check can have acted, true flow at the meter);
* the machine stops for 5 s in a field run: grams metered while standing still;
* the target exceeds the meter's capacity, then returns into range: while it is out of reach
  the meter must deliver what the drive allows at full command (a controller that caps its
  target below the meter's capacity does not), and after it returns, the time to be back in
  the +/-5 % band (an integrator that wound up while saturated takes long to unwind);
* the controller goes silent (its wire is cut for 5 s; the analog module falls back to 0 V
  and the flow stops while the controller still sees it fall), then is heard again: the time
  to be back in the band (a controller that integrated the missing flow overshoots);
* the controller is power-cycled mid-run: the time to be back in the band.
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.metrics import accuracy_theta, judged_recovery, recovery_time
from hil.rig import RunResult
from plant_emulators.fertilizer.config import load_rig_config
from plant_emulators.fertilizer.flow_map import FlowMap
from test_suites.fertilizer.traces import (
    delivered_and_target_g,
    flow_filter,
    row_mean,
    trace,
)

pytestmark = [pytest.mark.hil_rig("fertilizer"), pytest.mark.hil_suite("robustness")]

RETURN_S = 12.0            # fault-saturation-recovery: the target drops back to 34 g/s here
RETURN_TARGET_GPS = 34.0
#: fault-saturation-recovery: enabled at 3 s at 90 g/s per row, out of the meter's reach; the
#: delivered flow is judged from 3 s later ([F]'s 1.5 s response twice over) to the return
SATURATED_FROM_S = 6.0


#: fault scenario -> (measurement, what a controller must do about it)
SENSOR_FAULTS = {
    # no usable number: nothing at all, or a number the module itself flags as invalid
    "silent": ("flow.fault.sensor_dropout.accuracy", "notice the silence (stale reports)"),
    "baseline-lost": ("flow.fault.sensor_dropout.accuracy",
                      "drop a report with BaselineReady cleared (it reads ~65 % of the flow)"),
    "overrange": ("flow.fault.sensor_dropout.accuracy",
                  "drop a report with AdcOverrange set (it reads ~70 % of the flow)"),
    # numbers the meter cannot be delivering
    "garbage": ("flow.fault.sensor_garbage.accuracy", "reject values out of the valid range"),
    "implausible": ("flow.fault.sensor_garbage.accuracy",
                    "reject a row reading 4x the flow: more than the meter delivers at the "
                    "target"),
}


@pytest.mark.parametrize("fault", sorted(SENSOR_FAULTS))
def test_sensor_faults(hil_run, hil_measure, fault: str) -> None:
    measurement, duty = SENSOR_FAULTS[fault]
    result = hil_run(f"fault-sensor-{fault}")
    delivered, target = delivered_and_target_g(result)
    # the original two faults keep their conditions (the stored baselines' keys)
    conditions = {"row": 2} if fault in ("silent", "garbage") else {
        "row": 2, "fault": fault.replace("-", "_")}
    hil_measure(measurement, accuracy_theta(target, delivered), conditions=conditions,
                run=result,
                note=f"weighed {delivered:.1f} g of {target:.1f} g; the controller must "
                     f"{duty}")


PLAUSIBILITY_TARGET_GPS = 34.0
#: fault scenario -> (from when its flow is judged, s; what the fault is). The module goes wrong
#: at 8 s. A cross-row check that never leaves out a healthy row (12 % + 1 g/s for 3 s,
#: reference_controllers/fertilizer/cross_row.py) catches a step fault within its 3 s dwell;
#: [F]'s 1.5 s response later the flow is back: 12.5 s. A drift of 2 %/s leaves the rows' band
#: (15 % at 34 g/s) 7.5 s after it starts, then the dwell and the response: 20 s
#: (hil/limits.py, _SENSOR_PLAUSIBILITY_LIMIT_PCT, says what the limit allows on top).
PLAUSIBILITY_FAULTS = {
    "stuck-mid": (12.5, "freezes at 60 % of the flow"),
    "gain-step": (12.5, "reads 30 % high"),
    "drift": (20.0, "drifts up 2 %/s"),
}


@pytest.mark.parametrize("fault", sorted(PLAUSIBILITY_FAULTS))
def test_sensor_plausibility(hil_run, hil_measure, fault: str) -> None:
    """Row 2's module reads wrong with good status bits: only the other rows can tell. The
    true flow at the meter from the judged time on, against the target (eq. 15)."""
    judged_from_s, what = PLAUSIBILITY_FAULTS[fault]
    result = hil_run(f"fault-sensor-{fault}")
    t, flow = row_mean(result, "flow_at_meter")
    judged = t >= judged_from_s
    dt = float(np.median(np.diff(t)))
    metered = float(np.sum(flow[judged]) * dt)
    target = PLAUSIBILITY_TARGET_GPS * float(np.count_nonzero(judged)) * dt
    hil_measure("flow.fault.sensor_plausibility.accuracy", accuracy_theta(target, metered),
                conditions={"row": 2, "fault": fault.replace("-", "_")}, run=result,
                note=f"row 2's module {what} from 8 s with good status bits; {metered:.1f} g "
                     f"of {target:.1f} g per row metered from {judged_from_s:g} s: the "
                     f"controller must leave out a row that disagrees with the others")


def test_speed_loss(hil_run, hil_measure) -> None:
    result = hil_run("field-stop-go")
    t, speed = trace(result, "ground_speed_mps")
    _, flow = row_mean(result, "flow_at_meter")
    rows = len(result.record["truth"]["delivered_g"])
    standing = speed < 0.01
    dt = float(np.median(np.diff(t)))
    grams = float(np.sum(flow[standing]) * dt * rows)
    hil_measure("flow.fault.speed_loss.overdelivery", grams, run=result,
                note=f"{standing.sum() * dt:.1f} s standing still")


def full_command_flow_gps(result: RunResult) -> float:
    """The mean flow per row the meter delivers at full command in this run, from the drive
    and meter model (the run's rig configuration and its truth).

    The drive turns the motor at the speed full command sets (``speed_at_full_command_rpm``)
    unless the supply cannot hold it under load: the back-EMF at the speed reached plus the
    load current's drop in the armature must stay within the supply. The load is the rollers'
    shearing torque (a constant and a per-r/min part each) and the shaft's friction through the
    reducer, and the motor's own friction. The meter's flow at that shaft speed is the flow
    map's, times the run's fertilizer density factor and the rows' mean roller gain (truth).
    """
    overrides = result.record.get("rig_config_overrides") or {}
    cfg = load_rig_config(overrides=overrides, source="the run's rig_config_overrides")
    motor, drive, meter = cfg.motor, cfg.drive, cfg.meter
    motor_rpm = motor.speed_at_full_command_rpm
    for _ in range(20):       # the load grows with speed: settle the supply limit
        shaft_rpm = motor_rpm / drive.total_ratio
        load_nm = (meter.rows * (meter.roller_torque_nm + meter.roller_torque_per_rpm_nm
                                 * shaft_rpm) + drive.shaft_friction_nm) \
            / (drive.total_ratio * drive.reducer_efficiency) \
            + motor.coulomb_friction_nm + motor.viscous_friction_nm_per_krpm * motor_rpm / 1000
        current = load_nm / motor.kt_nm_per_a
        emf_limit_rpm = ((motor.supply_v - current * motor.armature_resistance_ohm)
                         / motor.ke_v_per_krpm * 1000.0)
        motor_rpm = min(motor.speed_at_full_command_rpm, emf_limit_rpm)
    truth = result.record["truth"]
    gain = float(np.mean(truth["row_gain"]))
    return (FlowMap.from_config(meter).flow_gps(motor_rpm / drive.total_ratio)
            * (1.0 + float(truth["density_offset_frac"])) * gain)


def test_saturation_recovery(hil_run, hil_measure) -> None:
    result = hil_run("fault-saturation-recovery")
    t, flow = row_mean(result, "flow_at_meter")
    saturated_window = (t >= SATURATED_FROM_S) & (t < RETURN_S)
    capacity = full_command_flow_gps(result)
    delivered = float(np.mean(flow[saturated_window]))
    hil_measure("flow.fault.saturation.delivered_share", 100.0 * delivered / capacity,
                run=result,
                note=f"{delivered:.2f} g/s per row from {SATURATED_FROM_S:g} to {RETURN_S:g} s "
                     f"at a target of 90 g/s; the meter delivers {capacity:.2f} g/s at full "
                     f"command (drive and meter model)")
    # the true flow as the step tests judge it (mass per whole flute periods, ~1 s), back
    # within +/-5 % of the target, as after a restart or a cut wire. Not 5 % of the step down
    # from saturation (issue #16): that band is 5 % of the meter's capacity of the day minus
    # the target (~29 g/s, a +/-4.3 % band at 34 g/s, narrower on a denser lot), and it
    # failed flows that stayed within +/-4.3 % from 0.5 s after the return (seed 8300052)
    recovery = recovery_time(t, flow, t0=RETURN_S, target=RETURN_TARGET_GPS,
                             **flow_filter(result, RETURN_S))
    value, never = judged_recovery(recovery, t, t0=RETURN_S)
    before = (t >= RETURN_S - 2.0) & (t < RETURN_S)
    saturated = float(np.mean(flow[before])) if before.any() else float("nan")
    hil_measure("flow.fault.saturation.recovery_time", value, run=result,
                note=never or f"{saturated:.1f} g/s per row (mean of the last 2 s) at full "
                              f"command before the target returned to "
                              f"{RETURN_TARGET_GPS:g} g/s")


RESTART_S = 13.0           # fault-dut-restart: the controller is power-cycled here
RESTART_TARGET_GPS = 34.0


def test_dut_restart(hil_run, hil_measure) -> None:
    """The controller is stopped and started again mid-run (its state is lost, the process
    and its output are kept apart): the true flow must be back within ±5 % of the target."""
    result = hil_run("fault-dut-restart")
    t, flow = row_mean(result, "flow_at_meter")
    recovery = recovery_time(t, flow, t0=RESTART_S, target=RESTART_TARGET_GPS,
                             **flow_filter(result, RESTART_S))
    restarts = [e for e in result.record["events"] if e["kind"] == "dut-restart"]
    recovery, never = judged_recovery(recovery, t, t0=RESTART_S)
    hil_measure("flow.restart.recovery_time", recovery, run=result,
                note=never or f"{len(restarts)} restart(s); 0 s: the flow never left the "
                              "±5 % band")


SILENCE_END_S = 18.0       # fault-controller-silent-recovery: the wire is reconnected here
SILENCE_TARGET_GPS = 34.0


def test_dut_silence(hil_run, hil_measure) -> None:
    """The controller's frames stop reaching the rig for 5 s (the analog module watches its
    heartbeat and falls back to 0 V), then reach it again: the true flow must be back within
    ±5 % of the target soon after."""
    result = hil_run("fault-controller-silent-recovery")
    t, flow = row_mean(result, "flow_at_meter")
    recovery = recovery_time(t, flow, t0=SILENCE_END_S, target=SILENCE_TARGET_GPS,
                             **flow_filter(result, SILENCE_END_S))
    recovery, never = judged_recovery(recovery, t, t0=SILENCE_END_S)
    hil_measure("flow.silence.recovery_time", recovery, run=result,
                note="5 s of cut wire from 13 s; the flow stops while the wire is cut"
                     + (f"; {never}" if never else ""))
