"""Servo electric cylinder mechanics: speed and force limits, end stops, brake, jam."""

from __future__ import annotations

import math

import pytest

from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.cylinder import ServoCylinder

DT = 0.001


@pytest.fixture
def cyl() -> ServoCylinder:
    cfg = load_rig_config()
    return ServoCylinder(cfg.motor, cfg.cylinder)


def test_motor_constants_in_si(cyl: ServoCylinder) -> None:
    # 6.1 V/krpm = 6.1 / (1000·2π/60) V·s/rad; Kt = Ke in the DC-equivalent model.
    assert cyl.ke_v_s_per_rad == pytest.approx(0.05825, rel=1e-3)
    assert cyl.kt_n_m_per_a == cyl.ke_v_s_per_rad
    assert 1.0 / cyl.ke_v_s_per_rad == pytest.approx(17.2, abs=0.05)   # check: 17.2 rad/s/V
    cfg = load_rig_config()
    tau_m = cfg.motor.ja_kg_m2 * cfg.motor.ra_ohm / cyl.kt_n_m_per_a ** 2
    assert tau_m == pytest.approx(0.032, abs=0.001)                   # check: 6-32 ms


def test_rated_speed_gives_the_rod_speed_of_the_paper(cyl: ServoCylinder) -> None:
    cfg = load_rig_config()
    rod = cfg.motor.rated_speed_rpm / 60.0 * cfg.cylinder.rod_mm_per_motor_rev
    assert rod == pytest.approx(50.0)
    assert cyl.torque_max_n_m * cyl.k_force_n_per_n_m == pytest.approx(9806.65)


def test_velocity_loop_is_a_first_order_lag(cyl: ServoCylinder) -> None:
    for _ in range(5):                                   # one time constant (5 ms)
        cyl.step(DT, 1.0)                                # small: no torque saturation
    assert not cyl.at_force_limit
    assert cyl.velocity_mm_s == pytest.approx(1.0 - math.exp(-1.0), rel=1e-6)


def test_rod_speed_never_exceeds_50_mm_per_s(cyl: ServoCylinder) -> None:
    cyl.load_preload_n = 20_000.0                        # a load pulling the rod out
    peak = 0.0
    for _ in range(600):
        cyl.step(DT, 80.0)
        peak = max(peak, abs(cyl.velocity_mm_s))
    assert peak == pytest.approx(50.0)


def test_force_is_clipped_at_the_push_force_rating(cyl: ServoCylinder) -> None:
    cyl.load_contact_mm = 41.0
    cyl.load_stiffness_n_per_mm = 5000.0
    cyl.load_damping_n_s_per_mm = 1000.0
    peak = 0.0
    for _ in range(2000):
        cyl.step(DT, 50.0)
        peak = max(peak, cyl.force_n)
    assert peak == pytest.approx(9806.65)
    assert cyl.at_force_limit
    assert cyl.load_force_n == pytest.approx(9806.65, rel=1e-3), "stalled where load = limit"
    assert cyl.current_a == pytest.approx(cyl.torque_max_n_m / cyl.kt_n_m_per_a)


def test_end_stops_hold_the_rod_inside_the_stroke(cyl: ServoCylinder) -> None:
    for _ in range(3000):
        cyl.step(DT, 50.0)
    assert cyl.position_mm == 100.0 and cyl.velocity_mm_s == 0.0
    for _ in range(3000):
        cyl.step(DT, -50.0)
    assert cyl.position_mm == 0.0 and cyl.velocity_mm_s == 0.0


def test_brake_holds_when_the_power_stage_is_off(cyl: ServoCylinder) -> None:
    for _ in range(100):
        cyl.step(DT, 30.0)
    cyl.load_preload_n = -500.0
    x = cyl.position_mm
    cyl.hold()
    assert cyl.velocity_mm_s == 0.0 and cyl.current_a == 0.0
    assert cyl.position_mm == x
    assert cyl.force_n == pytest.approx(500.0)


def test_a_jammed_rod_does_not_move_and_saturates_when_driven(cyl: ServoCylinder) -> None:
    cyl.jammed = True
    x = cyl.position_mm
    cyl.step(DT, 20.0)
    assert cyl.position_mm == x and cyl.at_force_limit
    cyl.step(DT, 0.0)
    assert not cyl.at_force_limit


def test_low_bus_voltage_limits_torque_at_speed() -> None:
    import dataclasses
    cfg = load_rig_config()
    cyl = ServoCylinder(dataclasses.replace(cfg.motor, dc_bus_voltage_v=24.0), cfg.cylinder)
    cyl.load_contact_mm = 0.0
    cyl.load_stiffness_n_per_mm = 0.0
    cyl.load_preload_n = -8000.0                         # 8 kN against extension
    for _ in range(500):
        cyl.step(DT, 50.0)
    # (24 V - Ke·ω) / Ra · Kt · k_F = 8 kN → ω, i.e. the rod slows under load at 24 V.
    assert 0.0 < cyl.velocity_mm_s < 45.0
    assert cyl.at_force_limit
