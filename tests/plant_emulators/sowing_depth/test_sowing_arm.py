"""Press-arm geometry against [D]'s depth-sensor calibration (13)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plant_emulators.sowing_depth.arm import PressArm
from plant_emulators.sowing_depth.config import load_rig_config
from plant_emulators.sowing_depth.sensors import (
    CALIBRATION_INTERCEPT_MM,
    CALIBRATION_RANGE_MV,
    CALIBRATION_SLOPE_MM_PER_MV,
    Inclinometer,
    calibration_depth_mm,
)


@pytest.fixture
def arm() -> PressArm:
    return PressArm(load_rig_config().arm)


def geometry_over_calibration_range(arm: PressArm) -> tuple[np.ndarray, np.ndarray]:
    """(X output in mV, true cover in mm) of the exact geometry over x = 2,628 … 4,356 mV."""
    incl = Inclinometer(load_rig_config().inclinometer, np.random.default_rng(0))
    x_mv = np.linspace(*CALIBRATION_RANGE_MV, 500)
    sensor_deg = np.array([incl.mv_to_angle(x) for x in x_mv])
    cover = np.array([arm.cover_mm(a - arm.mount_offset_deg) for a in sensor_deg])
    return x_mv, cover


def test_geometry_reproduces_the_calibration_of_the_paper(arm: PressArm) -> None:
    x_mv, cover = geometry_over_calibration_range(arm)
    slope, intercept = np.polyfit(x_mv, cover, 1)
    assert slope == pytest.approx(CALIBRATION_SLOPE_MM_PER_MV, rel=1e-3)
    assert intercept == pytest.approx(CALIBRATION_INTERCEPT_MM, abs=0.5)
    fit = slope * x_mv + intercept
    r2 = 1.0 - np.sum((cover - fit) ** 2) / np.sum((cover - cover.mean()) ** 2)
    assert r2 > 0.9962                                 # [D] measured R² = 0.9962 with noise
    residual = cover - np.array([calibration_depth_mm(x) for x in x_mv])
    assert np.abs(residual).max() < 1.0                # the arc is not a line: ≤ ~0.9 mm
    near_target = np.abs(cover - 30.0) < 5.0
    assert np.abs(residual[near_target]).max() < 0.45


def test_depth_change_is_l_cos_phi_dphi(arm: PressArm) -> None:
    phi = arm.angle_deg(30.0)
    d_phi = 1e-4
    dc = arm.cover_mm(phi) - arm.cover_mm(phi + d_phi)
    assert dc / d_phi == pytest.approx(arm.sensitivity_mm_per_deg(phi), rel=1e-5)
    assert arm.sensitivity_mm_per_deg(phi) == pytest.approx(
        320.0 * math.cos(math.radians(phi)) * math.pi / 180.0)
    # ≈ 5.4 mm/° on the 320 mm arm, the slope of eq. (13) on a ±30° sensor (papers.md check).
    assert arm.sensitivity_mm_per_deg(phi) == pytest.approx(5.4, abs=0.05)


def test_angle_and_cover_are_inverse(arm: PressArm) -> None:
    for cover in (-12.0, 0.0, 30.0, 60.0, 99.0):
        assert arm.cover_mm(arm.angle_deg(cover)) == pytest.approx(cover, abs=1e-9)
    assert arm.angle_deg(-1e6) == 90.0 and arm.angle_deg(1e6) == -90.0
    assert arm.angle_deg(30.0, pivot_rise_mm=5.0) == pytest.approx(arm.angle_deg(25.0))
