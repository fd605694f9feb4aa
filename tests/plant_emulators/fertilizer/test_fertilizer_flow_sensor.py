"""Capacitive flow detection module: Table 1 accuracy, baseline, modes, intercept, faults."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from plant_emulators.fertilizer import paper_data as paper
from plant_emulators.fertilizer.flow_sensor import FlowSensor, SensorStatus, _crossing
from plant_emulators.fertilizer.physics import FertilizerPlant

DT = 0.001
PERIOD = 10
"""Steps per rig period in these tests (10 ms, a typical control period)."""


def _rig(config, seed: int, mode: str = "block"):
    rng = np.random.default_rng(seed)
    plant = FertilizerPlant(config, rng)
    sensors = [FlowSensor(config.flow_sensor, rng, mode=mode) for _ in range(config.meter.rows)]
    return plant, sensors


def _period(plant, sensors) -> None:
    """One rig period: plant, then each sensor with the mean flow that passed it."""
    before = plant.sensor_passed_g
    plant.advance(PERIOD, DT)
    for r, sensor in enumerate(sensors):
        sensor.advance(PERIOD, DT, (plant.sensor_passed_g[r] - before[r]) / (PERIOD * DT))


def _table1_errors(config, seeds) -> np.ndarray:
    """Relative error (%) of 10 s sums of reports vs the grams that passed, like Table 1."""
    errors = []
    for seed in seeds:
        plant, sensors = _rig(config, seed)
        for _ in range(300):                           # 3 s: empty-pipe baseline
            _period(plant, sensors)
        for shaft_rpm in paper.TABLE1_SHAFT_RPM:
            plant.command_v = shaft_rpm * config.drive.total_ratio / config.motor.rpm_per_command_v
            for _ in range(200):
                _period(plant, sensors)
            for s in sensors:
                s.take_reports()
            series: list[list[tuple[float, float]]] = [[] for _ in sensors]
            for _ in range(1150):
                _period(plant, sensors)
                for r, s in enumerate(sensors):
                    series[r] += [(rep.grams_in_window, plant.sensor_passed_g[r])
                                  for rep in s.take_reports()]
            for seq in series:
                reported = sum(g for g, _ in seq[1:11])
                passed = seq[10][1] - seq[0][1]
                errors.append(100.0 * (reported - passed) / passed)
    return np.array(errors)


def test_sensor_error_matches_table1(rig_config):
    """Table 1: 0.16-1.20 % (mean 0.74 %) over ~10 s collections at 5-40 r/min."""
    errors = _table1_errors(rig_config, seeds=range(3))
    mae = float(np.mean(np.abs(errors)))
    assert 0.3 < mae < 1.2
    assert float(np.max(np.abs(errors))) < 3.0
    assert abs(float(np.mean(errors))) < 0.6


def test_window_error_is_larger_than_run_error_and_realistic(rig_config):
    plant, sensors = _rig(rig_config, 11)
    for _ in range(300):
        _period(plant, sensors)
    plant.command_v = 3.5
    for _ in range(300):
        _period(plant, sensors)
    sensors[0].take_reports()
    pairs = []
    for _ in range(3050):
        _period(plant, sensors)
        pairs += [(rep.grams_in_window, plant.sensor_passed_g[0])
                  for rep in sensors[0].take_reports()]
    window = np.array([(b[0] - (b[1] - a[1])) / (b[1] - a[1])
                       for a, b in itertools.pairwise(pairs)]) * 100
    assert 0.5 < window.std() < 4.0


def test_baseline_takes_200_conversions(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(1))
    cfg = rig_config.flow_sensor
    expected_s = cfg.baseline_samples * cfg.conversion_time_ms / 1000.0
    sensor.advance(round(expected_s / DT) - 20, DT, 0.0)
    assert not sensor.baseline_ready
    sensor.advance(40, DT, 0.0)
    assert sensor.baseline_ready
    sensor.advance(1500, DT, 0.0)
    reports = sensor.take_reports()
    assert not reports[0].status & SensorStatus.BASELINE_READY
    assert reports[0].flow_gps == 0.0
    assert reports[-1].status & SensorStatus.BASELINE_READY
    assert abs(reports[-1].flow_gps) < 0.05


def test_flow_during_baseline_biases_the_module_low(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(2))
    sensor.advance(3000, DT, 30.0)        # the motor ran during start-up
    sensor.take_reports()
    sensor.advance(5000, DT, 30.0)
    flows = [r.flow_gps for r in sensor.take_reports()]
    assert np.mean(flows) < 1.0           # the baseline swallowed the flow


@pytest.mark.parametrize(("mode", "period_s"), [("block", 1.0), ("sliding", 0.1)])
def test_report_period(rig_config, mode, period_s):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(3), mode=mode)
    sensor.advance(5000, DT, 10.0)
    times = np.array([r.time_s for r in sensor.take_reports()])
    assert np.allclose(np.diff(times), period_s, atol=DT + 1e-9)
    assert sensor.report_period_s == period_s


def _response_time(config, mode: str) -> float:
    """Time from a 0 -> 30 g/s flow step until a report first reads >= 90 %."""
    sensor = FlowSensor(config.flow_sensor, np.random.default_rng(4), mode=mode)
    sensor.advance(3500, DT, 0.0)
    sensor.take_reports()
    step_at = sensor.time_s
    for _ in range(400):
        sensor.advance(PERIOD, DT, 30.0)
        for r in sensor.take_reports():
            if r.flow_gps >= 27.0:
                return r.time_s - step_at
    raise AssertionError("no report reached 90 %")


def test_sliding_window_responds_faster_than_block(rig_config):
    block = _response_time(rig_config, "block")
    sliding = _response_time(rig_config, "sliding")
    assert 0.85 < sliding < 1.05
    assert sliding < block <= 2.05


def test_sliding_reports_carry_the_mode_bit(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(5), mode="sliding")
    sensor.advance(4000, DT, 20.0)
    last = sensor.take_reports()[-1]
    assert last.status & SensorStatus.SLIDING_WINDOW
    assert last.window_s == pytest.approx(1.0, rel=1e-3)


@pytest.mark.parametrize(("intercept", "bias"), [("never", 0.0), ("per_window", 0.4053)])
def test_intercept_policy(rig_config, intercept, bias):
    cfg = dataclasses.replace(rig_config.flow_sensor, intercept=intercept)
    sensor = FlowSensor(cfg, np.random.default_rng(6))
    sensor.advance(20_000, DT, 0.0)       # empty pipe
    reports = [r for r in sensor.take_reports() if r.status & SensorStatus.BASELINE_READY]
    assert np.mean([r.flow_gps for r in reports]) == pytest.approx(bias, abs=0.05)
    assert all(bool(r.status & SensorStatus.INTERCEPT_APPLIED) == (bias > 0) for r in reports)


def test_stuck_module_repeats_its_last_report(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(7))
    sensor.advance(3000, DT, 0.0)
    sensor.advance(2000, DT, 20.0)
    last = sensor.take_reports()[-1]
    sensor.stuck = True
    sensor.advance(3000, DT, 40.0)
    stale = sensor.take_reports()
    assert len(stale) == 3
    assert all(r._replace(time_s=0) == last._replace(time_s=0) for r in stale)
    sensor.stuck = False
    sensor.advance(1000, DT, 40.0)
    fresh = sensor.take_reports()[-1]
    assert fresh.counter == (last.counter + 1) % 256
    assert fresh.flow_gps > 30.0


def test_garbage_module_reports_out_of_range_values(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(8))
    sensor.garbage = True
    sensor.advance(5000, DT, 20.0)
    reports = sensor.take_reports()
    limit = rig_config.flow_sensor.flow_valid_max_gps
    assert all(limit <= r.flow_gps <= 655.35 and limit <= r.grams_in_window <= 655.35
               for r in reports)
    assert [r.counter for r in reports] == list(range(len(reports)))


def test_silent_is_only_a_flag(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(9))
    sensor.silent = True
    sensor.advance(3000, DT, 0.0)
    assert sensor.take_reports()          # the firmware runs; the device must not send
    assert sensor.signals()["silent"] == (1.0, "1")


def test_counter_wraps_at_256(rig_config):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(10), mode="sliding")
    sensor.advance(30_000, DT, 5.0)
    counters = [r.counter for r in sensor.take_reports()]
    assert max(counters) == 255
    assert counters[256] == 0


def test_field_vibration_adds_scatter(rig_config):
    def window_sd(vibration: float) -> float:
        sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(12))
        sensor.vibration_rms_mps2 = vibration
        sensor.advance(60_000, DT, 25.0)
        flows = [r.flow_gps for r in sensor.take_reports()[5:]]
        return float(np.std(flows))

    assert window_sd(20.0) > 1.5 * window_sd(0.0)


@pytest.mark.parametrize("engine", ["native", "python"])
def test_sensor_step_rules(rig_config, engine):
    sensor = FlowSensor(rig_config.flow_sensor, np.random.default_rng(13), engine=engine)
    with pytest.raises(ValueError, match="dt must be"):
        sensor.advance(1, 0.05, 0.0)
    sensor.advance(1, DT, 0.0)
    with pytest.raises(ValueError, match="dt changed"):
        sensor.advance(1, 0.002, 0.0)
    with pytest.raises(ValueError, match="n must be >= 0"):
        sensor.advance(-1, DT, 0.0)
    with pytest.raises(TypeError):
        sensor.advance(1.5, DT, 0.0)
    with pytest.raises(TypeError):
        sensor.advance(1, DT, None)
    assert sensor.time_s == DT
    with pytest.raises(ValueError, match="mode"):
        FlowSensor(rig_config.flow_sensor, np.random.default_rng(13), mode="rolling")


def test_scheduled_window_end_is_where_the_per_step_clock_would_cross():
    """``_crossing`` replaces a per-step ``t += step; t >= due`` test: same floats, same step."""
    rng = np.random.default_rng(17)
    for _ in range(300):
        step = float(rng.uniform(1e-4, 1.1e-2)) * (1.0 + float(rng.normal(0.0, 3e-5)))
        due = float(rng.uniform(0.0, 1.2))
        t0 = float(rng.uniform(-step, step))
        t, k = t0, 0
        while True:
            t += step
            k += 1
            if t >= due:
                break
        assert _crossing(t0, step, due) == (k, t)
