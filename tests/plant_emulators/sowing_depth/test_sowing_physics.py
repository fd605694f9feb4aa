"""Sowing-depth plant: determinism, stepping, the depth model and the field statistics of [D]."""

from __future__ import annotations

import dataclasses
import math
from functools import cache

import numpy as np
import pytest

from plant_emulators.sowing_depth.config import SowingDepthRigConfig, load_rig_config
from plant_emulators.sowing_depth.physics import OUTLIER_KINDS, SowingDepthPlant, TruthCells
from plant_emulators.sowing_depth.sensors import Inclinometer, calibration_depth_mm

DT = 0.001


def quiet_config(**sections: dict[str, object]) -> SowingDepthRigConfig:
    """The packaged config with the named sections' fields replaced."""
    cfg = load_rig_config()
    return dataclasses.replace(cfg, **{
        name: dataclasses.replace(getattr(cfg, name), **fields)
        for name, fields in sections.items()})


NO_RANDOM_FIELD = {
    "terrain": {"long_wave_sd_mm": 0.0, "short_wave_sd_mm": 0.0, "roll_sd_deg": 0.0},
    "throw": {"noise_sd_mm": 0.0, "row_offset_sd_mm": 0.0, "lateral_tilt_sd_deg": 0.0},
    "soil": {"moisture_sd_percent": 0.0, "compaction_sd_n_per_cm2": 0.0,
             "stubble_sd_relative": 0.0},
    "outliers": {"clod_rate_per_m": 0.0, "bounce_rate_per_m": 0.0, "stubble_rate_per_m": 0.0,
                 "poor_throw_rate_per_m": 0.0},
}


def enable(plant: SowingDepthPlant, mode: int) -> None:
    drive = plant.drive
    plant.advance(30, DT)
    drive.write(0x6060, 0, mode)
    for word in (0x06, 0x07, 0x0F):
        drive.write(0x6040, 0, word)


def hold_rod_at(plant: SowingDepthPlant, rod_mm: float) -> None:
    """Move the rod to ``rod_mm`` in profile position mode, standing still."""
    enable(plant, 1)
    plant.drive.write(0x607A, 0, round(rod_mm * 100))
    plant.drive.write(0x6040, 0, 0x1F)
    plant.advance(10, DT)
    plant.drive.write(0x6040, 0, 0x0F)
    plant.advance(3000, DT)
    assert plant.rod_position_mm == pytest.approx(rod_mm, abs=0.05)


def drive_at(plant: SowingDepthPlant, speed_mps: float, distance_m: float) -> TruthCells:
    plant.drain_truth()
    plant.ground_speed_mps = speed_mps
    steps = math.ceil(distance_m / speed_mps / DT)
    plant.advance(steps, DT)
    return plant.drain_truth()


def field_stats(truth: TruthCells, length_m: float, headland_m: float = 10.0) -> dict[str, float]:
    """[D]'s statistics over the rows, headlands excluded (GB/T 20865: 20-40 mm passes)."""
    sel = (truth.distance_m >= headland_m) & (truth.distance_m <= length_m - headland_m)
    depth = truth.depth_mm[sel]
    passing = depth[(depth >= 20.0) & (depth <= 40.0)]
    inliers = depth[truth.outlier_kind[sel] == 0]
    return {
        "mean": float(depth.mean()),
        "sd": float(depth.std(ddof=1)),
        "pass_rate": 100.0 * passing.size / depth.size,
        "cv_pass_band": 100.0 * passing.std(ddof=1) / passing.mean(),
        "cv_inlier": 100.0 * inliers.std(ddof=1) / inliers.mean(),
        "outlier_fraction": 100.0 * float((truth.outlier_kind[sel] > 0).mean()),
    }


