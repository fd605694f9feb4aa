"""Plant physics against [F]'s data and against physics: flows, drift, pulsation, delays."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from plant_emulators.fertilizer import paper_data as paper
from plant_emulators.fertilizer.physics import MAX_STEP_S, FertilizerPlant, _flute_window

DT = 0.001
"""Physics step (s): the rig's 1 kHz."""
FLOW_TOLERANCE_REL = 0.02
"""Steady mean flow vs [F]'s bench targets: the fit's residual (<= 1.3 %) plus averaging."""


def command_for_shaft_rpm(config, shaft_rpm: float) -> float:
    """The drive command (V) that sets ``shaft_rpm`` on the meter shaft."""
    return shaft_rpm * config.drive.total_ratio / config.motor.rpm_per_command_v


def run_at(config, shaft_rpm: float, seed: int, settle_s: float = 3.0):
    plant = FertilizerPlant(config, np.random.default_rng(seed))
    plant.command_v = command_for_shaft_rpm(config, shaft_rpm)
    plant.advance(round(settle_s / DT), DT)
    return plant


@pytest.mark.parametrize(("shaft_rpm", "target_gps"),
                         list(zip(paper.BENCH_SHAFT_RPM, paper.BENCH_TARGET_GPS, strict=True)))
def test_steady_flow_matches_bench_targets(calibrated_config, shaft_rpm, target_gps):
    plant = run_at(calibrated_config, shaft_rpm, seed=1)
    assert plant.shaft_speed_rpm == pytest.approx(shaft_rpm, rel=1e-6)
    before = plant.metered_g
    plant.advance(10_000, DT)
    flows = [(a - b) / 10.0 for a, b in zip(plant.metered_g, before, strict=True)]
    for flow in flows:
        assert flow == pytest.approx(target_gps, rel=FLOW_TOLERANCE_REL)


def test_mass_per_revolution_falls_with_speed(calibrated_config):
    per_rev = []
    for shaft_rpm in paper.BENCH_SHAFT_RPM:
        plant = run_at(calibrated_config, shaft_rpm, seed=2)
        g0, rev0 = plant.metered_g[0], plant.shaft_revolutions
        plant.advance(10_000, DT)
        per_rev.append((plant.metered_g[0] - g0) / (plant.shaft_revolutions - rev0))
    assert per_rev[0] > per_rev[1] > per_rev[2]
    assert per_rev[0] == pytest.approx(115.0, rel=0.02)
    assert per_rev[2] == pytest.approx(82.5, rel=0.02)


def test_uncompensated_meter_delivers_3_to_4_percent_less_than_calibrated(rig_config):
    """[F] Table 2 via papers.md: constant speed misses by ~3.8 % (fertilizer drift)."""
    deficits = []
    for seed in range(6):
        plant = run_at(rig_config, 21.0, seed=seed)
        before = sum(plant.delivered_g)
        plant.advance(50_000, DT)
        delivered = (sum(plant.delivered_g) - before) / 50.0
        calibrated = rig_config.meter.rows * plant.flow_map.flow_gps(21.0)
        deficits.append(100.0 * (1.0 - delivered / calibrated))
    assert 2.8 < float(np.mean(deficits)) < 4.8
    assert all(0.5 < d < 7.0 for d in deficits)


def test_rows_differ_by_their_seeded_spread(rig_config):
    plant = run_at(rig_config, 21.0, seed=3)
    before = plant.metered_g
    plant.advance(10_000, DT)
    flows = np.array([(a - b) / 10.0 for a, b in zip(plant.metered_g, before, strict=True)])
    assert flows.std() > 0.001 * flows.mean()
    assert np.allclose(flows / flows.mean(), np.array(plant.row_gain) / np.mean(plant.row_gain),
                       rtol=0.01)


def _spectrum_peak(signal: np.ndarray, dt: float) -> tuple[float, float]:
    x = signal - signal.mean()
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    freqs = np.fft.rfftfreq(len(x), dt)
    k = int(np.argmax(spec[1:])) + 1
    return float(freqs[k]), float(spec[k])


@pytest.mark.parametrize("shaft_rpm", [12.0, 32.0])
def test_pulsation_at_flute_passing_frequency(calibrated_config, shaft_rpm):
    plant = run_at(calibrated_config, shaft_rpm, seed=4)
    meter, sensor = [], []
    for _ in range(8000):
        plant.advance(1, DT)
        meter.append(plant.flow_at_meter_gps[0])
        sensor.append(plant.flow_at_sensor_gps[0])
    expected = calibrated_config.meter.flutes * shaft_rpm / 60.0
    for series in (np.array(meter), np.array(sensor)):
        freq, _ = _spectrum_peak(series, DT)
        assert freq == pytest.approx(expected, abs=0.2)
    meter_arr = np.array(meter)
    swing = (meter_arr.max() - meter_arr.min()) / (2 * meter_arr.mean())
    a1 = calibrated_config.meter.pulsation_first_harmonic_frac
    a2 = calibrated_config.meter.pulsation_second_harmonic_frac
    assert a1 < swing <= a1 + a2 + 0.01


