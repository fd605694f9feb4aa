"""The flow module's plausible faults (issue 21): on time, a wrong number that looks
plausible, flagged in the status bits only where a real module would flag it; and a tractor
asked to stop stands still, every speed it reports 0."""

from __future__ import annotations

import numpy as np
import pytest

from plant_emulators.fertilizer import flow_sensor as fs
from plant_emulators.fertilizer.flow_sensor import REPORT_FAULTS, FlowSensor, SensorStatus
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel

DT = 0.001
FLOW = 30.0


def _pair(rig_config, kind: str) -> tuple[list, list]:
    """Reports of a healthy module and of its twin (same seed) with ``kind`` from 5 s."""
    out = []
    for fault in (None, kind):
        sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(7), mode="sliding",
                            engine="python")
        sensor.advance(3000, DT, 0.0)             # the empty-pipe baseline
        sensor.advance(3000, DT, FLOW)
        sensor.take_reports()
        sensor.set_report_fault(fault, sensor.time_s)
        sensor.advance(3000, DT, FLOW)
        out.append(sensor.take_reports())
    return out[0], out[1]


@pytest.mark.parametrize(("kind", "gain", "cleared", "set_"), [
    ("baseline_lost", fs.BASELINE_LOST_GAIN, SensorStatus.BASELINE_READY, None),
    ("overrange", fs.OVERRANGE_GAIN, None, SensorStatus.ADC_OVERRANGE),
    ("implausible", fs.IMPLAUSIBLE_GAIN, None, None),
    ("gain_step", fs.GAIN_STEP, None, None),
])
def test_a_faulty_report_is_the_healthy_one_scaled_and_flagged(rig_config, kind, gain, cleared,
                                                               set_):
    healthy, faulty = _pair(rig_config, kind)
    assert len(healthy) == len(faulty) > 20          # on time, every report
    assert np.mean([h.flow_gps for h in healthy]) == pytest.approx(FLOW, rel=0.1)
    for h, f in zip(healthy, faulty, strict=True):
        assert f.flow_gps == pytest.approx(gain * h.flow_gps)
        assert f.counter == h.counter
        if cleared is not None:
            assert not f.status & cleared and h.status & cleared
        if set_ is not None:
            assert f.status & set_ and not h.status & set_
        if cleared is None and set_ is None:
            assert f.status == h.status                 # good flags: only the number lies


def test_drift_grows_and_stuck_mid_freezes(rig_config):
    healthy, drift = _pair(rig_config, "drift")
    ratios = [d.flow_gps / h.flow_gps for h, d in zip(healthy, drift, strict=True)]
    assert ratios[0] == pytest.approx(1.0, abs=0.01)
    assert ratios[-1] == pytest.approx(1.0 + fs.DRIFT_PER_S * 3.0, abs=0.01)
    assert np.all(np.diff(ratios) > 0)
    healthy, stuck = _pair(rig_config, "stuck_mid")
    values = {round(r.flow_gps, 9) for r in stuck}
    assert len(values) == 1 and values.pop() == pytest.approx(
        fs.STUCK_MID_FRACTION * healthy[0].flow_gps)
    assert [r.counter for r in stuck] == [r.counter for r in healthy]   # still counting


def test_unknown_report_fault_is_refused(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(1))
    with pytest.raises(ValueError, match="unknown report fault"):
        sensor.set_report_fault("melted", 0.0)
    assert set(REPORT_FAULTS) == {"baseline_lost", "overrange", "implausible", "gain_step",
                                  "drift", "stuck_mid"}


@pytest.mark.parametrize("engine", ["python", "native"])
def test_a_tractor_asked_to_stop_stands_still(rig_config, engine):
    gs = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(5), engine=engine)
    gs.target_speed_mps = 6.0 / 3.6
    gs.advance(10000, DT)
    gs.target_speed_mps = 0.0
    # braking at 0.5 m/s2 from ~1.7 m/s takes ~3.4 s; then the Hall node times out after 1 s
    gs.advance(3500, DT)
    assert gs.true_speed_mps == 0.0
    assert gs.wheel_based_report().speed_mps == 0.0 == gs.ground_based_report().speed_mps
    gs.advance(1100, DT)
    hall = gs.hall_report()
    assert hall.wheel_speed_mps == 0.0 and not hall.moving
    pulses = gs.hall_pulses
    gs.advance(3000, DT)
    assert gs.hall_pulses == pulses and gs.true_speed_mps == 0.0
