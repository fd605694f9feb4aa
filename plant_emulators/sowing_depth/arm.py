"""Geometry of the post-sowing press roller arm that carries the inclinometer.

The arm (length ``L`` = 320 mm, pivot on the seeding carrier) trails the pivot; its roller
(radius ``R`` = 140 mm) rides on the covering soil. With the pivot ``H`` above the seedbed and a
covering-soil height ``c`` under the roller, the arm's angle below horizontal is::

    sin φ = (H - R - c) / L            so   dc = -L · cos φ · dφ

(paper [D] writes h = K·(L + R); the check in papers.md shows the depth change is L·cos φ·dφ).
When the machine is pitched or the carrier has moved since the soil under the roller was
pressed, the plant adds the pivot's rise to ``H`` (see :mod:`.physics`); a gravity-referenced
inclinometer then reads that too. The inclinometer sits on the arm at
``inclinometer_mount_offset_deg``: sensor angle = φ + offset.

``H`` and the offset in ``rig.toml`` are fitted so that this exact geometry, read through a
±30° inclinometer, reproduces [D]'s calibration (13) ``y = -0.065·x + 270.35`` mm over
x = 2,628 … 4,356 mV by least squares (slope to 0.1 %, R² > 0.999); the linear calibration then
differs from the geometry by at most ~0.9 mm at the ends of that range and ~0.4 mm near 30 mm.

Example
-------
>>> from plant_emulators.sowing_depth.config import load_rig_config
>>> arm = PressArm(load_rig_config().arm)
>>> round(arm.cover_mm(arm.angle_deg(30.0)), 9)
30.0
"""

from __future__ import annotations

import math

from plant_emulators.sowing_depth.config import ArmConfig

__all__ = ["PressArm"]


class PressArm:
    """The arm's angle ↔ covering-soil relation.

    Parameters
    ----------
    config : ArmConfig
        Arm length, roller radius, pivot height, sensor mounting offset.
    """

    __slots__ = ("arm_length_mm", "mount_offset_deg", "pivot_height_mm", "roller_radius_mm")

    def __init__(self, config: ArmConfig) -> None:
        self.arm_length_mm = config.arm_length_mm
        self.roller_radius_mm = config.roller_radius_mm
        self.pivot_height_mm = config.pivot_height_above_seedbed_mm
        self.mount_offset_deg = config.inclinometer_mount_offset_deg

    def angle_deg(self, cover_mm: float, pivot_rise_mm: float = 0.0) -> float:
        """Arm angle below horizontal for ``cover_mm`` of soil, the pivot ``pivot_rise_mm`` higher.

        The ratio is clipped to ±1 (arm vertical) for covers the arm cannot reach.
        """
        ratio = (self.pivot_height_mm + pivot_rise_mm - self.roller_radius_mm - cover_mm) \
            / self.arm_length_mm
        if ratio > 1.0:
            ratio = 1.0
        elif ratio < -1.0:
            ratio = -1.0
        return math.degrees(math.asin(ratio))

    def cover_mm(self, angle_deg: float) -> float:
        """Covering-soil height for arm angle ``angle_deg`` (level machine, nominal pivot)."""
        return (self.pivot_height_mm - self.roller_radius_mm
                - self.arm_length_mm * math.sin(math.radians(angle_deg)))

    def sensitivity_mm_per_deg(self, angle_deg: float) -> float:
        """|dc/dφ| = L·cos φ per degree at ``angle_deg``."""
        return self.arm_length_mm * math.cos(math.radians(angle_deg)) * math.pi / 180.0

    def sensor_angle_deg(self, angle_deg: float) -> float:
        """Angle the arm-mounted inclinometer's axis makes with horizontal."""
        return angle_deg + self.mount_offset_deg
