"""What sensor faults, a silent controller and a controller restart do to the seeds.

Each fault scenario is run with its *twin*: the same scenario and seed without the events
(:mod:`test_suites.sowing_depth.pairing`). Both see the same field and the same sensor noise,
so the difference of their mean true seed depths (the 12 rows, the rig's truth) is what the
fault made the DUT do to the seeds, without the soil's own ripple (~1.5 mm SD)::

    y(t) = 30 mm + d_fault(t) - d_twin(t)        (the paired true depth; exactly 30 mm
                                                  before the fault, in lockstep)

The true depth is judged, not the sensed one: in a sensor fault the sensed depth is what
is broken.

* **sensor faults** (``depth.fault.sensor.deviation``, condition ``fault``): from 20 s the
  inclinometer freezes, gets very noisy (a loose mounting: x20 noise), stops sending (its
  analog input node is off the bus), or its X wire breaks (0 mV, status "below range"); the
  draw-wire sensor stops sending, or the GNSS receiver loses its fix (for 10 s; the ground
  speed still comes from the tractor's GBSD). The value is the RMS of ``y - 30`` from the
  fault's onset to the end of the run (recovering after a cleared fault is part of it), in
  mm. A controller that integrates a frozen depth drives the roller to its end stop (tens
  of mm); one that notices the dead sensor and holds the roller stays within the soil's
  drift (~1 mm); a controller that does not use a sensor is not moved by its loss at all
  (0 mm, exactly, in lockstep).
* **silence** (``depth.silence.recovery_time``): the controller's frames stop reaching the
  rig from 20 s to 25 s (a cut wire; the drive, with no heartbeat consumer configured, keeps
  its last target velocity, so the roller drifts), then reach it again. The time from 25 s
  until the 0.2 s running median of ``y`` is within +/-5 % (1.5 mm) of 30 mm and stays there
  to the end (at least 1 s): a controller that wound up while its commands did not arrive
  overshoots the other way.
* **restart** (``depth.restart.recovery_time``): the controller is power-cycled at 20 s (its
  state is lost; the drive stays Operational with its last command). The time from 20 s
  until ``y`` is back in the band, as above; 0 s when it never left.
* **saturation** (``depth.fault.saturation.recovery_time``): the target jumps to 90 mm, out of
  the roller's reach, at 20 s and returns to 30 mm at 25 s; the twin holds 30 mm. The time
  from 25 s until ``y`` is back in the band: a controller that wound up against the end of
  travel overshoots on the way back.

**Absolute tracking around the fault.** The pairing removes the soil's ripple, and with it
everything the twin does too: a controller that is broken in both runs (its polarity
inverted, the roller at an end stop) would read a perfect 0. So each fault run must also keep
its own true depth (the 0.2 s median, as above) within ``ABS_TOL_MM`` of the target:

* sensor faults: the value is the RMS over the fault of ``max(|y - 30|, |d_fault - 30| -
  ABS_TOL_MM)``: the paired deviation while the run tracks, its excess over the tolerance
  where it does not;
* recoveries: the time until the paired depth is back in +/-5 % *and* the run's own depth is
  within ``ABS_TOL_MM`` of the target, both staying there to the end; the saturation run must
  also have followed the out-of-reach target (left the band towards it), or it has not been
  tested and fails.

A recovery that never comes is a failed measurement whose value is the time observed after
the event (a lower bound) and whose note says so (:func:`hil.metrics.judged_recovery`).

The fault scenarios share seed, speed and target, so they share one twin run, made once per
session (the session caches runs by scenario). The filter and the band are the step suite's
(:mod:`test_depth_step`): the paired signal needs no smoothing against soil noise, the median
only removes sample-level flicker.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hil.metrics import judged_recovery, recovery_time
from hil.rig.scenario import Scenario
from test_suites.sowing_depth.pairing import hold_twin, paired
from test_suites.sowing_depth.traces import trace

pytestmark = [pytest.mark.hil_rig("sowing_depth"), pytest.mark.hil_suite("robustness")]

TRUE_DEPTH = "mean_true_depth_mm"
BAND = 0.05
FILTER = {"filter_kind": "median", "filter_s": 0.2}
#: how far a fault run's own mean true depth may be from the target (mm): GB/T 20865's
#: qualified band (+/-10 mm at a 30 mm target): a run whose mean seed depth leaves it is
#: sowing out of specification whatever its twin does. The soil's ripple of the mean true
#: depth (the reference's fault runs reach 7.2 mm off the target, seed 1) stays inside it; a
#: roller at an end stop (25-30 mm off) does not.
ABS_TOL_MM = 10.0


def _twin(scenario: Scenario) -> Scenario:
    """The scenario without its events, named and described by what it is, not by the fault
    it pairs with: the fault scenarios share seed, speed and target, so every test asks for
    the same twin and the session's run cache makes it once."""
    held = hold_twin(scenario)
    return dataclasses.replace(
        held, name="fault-twin",
        description=f"the fault scenarios without their events (target "
                    f"{scenario.initial.get('target_depth_mm'):g} mm throughout)")


def _fault_run(hil_run, hil_rig, name: str):
    scenario = hil_rig.load_scenario(name)
    target = scenario.initial.get("target_depth_mm")
    targets = [e.set["target_depth_mm"] for e in scenario.events
               if e.set and "target_depth_mm" in e.set]
    if target is None or (targets and targets[-1] != target):
        raise AssertionError(f"{name}: the fault suites need a target depth that ends where "
                             "it began")
    return scenario, hil_run(scenario), hil_run(_twin(scenario), label="twin"), float(target)


def _twin_note(twin) -> str:
    return f"; the twin run ended early: {twin.record['error']}" if twin.record.get(
        "error") else ""


