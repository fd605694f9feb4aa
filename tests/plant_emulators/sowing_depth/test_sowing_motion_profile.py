"""Trapezoidal moves and velocity ramps of the drive's trajectory generator."""

from __future__ import annotations

import itertools

import pytest

from plant_emulators.sowing_depth.motion_profile import MotionProfile

DT = 0.001


def trajectory(start: float, target: float, v_max: float, accel: float,
               decel: float, velocity: float = 0.0) -> list[tuple[float, float]]:
    prof = MotionProfile(start, velocity)
    points = [(prof.position, prof.velocity)]
    while not prof.move_step(DT, target, v_max, accel, decel):
        points.append((prof.position, prof.velocity))
        assert len(points) < 100_000
    points.append((prof.position, prof.velocity))
    return points


@pytest.mark.parametrize(("v_max", "accel", "decel", "distance"), list(itertools.product(
    (5.0, 20.0, 50.0), (50.0, 250.0, 1000.0), (50.0, 250.0, 1000.0), (0.05, 1.0, 7.3, 60.0))))
def test_moves_end_on_target_within_velocity_and_ramp_limits(
        v_max: float, accel: float, decel: float, distance: float) -> None:
    points = trajectory(0.0, distance, v_max, accel, decel)
    positions = [p for p, _ in points]
    velocities = [v for _, v in points]
    assert positions[-1] == distance and velocities[-1] == 0.0
    assert max(positions) <= distance + 1e-12, "no overshoot"
    assert max(velocities) <= v_max + 1e-12
    assert min(velocities) >= 0.0
    for a, b in itertools.pairwise(velocities[:-1]):
        assert -decel * DT - 1e-9 <= b - a <= accel * DT + 1e-9


def test_trapezoid_duration_matches_the_closed_form() -> None:
    # 40 mm, 50 mm/s, 250 up, 500 down: 0.2 s + 0.1 s ramps (7.5 mm) and 32.5 mm at 50 mm/s.
    points = trajectory(0.0, 40.0, 50.0, 250.0, 500.0)
    assert (len(points) - 1) * DT == pytest.approx(0.2 + 0.1 + 32.5 / 50.0, abs=0.01)


def test_negative_moves_mirror_positive_ones() -> None:
    up = trajectory(0.0, 12.0, 30.0, 200.0, 300.0)
    down = trajectory(0.0, -12.0, 30.0, 200.0, 300.0)
    assert len(up) == len(down)
    assert all(a == pytest.approx(-b) for (a, _), (b, _) in zip(up, down, strict=True))


def test_a_target_too_close_for_the_speed_is_overshot_and_recovered() -> None:
    points = trajectory(0.0, 1.0, 50.0, 250.0, 250.0, velocity=50.0)
    assert max(p for p, _ in points) == pytest.approx(5.0, abs=0.1)   # 50²/(2·250)
    assert points[-1] == (1.0, 0.0)


def test_velocity_ramp_uses_accel_up_and_decel_down() -> None:
    prof = MotionProfile(0.0)
    for _ in range(100):
        prof.velocity_step(DT, 20.0, 100.0, 400.0)
    assert prof.velocity == pytest.approx(10.0)
    for _ in range(200):
        prof.velocity_step(DT, 20.0, 100.0, 400.0)
    assert prof.velocity == 20.0
    for _ in range(25):
        prof.velocity_step(DT, 0.0, 100.0, 400.0)
    assert prof.velocity == pytest.approx(10.0)
    for _ in range(200):
        prof.velocity_step(DT, -10.0, 100.0, 400.0)
    assert prof.velocity == -10.0
    assert prof.position > 0.0