def test_transport_delays_to_sensor_and_exit(calibrated_config):
    cfg = dataclasses.replace(calibrated_config, transport=dataclasses.replace(
        calibrated_config.transport, dispersion_time_s=0.0))
    plant = FertilizerPlant(cfg, np.random.default_rng(5))
    plant.command_v = command_for_shaft_rpm(cfg, 21.0)
    first = {"meter": None, "sensor": None, "exit": None}
    for step in range(1, 2000):
        plant.advance(1, DT)
        for key, value in (("meter", plant.flow_at_meter_gps[0]),
                           ("sensor", plant.flow_at_sensor_gps[0]),
                           ("exit", plant.delivered_g[0])):
            if first[key] is None and value > 0.0:
                first[key] = step
    to_sensor = round(cfg.transport.meter_to_sensor_delay_s / DT)
    to_exit = round(cfg.transport.sensor_to_exit_delay_s / DT)
    assert first["sensor"] - first["meter"] == to_sensor
    assert first["exit"] - first["sensor"] == to_exit


def test_mass_is_conserved(rig_config):
    plant = run_at(rig_config, 32.0, seed=6, settle_s=5.0)
    hopper0 = rig_config.fertilizer.hopper_initial_kg * 1000.0
    metered = plant.metered_g
    for m, d, t in zip(metered, plant.delivered_g, plant.in_transit_g, strict=True):
        assert m == pytest.approx(d + t)
        assert t > 0.0
    assert hopper0 - plant.hopper_kg * 1000.0 == pytest.approx(sum(metered), rel=1e-9)
    plant.command_v = 0.0
    plant.advance(2000, DT)
    assert plant.motor_speed_rpm == 0.0          # friction holds the shaft: no creep
    assert sum(plant.in_transit_g) == pytest.approx(0.0, abs=1e-6)


def test_stall_stops_flow_and_drives_current_to_the_limit_then_derates(rig_config):
    motor = rig_config.motor
    plant = run_at(rig_config, 21.0, seed=7)
    plant.stalled = True
    plant.advance(1, DT)
    assert plant.motor_speed_rpm == 0.0
    plant.advance(500, DT)
    assert plant.motor_current_a == pytest.approx(motor.current_limit_a)
    assert all(f < 1e-3 for f in plant.flow_at_sensor_gps)   # dispersion tail only
    plant.advance(round(motor.peak_current_time_s / DT), DT)
    assert plant.drive_derated
    assert plant.motor_current_a == pytest.approx(motor.continuous_current_a)
    plant.stalled = False
    plant.advance(1000, DT)
    assert plant.shaft_speed_rpm == pytest.approx(21.0, rel=1e-3)


def test_command_is_clipped_to_0_10_v_and_speed_to_the_drive_maximum(rig_config):
    full = run_at(rig_config, 0.0, seed=8)
    full.command_v = 10.0
    full.advance(1000, DT)
    over = run_at(rig_config, 0.0, seed=8)
    over.command_v = 15.0
    over.advance(1000, DT)
    assert over.motor_speed_rpm == full.motor_speed_rpm
    assert full.motor_speed_rpm == pytest.approx(rig_config.motor.speed_at_full_command_rpm)
    neg = run_at(rig_config, 0.0, seed=8)
    neg.command_v = -3.0
    neg.advance(500, DT)
    assert neg.motor_speed_rpm == 0.0 and sum(neg.metered_g) == 0.0


def test_dead_band_keeps_the_motor_still(rig_config):
    plant = run_at(rig_config, 0.0, seed=9)
    plant.command_v = rig_config.motor.command_deadband_v * 0.9
    plant.advance(500, DT)
    assert plant.motor_speed_rpm == 0.0


def test_low_supply_voltage_limits_speed_by_back_emf(rig_config):
    cfg = dataclasses.replace(rig_config, motor=dataclasses.replace(rig_config.motor,
                                                                   supply_v=12.0))
    plant = FertilizerPlant(cfg, np.random.default_rng(10))
    plant.command_v = 10.0
    plant.advance(2000, DT)
    m = cfg.motor
    expected = (12.0 - plant.motor_current_a * m.armature_resistance_ohm) / m.ke_v_s_per_rad
    assert plant.motor_voltage_v == pytest.approx(12.0)
    assert plant.motor_speed_rpm == pytest.approx(expected * 60 / (2 * math.pi), rel=1e-3)
    assert plant.motor_speed_rpm < m.speed_at_full_command_rpm


