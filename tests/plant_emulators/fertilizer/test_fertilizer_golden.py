"""Golden values: the models' outputs for fixed seeds, as the reference implementation gave them.

The hot loops are tuned for speed (hoisted constants, scheduled events, rows processed in
bulk); none of that may change a result. These values were produced by the straightforward
per-step implementation (commit ffad60c) in the rig's call pattern (``advance(10)`` per 10 ms);
the plant's were updated once for a deliberate change of the physics (issue #16: the rollers'
per-run spread is drawn about its mean, which the meter's calibration absorbs). The tolerance
(1e-12 relative) only absorbs last-bit differences of ``cos``/``pow`` between C libraries; on
the development VM the values match exactly. Update them only for a deliberate change of the
physics, and say so in the commit.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from plant_emulators.fertilizer.flow_sensor import FlowSensor
from plant_emulators.fertilizer.ground_speed import GroundSpeedModel
from plant_emulators.fertilizer.physics import FertilizerPlant

DT = 0.001
REL = 1e-12

# (steps, command V, stalled): ramps, steady running, a stall, a stop, an over-range command.
PLANT_SCRIPT = [(700, 2.0, False), (1300, 5.3, False), (400, 5.3, True), (900, 7.0, False),
                (600, 0.0, False), (300, 12.0, False)]

PLANT = {
    "motor_speed_rpm": 2999.9980115434346,
    "motor_current_a": 2.7802535606043213,
    "hopper_kg": 49.460429086648546,
    "density_factor": 0.9648022837739517,
    "row1_flow_at_meter_gps": 49.67201443482568,
    "row4_flow_at_sensor_gps": 69.54422849752632,
    "row2_metered_g": 137.32469542720048,
    "row3_sensor_passed_g": 127.68444715659523,
    "row4_delivered_g": 117.54964417661718,
    "row1_in_transit_g": 15.886744790857193,
}

SENSOR_REPORTS = 72
SENSOR_LAST = (7.2, 12.404892199390988, 12.404892199390988)   # time, grams, flow
SENSOR_SUM_G = 1056.1973902100895

GROUND = {
    "true_distance_m": 8.821004499648131,
    "ground_wheel_distance_m": 8.441038166879222,
    "wheel_based_distance_m": 9.498340396517193,
    "ground_based_distance_m": 8.79432710453722,
    "vibration_mps2": -1.173944923162477,
    "hall_pulses": 186.0,
}
HALL_WHEEL_SPEED_MPS = 1.5718230783506406


def test_plant_golden_values(rig_config):
    # the golden values were recorded with the flute pulsation estimate of the time (30 % and
    # 10 %; issue #16 bounded it by [F]'s data to 15 % and 5 %): they check the implementation,
    # so they keep the parameters they were recorded with
    meter = dataclasses.replace(rig_config.meter, pulsation_first_harmonic_frac=0.30,
                                pulsation_second_harmonic_frac=0.10)
    plant = FertilizerPlant(dataclasses.replace(rig_config, meter=meter),
                            np.random.default_rng(42))
    for steps, command, stalled in PLANT_SCRIPT:
        plant.command_v, plant.stalled = command, stalled
        for _ in range(steps // 10):
            plant.advance(10, DT)
    signals = plant.signals()
    assert {k: signals[k][0] for k in PLANT} == pytest.approx(PLANT, rel=REL)


def test_sensor_golden_values(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(9), mode="sliding")
    reports = []
    for steps, flow, vibration in ((2500, 0.0, 0.0), (3000, 31.0, 1.5), (1700, 12.5, 3.0)):
        sensor.vibration_rms_mps2 = vibration
        for _ in range(steps // 10):
            sensor.advance(10, DT, flow)
            reports += sensor.take_reports()
    assert len(reports) == SENSOR_REPORTS
    last = reports[-1]
    assert (last.time_s, last.grams_in_window, last.flow_gps) == pytest.approx(SENSOR_LAST,
                                                                               rel=REL)
    assert sum(r.grams_in_window for r in reports) == pytest.approx(SENSOR_SUM_G, rel=REL)


def test_ground_speed_golden_values(rig_config):
    model = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(4))
    for steps, target in ((4000, 2.0), (3000, 6 / 3.6)):
        model.target_speed_mps = target
        for _ in range(steps // 10):
            model.advance(10, DT)
    signals = model.signals()
    assert {k: signals[k][0] for k in GROUND} == pytest.approx(GROUND, rel=REL)
    # the golden value predates the Hall node's field calibration (hall_calibration_frac)
    calibrated = 1.0 - rig_config.ground_speed.hall_calibration_frac
    assert model.hall_report().wheel_speed_mps * calibrated == pytest.approx(
        HALL_WHEEL_SPEED_MPS, rel=REL)