# ---------------------------------------------------------------------- stepping and seeds
def scripted_run(seed: int, chunks: list[int]) -> tuple[dict[str, tuple[float, str]], TruthCells]:
    """The same scenario, advanced in the given chunk sizes between the same commands."""
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(seed))
    enable(plant, 1)
    plant.ground_speed_mps = 1.4
    plant.drive.write(0x607A, 0, 6500)
    plant.drive.write(0x6040, 0, 0x1F)
    for n in chunks:
        plant.advance(n, DT)
    plant.drive.write(0x6040, 0, 0x0F)
    plant.drive.write(0x6060, 0, 3)
    plant.drive.write(0x60FF, 0, -2500)
    for n in chunks:
        plant.advance(n, DT)
    return plant.signals(), plant.drain_truth()


def test_advance_n_equals_n_single_steps_exactly() -> None:
    whole_sig, whole_truth = scripted_run(7, [1500])
    ones_sig, ones_truth = scripted_run(7, [1] * 1500)
    mixed_sig, mixed_truth = scripted_run(7, [1, 2, 3, 500, 994])
    assert whole_sig == ones_sig == mixed_sig
    for a, b in ((whole_truth, ones_truth), (whole_truth, mixed_truth)):
        for field in dataclasses.fields(TruthCells):
            np.testing.assert_array_equal(getattr(a, field.name), getattr(b, field.name))


def test_same_seed_same_run_other_seed_other_field() -> None:
    a_sig, a_truth = scripted_run(11, [1500])
    b_sig, b_truth = scripted_run(11, [1500])
    c_sig, c_truth = scripted_run(12, [1500])
    assert a_sig == b_sig
    np.testing.assert_array_equal(a_truth.depth_mm, b_truth.depth_mm)
    assert a_truth.depth_mm.shape == c_truth.depth_mm.shape
    assert not np.array_equal(a_truth.depth_mm, c_truth.depth_mm)
    assert a_sig["rod_position_mm"] == c_sig["rod_position_mm"], "the drive is not random"


def test_arguments_are_validated() -> None:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(0))
    with pytest.raises(ValueError, match="ground_speed_mps"):
        plant.ground_speed_mps = -1.0
    with pytest.raises(ValueError, match="ground_speed_mps"):
        plant.ground_speed_mps = math.nan
    with pytest.raises(ValueError, match="dt"):
        plant.advance(1, 0.0)
    with pytest.raises(ValueError, match="n"):
        plant.advance(-1, DT)


def test_time_and_distance_advance_with_the_steps() -> None:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(0))
    plant.ground_speed_mps = 2.0
    plant.advance(2500, DT)
    assert plant.time_s == pytest.approx(2.5)
    assert plant.distance_m == pytest.approx(5.0)
    truth = plant.drain_truth()
    assert truth.distance_m[0] == 0.0
    np.testing.assert_allclose(np.diff(truth.distance_m), 0.01)
    assert truth.distance_m[-1] == pytest.approx(5.0, abs=0.011)
    assert truth.depth_mm.shape == (truth.distance_m.size, 12)
    assert plant.drain_truth().distance_m.size == 0


def test_signals_carry_every_output_with_its_unit() -> None:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(0))
    plant.ground_speed_mps = 1.0
    plant.advance(100, DT)
    sig = plant.signals()
    for name in ("time_s", "distance_m", "rod_position_mm", "rod_velocity_mm_s",
                 "motor_current_a", "rod_force_n", "arm_angle_deg", "machine_pitch_deg",
                 "mean_true_depth_mm", "cover_soil_mm", "true_depth_row01_mm",
                 "true_depth_row12_mm", "outlier_row12"):
        assert name in sig
    for name, (value, unit) in sig.items():
        assert isinstance(value, float) and math.isfinite(value), name
        assert isinstance(unit, str) and unit, name
    assert sig["mean_true_depth_mm"][0] == pytest.approx(np.mean(plant.true_depth_mm))


