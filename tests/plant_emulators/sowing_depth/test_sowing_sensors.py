"""Inclinometer and draw-wire sensor: transfer, resolution, noise, faults."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from plant_emulators.sowing_depth.arm import PressArm
from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.sensors import (
    CALIBRATION_RANGE_MV,
    DrawWireSensor,
    Inclinometer,
    calibration_depth_mm,
    calibration_signal_mv,
)


def quiet_inclinometer(**overrides: float) -> Inclinometer:
    cfg = dataclasses.replace(load_rig_config().inclinometer, noise_sd_deg=0.0,
                              vibration_noise_sd_deg_per_m_per_s=0.0, accuracy_deg=0.0,
                              **overrides)
    return Inclinometer(cfg, np.random.default_rng(0))


def test_output_span_is_0_to_5_v_over_plus_minus_30_deg() -> None:
    incl = quiet_inclinometer()
    assert incl.angle_to_mv(-30.0) == 0.0
    assert incl.angle_to_mv(0.0) == 2500.0
    assert incl.angle_to_mv(30.0) == 5000.0
    assert incl.angle_to_mv(45.0) == 5000.0, "clipped at the range"
    assert incl.config.mv_per_deg == pytest.approx(83.333, abs=1e-3)


def test_calibration_round_trip_within_resolution_over_the_paper_range() -> None:
    """mV → angle → sensor → mV, and depth → mV → eq. (13) → depth, at the ADC resolution."""
    incl = quiet_inclinometer()
    for t, x_mv in enumerate(np.arange(CALIBRATION_RANGE_MV[0], CALIBRATION_RANGE_MV[1] + 1, 7)):
        reading = incl.sample(10.0 * t, incl.mv_to_angle(x_mv), 0.0)
        assert abs(reading.x_mv - x_mv) <= 1, x_mv       # 0.01° = 0.83 mV, ADC 1 mV
        depth = calibration_depth_mm(x_mv)
        assert abs(calibration_depth_mm(reading.x_mv) - depth) <= 0.065 + 1e-9
        assert calibration_signal_mv(depth) == pytest.approx(x_mv)


def test_arm_through_sensor_through_calibration_reads_depth() -> None:
    """Cover → arm angle → sensor mV → eq. (13): within the geometry's nonlinearity."""
    incl = quiet_inclinometer()
    arm = PressArm(load_rig_config().arm)
    for t, cover in enumerate(np.linspace(-12.0, 99.0, 60)):
        reading = incl.sample(10.0 * t, arm.sensor_angle_deg(arm.angle_deg(cover)), 0.0)
        assert CALIBRATION_RANGE_MV[0] - 12 <= reading.x_mv <= CALIBRATION_RANGE_MV[1] + 12
        assert calibration_depth_mm(reading.x_mv) == pytest.approx(cover, abs=1.0)


def test_angle_resolution_is_a_hundredth_of_a_degree() -> None:
    incl = quiet_inclinometer(adc_resolution_mv=0.001)
    reading = incl.sample(0.0, 12.3456, -0.0049)
    assert reading.x_deg == pytest.approx(12.35)
    assert reading.y_deg == 0.0


def test_noise_bias_and_vibration_are_seeded_and_realistic() -> None:
    cfg = load_rig_config().inclinometer
    readings = []
    incl = Inclinometer(cfg, np.random.default_rng(1))
    for k in range(4000):
        readings.append(incl.sample(k * 0.01, 10.0, 0.0, ground_speed_mps=0.0).x_deg)
    x = np.array(readings[100:])
    assert abs(x.mean() - 10.0) <= cfg.accuracy_deg / 2 + 0.005
    assert x.std() == pytest.approx(cfg.noise_sd_deg, rel=0.15)
    moving = Inclinometer(cfg, np.random.default_rng(1))
    fast = np.array([moving.sample(k * 0.01, 10.0, 0.0, ground_speed_mps=2.0).x_deg
                     for k in range(4000)])
    expected_sd = cfg.noise_sd_deg + 2.0 * cfg.vibration_noise_sd_deg_per_m_per_s
    assert fast.std() == pytest.approx(expected_sd, rel=0.1)
    again = Inclinometer(cfg, np.random.default_rng(1))
    assert [again.sample(k * 0.01, 10.0, 0.0).x_deg for k in range(50)] == readings[:50]


def test_response_lag_follows_the_time_constant() -> None:
    incl = quiet_inclinometer(adc_resolution_mv=0.001, resolution_deg=1e-6)
    incl.sample(0.0, 0.0, 0.0)
    reading = incl.sample(0.02, 10.0, 0.0)                # one 20 ms time constant later
    assert reading.x_deg == pytest.approx(10.0 * (1.0 - np.exp(-1.0)), abs=1e-4)


def test_stuck_and_noisy_faults() -> None:
    cfg = load_rig_config().inclinometer
    incl = Inclinometer(cfg, np.random.default_rng(2))
    first = incl.sample(0.0, 5.0, 1.0)
    incl.stuck = True
    assert incl.sample(0.01, 20.0, -3.0) == first
    incl.stuck = False
    assert incl.sample(1.0, 20.0, -3.0).x_deg == pytest.approx(20.0, abs=0.2)
    incl.noisy = True
    noisy = np.array([incl.sample(1.0 + k * 0.01, 20.0, 0.0).x_deg for k in range(2000)])
    assert noisy.std() == pytest.approx(cfg.noise_sd_deg * cfg.noisy_fault_gain, rel=0.25)


def test_draw_wire_resolution_noise_linearity_and_loss() -> None:
    cfg = load_rig_config().draw_wire
    wire = DrawWireSensor(cfg, np.random.default_rng(3))
    values = np.array([wire.sample(43.21) for _ in range(5000)], dtype=float)
    steps = values / cfg.resolution_mm
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    assert abs(values.mean() - 43.21) <= cfg.linearity_error_mm + 0.01
    assert values.std() == pytest.approx(np.hypot(cfg.noise_sd_mm, cfg.resolution_mm / 12**0.5),
                                         rel=0.15)
    quiet = DrawWireSensor(dataclasses.replace(cfg, noise_sd_mm=0.0, linearity_error_mm=0.0),
                           np.random.default_rng(3))
    assert quiet.sample(43.21) == pytest.approx(43.2)
    assert quiet.sample(-4.0) == 0.0 and quiet.sample(400.0) == cfg.range_mm
    wire.lost = True
    assert wire.sample(43.21) is None