def test_speed_loop_settles_within_tens_of_milliseconds(rig_config):
    plant = FertilizerPlant(rig_config, np.random.default_rng(11))
    plant.command_v = command_for_shaft_rpm(rig_config, 12.0)
    target = 12.0 * rig_config.drive.total_ratio
    t95 = None
    for step in range(1, 300):
        plant.advance(1, DT)
        if t95 is None and plant.motor_speed_rpm >= 0.95 * target:
            t95 = step * DT
    assert t95 is not None and t95 < 0.1
    plant.advance(500, DT)
    assert plant.motor_speed_rpm == pytest.approx(target, rel=1e-6)


def test_load_torque_sets_a_plausible_running_current(rig_config):
    plant = run_at(rig_config, 32.0, seed=12)
    assert 0.5 < plant.motor_current_a < rig_config.motor.continuous_current_a


def test_empty_hopper_starves_the_meter(rig_config):
    cfg = dataclasses.replace(rig_config, fertilizer=dataclasses.replace(
        rig_config.fertilizer, hopper_initial_kg=1.0))
    plant = run_at(cfg, 32.0, seed=13, settle_s=30.0)
    assert sum(plant.flow_at_meter_gps) == 0.0
    assert plant.hopper_kg == pytest.approx(0.0, abs=1e-3)
    assert sum(plant.metered_g) == pytest.approx(1000.0, abs=1.0)


def test_signals_cover_every_output_with_units(rig_config):
    plant = run_at(rig_config, 12.0, seed=14, settle_s=0.5)
    sig = plant.signals()
    for name in ("motor_speed_rpm", "shaft_speed_rpm", "motor_current_a", "time_s",
                 "command_v", "hopper_kg"):
        assert name in sig
    for row in range(1, rig_config.meter.rows + 1):
        for output in ("flow_at_meter_gps", "flow_at_sensor_gps", "delivered_g",
                       "in_transit_g", "sensor_passed_g"):
            value, unit = sig[f"row{row}_{output}"]
            assert isinstance(value, float) and unit
    assert sig["motor_speed_rpm"] == (plant.motor_speed_rpm, "rpm")
    assert all(isinstance(v, float) for v, _ in sig.values())


def test_outputs_are_plain_floats_and_tuples(rig_config):
    plant = run_at(rig_config, 12.0, seed=15, settle_s=0.5)
    assert type(plant.motor_speed_rpm) is float
    for out in (plant.flow_at_meter_gps, plant.flow_at_sensor_gps, plant.delivered_g):
        assert isinstance(out, tuple) and len(out) == 4
        assert all(type(v) is float for v in out)


@pytest.mark.parametrize("engine", ["native", "python"])
def test_step_size_rules(rig_config, engine):
    plant = FertilizerPlant(rig_config, np.random.default_rng(16), engine=engine)
    with pytest.raises(ValueError, match="dt must be in"):
        plant.advance(1, MAX_STEP_S * 2)
    plant.advance(1, DT)
    with pytest.raises(ValueError, match="dt changed"):
        plant.advance(1, DT / 2)
    with pytest.raises(ValueError, match="n must be >= 0"):
        plant.advance(-1, DT)
    assert math.isfinite(plant.motor_speed_rpm)


@pytest.mark.parametrize("index_range", [(0, 3), (-4, 0), (1, 10**6)])
def test_flute_window_only_holds_positions_where_no_row_changes_flute(index_range):
    """Inside ``_flute_window`` every row's ``int(fpos + offset)`` is its current flute, so
    the plant may skip the per-row check there (and checks exactly outside it)."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        offsets = rng.uniform(0.0, 1.0, 4).tolist()
        fpos0 = float(rng.uniform(*index_range))
        indices = [int(fpos0 + off) for off in offsets]
        lo, hi = _flute_window(offsets, indices)
        near_a_flute_edge = any(abs(fpos0 + off - round(fpos0 + off)) < 1e-9 for off in offsets)
        assert near_a_flute_edge or lo < fpos0 < hi
        probes = [*np.linspace(lo, hi, 101)[1:-1].tolist(),
                  math.nextafter(lo, math.inf), math.nextafter(hi, -math.inf)]
        for fpos in probes:
            if lo < fpos < hi:
                assert [int(fpos + off) for off in offsets] == indices


def test_metered_and_in_transit_are_consistent_with_delivered(rig_config):
    plant = FertilizerPlant(rig_config, np.random.default_rng(2))
    plant.command_v = 4.0
    plant.advance(3000, DT)
    for m, d, t in zip(plant.metered_g, plant.delivered_g, plant.in_transit_g, strict=True):
        assert t == m - d
        assert 0.0 < d < m