# ---------------------------------------------------------------------- the cylinder in the plant
def test_rod_speed_never_exceeds_50_mm_per_s_in_the_field() -> None:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(3))
    enable(plant, 3)
    plant.ground_speed_mps = 2.0
    peak = 0.0
    for k in range(4000):
        if k % 500 == 0:
            plant.drive.write(0x60FF, 0, 9000 if (k // 500) % 2 else -9000)
        plant.advance(1, DT)
        peak = max(peak, abs(plant.rod_velocity_mm_s))
    assert 49.0 < peak <= 50.0


# ---------------------------------------------------------------------- depth model
def mean_depth(rod_mm: float, speed_mps: float, **sections: dict[str, object]) -> float:
    cfg = quiet_config(**{**NO_RANDOM_FIELD, **sections})
    plant = SowingDepthPlant(cfg, np.random.default_rng(0))
    hold_rod_at(plant, rod_mm)
    return float(drive_at(plant, speed_mps, 5.0).depth_mm.mean())


def test_depth_follows_the_roller_position() -> None:
    v = 1.111
    cfg = load_rig_config()
    eta = cfg.throw.efficiency_max * (1 - cfg.throw.low_speed_loss * math.exp(
        -v / cfg.throw.low_speed_scale_m_per_s))
    shallow, deep = mean_depth(35.0, v), mean_depth(50.0, v)
    assert (deep - shallow) / 15.0 == pytest.approx(eta, rel=1e-6)
    assert shallow == pytest.approx(eta * (35.0 + cfg.machine.seedbed_depth_at_rod_zero_mm))


def test_low_speed_throws_less_soil_on_the_row() -> None:
    depths = [mean_depth(43.0, kmh / 3.6) for kmh in (2.0, 4.0, 6.0)]
    assert depths[0] < depths[1] < depths[2]
    assert depths[0] / depths[2] == pytest.approx(0.894, abs=0.01)     # η(2 km/h)/η(6 km/h)
    assert depths[1] == pytest.approx(30.0, abs=1.0)


def test_wetter_soil_gives_shallower_seed() -> None:
    cfg = load_rig_config()
    only_moisture = quiet_config(**{**NO_RANDOM_FIELD, "soil": {
        **NO_RANDOM_FIELD["soil"], "moisture_sd_percent": 1.2}})
    plant = SowingDepthPlant(only_moisture, np.random.default_rng(4))
    hold_rod_at(plant, 43.0)
    plant.ground_speed_mps = 1.111
    depth, moisture = [], []
    for _ in range(1500):                                  # 150 m, a sample every 0.11 m
        plant.advance(100, DT)
        depth.append(plant.mean_true_depth_mm)
        moisture.append(plant.soil_moisture_percent)
    d, m = np.array(depth), np.array(moisture)
    slope = np.polyfit(m - cfg.soil.moisture_mean_percent, d, 1)
    assert m.std() > 0.5
    assert slope[0] / slope[1] == pytest.approx(cfg.throw.moisture_gain_per_percent, rel=1e-6)


def test_press_arm_reads_cover_and_a_field_slope_as_pitch() -> None:
    flat = quiet_config(**NO_RANDOM_FIELD)
    plant = SowingDepthPlant(flat, np.random.default_rng(0))
    hold_rod_at(plant, 43.0)
    drive_at(plant, 1.111, 2.0)
    cover = plant.cover_soil_mm
    assert cover == pytest.approx(plant.mean_true_depth_mm)
    assert plant.arm_angle_deg == pytest.approx(plant.arm.angle_deg(cover), abs=1e-9)
    sloped = quiet_config(**{**NO_RANDOM_FIELD, "terrain": {
        **NO_RANDOM_FIELD["terrain"], "field_slope_deg": 1.0}})
    uphill = SowingDepthPlant(sloped, np.random.default_rng(0))
    hold_rod_at(uphill, 43.0)
    drive_at(uphill, 1.111, 2.0)
    assert uphill.machine_pitch_deg == pytest.approx(1.0)
    assert uphill.mean_true_depth_mm == pytest.approx(plant.mean_true_depth_mm)
    assert uphill.arm_angle_deg - plant.arm_angle_deg == pytest.approx(1.0, abs=0.02)


def test_rod_motion_moves_the_arm_at_standstill() -> None:
    plant = SowingDepthPlant(quiet_config(**NO_RANDOM_FIELD), np.random.default_rng(0))
    hold_rod_at(plant, 40.0)
    before = plant.arm_angle_deg
    hold_rod_at(plant, 45.0)
    # The carrier (and the arm pivot) went 5 mm down over the same soil: the arm rises.
    assert plant.arm.cover_mm(plant.arm_angle_deg) - plant.arm.cover_mm(before) == \
        pytest.approx(5.0, abs=1e-6)


def test_twelve_rows_spread_around_the_common_depth() -> None:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(5))
    hold_rod_at(plant, 43.0)
    truth = drive_at(plant, 1.111, 60.0)
    inlier = np.where(truth.outlier_kind == 0, truth.depth_mm, np.nan)
    row_means = np.nanmean(inlier, axis=0)
    assert row_means.shape == (12,)
    assert 0.1 < row_means.std() < 1.0            # one actuator: rows differ a little
    assert set(np.unique(truth.outlier_kind)) <= set(OUTLIER_KINDS)


# ---------------------------------------------------------------------- field statistics
@cache
def fixed_roller_run(seed: int) -> dict[str, float]:
    plant = SowingDepthPlant(load_rig_config(), np.random.default_rng(seed))
    hold_rod_at(plant, 43.0)
    return field_stats(drive_at(plant, 4.0 / 3.6, 180.0), 180.0)


@pytest.mark.parametrize("seed", [1, 2])
def test_fixed_good_roller_position_gives_the_spread_of_the_field(seed: int) -> None:
    stats = fixed_roller_run(seed)
    assert stats["mean"] == pytest.approx(30.0, abs=2.0)
    assert 2.5 < stats["cv_inlier"] < 6.0
    assert 88.0 < stats["pass_rate"] < 96.0
    assert 4.0 < stats["outlier_fraction"] < 11.0
    assert 3.0 < stats["sd"] < 8.0, "SD over every seed, outliers included"


@cache
def closed_loop_run(kmh: float, seed: int = 1) -> dict[str, float]:
    """A plain PI on [D]'s calibrated sensor signal, through the CiA 402 drive (pv mode)."""
    cfg = load_rig_config()
    plant_rng, sensor_rng = np.random.default_rng(seed).spawn(2)
    plant = SowingDepthPlant(cfg, plant_rng)
    incl = Inclinometer(cfg.inclinometer, sensor_rng)
    enable(plant, 3)
    speed = kmh / 3.6
    plant.ground_speed_mps = speed
    integral, measured = 0.0, None
    while plant.distance_m < 180.0:
        plant.advance(10, DT)
        reading = incl.sample(plant.time_s, plant.arm.sensor_angle_deg(plant.arm_angle_deg),
                              plant.machine_roll_deg, speed)
        depth = calibration_depth_mm(reading.x_mv)
        measured = depth if measured is None else measured + 0.2 * (depth - measured)
        error = 30.0 - measured
        integral = min(max(integral + 1.0 * error * 0.01, -50.0), 50.0)
        command = 1.5 * error + integral
        plant.drive.write(0x60FF, 0, round(min(max(command, -50.0), 50.0) * 100))
    return field_stats(plant.drain_truth(), 180.0)


@pytest.mark.parametrize(("kmh", "cv_paper", "pass_paper"), [
    (2.0, 3.51, 92.0), (4.0, 2.93, 93.0), (6.0, 3.26, 91.0)])
def test_a_good_controller_reaches_the_statistics_of_table_3(
        kmh: float, cv_paper: float, pass_paper: float) -> None:
    stats = closed_loop_run(kmh)
    assert stats["mean"] == pytest.approx(30.0, abs=1.5)
    assert stats["cv_inlier"] == pytest.approx(cv_paper, abs=0.5)
    assert stats["pass_rate"] == pytest.approx(pass_paper, abs=2.0)
    assert stats["cv_pass_band"] == pytest.approx(stats["cv_inlier"], abs=0.3)


def test_the_controller_beats_a_fixed_roller() -> None:
    assert closed_loop_run(4.0)["cv_inlier"] < fixed_roller_run(1)["cv_inlier"]
