"""Ground speed: tractor response, slip, Hall pulses, ISOBUS speeds, vibration."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from plant_emulators.fertilizer.ground_speed import GroundSpeedModel, MachineDirection

DT = 0.001
KMH = 1 / 3.6


def _run(config, seed: int, speed_mps: float, seconds: float, every_s: float = 0.05):
    model = GroundSpeedModel(config, np.random.default_rng(seed))
    model.target_speed_mps = speed_mps
    trace = []
    steps = round(every_s / DT)
    for _ in range(round(seconds / every_s)):
        model.advance(steps, DT)
        trace.append((model.true_speed_mps, model.hall_report(), model.wheel_based_speed_mps,
                      model.ground_based_speed_mps, model.vibration_mps2))
    return model, trace


@pytest.mark.parametrize("kmh", [4.0, 6.0, 8.0])
def test_tractor_holds_the_field_speeds_with_small_smooth_variation(rig_config, kmh):
    _, trace = _run(rig_config.ground_speed, 1, kmh * KMH, 60.0)
    v = np.array([t[0] for t in trace[200:]])
    assert v.mean() == pytest.approx(kmh * KMH, rel=0.03)
    assert 0.003 < v.std() / v.mean() < 0.05
    # smooth: no jumps between 50 ms samples larger than the acceleration limit allows
    assert np.max(np.abs(np.diff(v))) <= rig_config.ground_speed.max_accel_mps2 * 0.05 + 1e-9


def test_speed_change_respects_acceleration_limit(rig_config):
    model = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(2))
    model.target_speed_mps = 3.0
    model.advance(1000, DT)
    assert model.true_speed_mps <= rig_config.ground_speed.max_accel_mps2 * 1.0 + 1e-9
    model.advance(20_000, DT)
    assert model.true_speed_mps == pytest.approx(3.0, rel=0.08)


def test_hall_speed_reads_the_slipping_ground_wheel(rig_config):
    model, trace = _run(rig_config.ground_speed, 3, 6.0 * KMH, 60.0)
    true = np.array([t[0] for t in trace[200:]])
    hall = np.array([t[1].wheel_speed_mps for t in trace[200:]])
    ratio = hall.mean() / true.mean()
    gs = rig_config.ground_speed
    # the node's calibration divides by (1 - hall_calibration_frac); the wheel still skids
    assert 1 - ratio * (1 - gs.hall_calibration_frac) == pytest.approx(
        gs.wheel_slip_mean_frac, abs=0.02)
    # the packaged installation is calibrated for the mean skid: it reads true speed ±2 %
    assert ratio == pytest.approx(1.0, abs=0.02)
    pitch = rig_config.ground_speed.metres_per_pulse
    assert abs(model.hall_pulses - model.ground_wheel_distance_m / pitch) <= 1.0
    assert model.hall_report().pulse_count == model.hall_pulses


def test_hall_node_reports_zero_after_the_wheel_stops(rig_config):
    model = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(4))
    assert model.hall_report() == (0.0, 0, 0.0, False)
    model.target_speed_mps = 1.5
    model.advance(10_000, DT)
    moving = model.hall_report()
    assert moving.moving and moving.wheel_speed_mps > 1.0 and moving.last_period_s > 0
    model.target_speed_mps = 0.0
    model.advance(8000, DT)
    stopped = model.hall_report()
    assert not stopped.moving
    assert stopped.wheel_speed_mps == 0.0


def test_hall_speed_decays_while_slowing(rig_config):
    model = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(5))
    model.target_speed_mps = 1.0
    model.advance(10_000, DT)
    model.target_speed_mps = 0.0
    readings = []
    for _ in range(40):
        model.advance(50, DT)
        readings.append(model.hall_report().wheel_speed_mps)
    assert readings[-1] < 0.5 * readings[0]


def test_tractor_speeds_bracket_the_truth(rig_config):
    model, trace = _run(rig_config.ground_speed, 6, 8.0 * KMH, 40.0)
    true = np.array([t[0] for t in trace[100:]])
    wheel_based = np.array([t[2] for t in trace[100:]])
    radar = np.array([t[3] for t in trace[100:]])
    assert wheel_based.mean() / true.mean() - 1 == pytest.approx(
        rig_config.ground_speed.tractor_slip_mean_frac, abs=0.03)
    assert radar.mean() / true.mean() == pytest.approx(1.0, abs=0.02)
    assert np.std(radar / true) > 0.003
    wb = model.wheel_based_report()
    gb = model.ground_based_report()
    assert wb.direction is MachineDirection.FORWARD and gb.direction is MachineDirection.FORWARD
    assert wb.distance_m > model.true_distance_m > 0
    assert gb.distance_m == pytest.approx(model.true_distance_m, rel=0.02)


def test_vibration_grows_with_speed(rig_config):
    def rms(kmh: float) -> float:
        _, trace = _run(rig_config.ground_speed, 7, kmh * KMH, 30.0, every_s=0.01)
        return float(np.sqrt(np.mean(np.square([t[4] for t in trace[500:]]))))

    slow, fast = rms(4.0), rms(8.0)
    assert fast > 1.5 * slow
    expected = rig_config.ground_speed.vibration_rms_mps2_per_mps * 8.0 * KMH
    assert fast == pytest.approx(expected, rel=0.3)


def test_vibration_spectrum_peaks_at_the_frame_mode(rig_config):
    cfg = rig_config.ground_speed
    _, trace = _run(cfg, 8, 6.0 * KMH, 60.0, every_s=0.005)
    vib = np.array([t[4] for t in trace[1000:]])
    spec = np.abs(np.fft.rfft(vib * np.hanning(len(vib))))
    freqs = np.fft.rfftfreq(len(vib), 0.005)
    band = (freqs > 0.5)
    peak = freqs[band][np.argmax(spec[band])]
    assert peak == pytest.approx(cfg.vibration_freq_hz, rel=0.25)


def test_no_slip_no_bias_config_reads_true_speed(rig_config):
    cfg = dataclasses.replace(
        rig_config.ground_speed, wheel_slip_mean_frac=0.0, wheel_slip_sd_frac=0.0,
        tractor_slip_mean_frac=0.0, tractor_slip_sd_frac=0.0, radar_bias_frac=0.0,
        radar_noise_sd_frac=0.0, pulse_spacing_error_sd_frac=0.0, hall_calibration_frac=0.0)
    model, _ = _run(cfg, 9, 1.5, 20.0)
    assert model.wheel_based_speed_mps == model.true_speed_mps
    assert model.ground_based_speed_mps == model.true_speed_mps
    assert model.ground_wheel_distance_m == pytest.approx(model.true_distance_m)
    assert model.hall_report().wheel_speed_mps == pytest.approx(model.true_speed_mps, rel=0.01)


def test_signals_have_units(rig_config):
    model, _ = _run(rig_config.ground_speed, 10, 1.0, 1.0)
    sig = model.signals()
    assert sig["true_speed_mps"] == (model.true_speed_mps, "m/s")
    assert all(unit for _, unit in sig.values())


@pytest.mark.parametrize("engine", ["native", "python"])
def test_ground_speed_step_rules(rig_config, engine):
    model = GroundSpeedModel(rig_config.ground_speed, np.random.default_rng(11), engine=engine)
    with pytest.raises(ValueError, match="dt must be"):
        model.advance(1, 0.01)
    model.advance(1, DT)
    with pytest.raises(ValueError, match="dt changed"):
        model.advance(1, 0.002)
    with pytest.raises(ValueError, match="n must be"):
        model.advance(-2, DT)
    with pytest.raises(TypeError):
        model.advance(1.5, DT)
    assert model.time_s == DT