@pytest.mark.parametrize(("scenario", "fault"), [
    ("fault-inclinometer-stuck", "inclinometer_stuck"),
    ("fault-inclinometer-noisy", "inclinometer_noisy"),
    ("fault-inclinometer-lost", "inclinometer_lost"),
    ("fault-inclinometer-open-circuit", "inclinometer_open_circuit"),
    ("fault-draw-wire-lost", "draw_wire_lost"),
    ("fault-gnss-fix-lost", "gnss_fix_lost"),
])
def test_sensor_fault(hil_run, hil_measure, hil_rig, scenario: str, fault: str) -> None:
    spec, run, twin, target = _fault_run(hil_run, hil_rig, scenario)
    onset = [e.at_s for e in spec.events if e.fault == fault]
    assert len(onset) == 1, f"{scenario}: expected one '{fault}' fault"
    cleared = [e.at_s for e in spec.events if e.clear == fault]
    t, y = paired(run, twin, TRUE_DEPTH, target)
    during = (t >= onset[0]) & np.isfinite(y)
    if twin.record.get("error") or not during.any():
        value, note = math.nan, "no paired samples during the fault" + _twin_note(twin)
    else:
        dev = y[during] - target
        own = _own_depth(run, t) - target
        excess = np.abs(own[during]) - ABS_TOL_MM
        value = float(np.sqrt(np.mean(np.maximum(np.abs(dev), excess) ** 2)))
        before = np.abs(y[(t < onset[0]) & np.isfinite(y)] - target)
        span = f"to {cleared[0]:g} s, judged to the end" if cleared else "to the end"
        note = (f"fault from {onset[0]:g} s {span} ({t[during][-1] - onset[0]:.1f} s); "
                f"paired true depth max {np.max(np.abs(dev)):.2f} mm, mean "
                f"{np.mean(dev):+.2f} mm; own true depth up to "
                f"{np.max(np.abs(own[during])):.1f} mm off the target (tolerance "
                f"{ABS_TOL_MM:g} mm); before the fault max "
                f"{float(before.max()) if before.size else math.nan:.3f} mm")
    hil_measure("depth.fault.sensor.deviation", value, conditions={"fault": fault}, run=run,
                note=note)


@pytest.mark.parametrize(("scenario", "measurement", "kind"), [
    ("fault-controller-silent-recovery", "depth.silence.recovery_time", "silence"),
    ("fault-dut-restart", "depth.restart.recovery_time", "restart"),
    ("fault-saturation-recovery", "depth.fault.saturation.recovery_time", "saturation"),
])
def test_controller_recovery(hil_run, hil_measure, hil_rig, scenario: str, measurement: str,
                             kind: str) -> None:
    spec, run, twin, target = _fault_run(hil_run, hil_rig, scenario)
    if kind == "silence":
        ends = [e.at_s for e in spec.events if e.clear == "controller_silent"]
    elif kind == "restart":
        ends = [e.at_s for e in spec.events if e.dut == "restart"]
    else:       # saturation: the target returns into reach
        ends = [e.at_s for e in spec.events if e.set and "target_depth_mm" in e.set][-1:]
    assert len(ends) == 1, f"{scenario}: expected one {kind} event to time the recovery from"
    t0 = ends[0]
    t, y = paired(run, twin, TRUE_DEPTH, target)
    if twin.record.get("error"):
        value, note = math.nan, _twin_note(twin).removeprefix("; ")
    elif run.record.get("error") or int(np.count_nonzero(t >= t0)) < 2:
        # the DUT did not come back (or the run ended before t0): nothing to time; the
        # measurement notes why (hil_measure adds the run's error)
        value, note = math.nan, f"the run ended at {t[-1]:.2f} s, before a recovery from " \
                                f"{t0:g} s could be timed"
    else:
        paired_back = recovery_time(t, y, t0=t0, target=target, band=BAND, **FILTER)
        own = _own_depth(run, t)
        own_back = recovery_time(t, own, t0=t0, target=target, band=ABS_TOL_MM / target,
                                 **FILTER)
        value = (math.nan if math.isnan(paired_back) or math.isnan(own_back)
                 else max(paired_back, own_back))
        after = (t >= t0 - 5.0) & np.isfinite(y)
        verdict = ("it never left the band" if value == 0.0 else "back in the band"
                   if not math.isnan(value) else "never back in the band for 1 s before "
                   "the end" if math.isnan(paired_back) else f"its own depth never back "
                   f"within {ABS_TOL_MM:g} mm of the target")
        note = (f"from {t0:g} s: {verdict} (±{BAND:.0%}, {BAND * target:g} mm); paired true "
                f"depth {np.min(y[after]):.1f}-{np.max(y[after]):.1f} mm from 5 s before; "
                f"own true depth {np.min(own[after]):.1f}-{np.max(own[after]):.1f} mm")
        value, never = judged_recovery(value, t, t0=t0, band=BAND)
        if never:
            note = f"{never}; {note}"
        if kind == "saturation":
            starts = [e.at_s for e in spec.events if e.set and "target_depth_mm" in e.set]
            away = (t >= starts[0]) & (t < t0)
            if not np.any(y[away] > target * (1.0 + BAND)):
                value = float(t[-1] - t0)
                note = (f"the depth never followed the out-of-reach target (the paired depth "
                        f"stayed within ±{BAND:.0%} of {target:g} mm from {starts[0]:g} s to "
                        f"{t0:g} s): the recovery was not tested, the value is the time "
                        f"observed after it; {note}")
    hil_measure(measurement, value, run=run, note=note)


def _own_depth(run, t: np.ndarray) -> np.ndarray:
    """The run's own mean true depth at the times ``t`` (not paired)."""
    t_run, d = trace(run, TRUE_DEPTH)
    return d if t_run.shape == t.shape else np.interp(t, t_run, d)
