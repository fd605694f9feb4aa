"""The boom: sections' widths and offsets from the GNSS antenna, and where they are on the ground.

Offsets follow ISO 11783-10's device element offsets: X (DDI 134) positive forward in the
direction of travel, Y (DDI 135) positive to the right, both from the navigation reference
point, here the GNSS antenna. A section is a line across the direction of travel, ``width_m``
wide, centred at (``fore_aft_m``, ``lateral_m``); the swath it applies is what that line sweeps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Boom", "Section"]


@dataclass(frozen=True)
class Section:
    """One section: width and the offset of its centre from the antenna (m)."""

    width_m: float
    lateral_m: float
    """Y offset of the centre, + right of the antenna."""
    fore_aft_m: float
    """X offset of the centre, + ahead of the antenna (a trailed boom is negative)."""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.width_m) and self.width_m > 0):
            raise ValueError(f"section width must be > 0 m, got {self.width_m}")
        if not (math.isfinite(self.lateral_m) and math.isfinite(self.fore_aft_m)):
            raise ValueError("section offsets must be finite")


@dataclass(frozen=True)
class Boom:
    """The sections of one boom and the look-ahead times the implement declares.

    Parameters
    ----------
    sections : tuple of Section
        Left to right.
    turn_on_s, turn_off_s : float
        How long before a section must apply (stop applying) the command to switch it on (off)
        has to be given: the implement's declared turn-on and turn-off times (ISO 11783-11
        "SC Setpoint Turn On/Off Time", in ms on the bus), >= 0.
    """

    sections: tuple[Section, ...]
    turn_on_s: float = 0.0
    turn_off_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.sections:
            raise ValueError("a boom needs at least one section")
        for name in ("turn_on_s", "turn_off_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0 s, got {value}")

    @classmethod
    def uniform(cls, count: int, width_m: float, *, fore_aft_m: float = 0.0,
                turn_on_s: float = 0.0, turn_off_s: float = 0.0) -> Boom:
        """``count`` equal sections side by side, ``width_m`` in all, centred on the antenna."""
        if count < 1:
            raise ValueError("at least one section")
        w = width_m / count
        return cls(tuple(Section(w, -width_m / 2.0 + w * (i + 0.5), fore_aft_m)
                         for i in range(count)), turn_on_s, turn_off_s)

    @property
    def width_m(self) -> float:
        """Sum of the sections' widths."""
        return float(sum(s.width_m for s in self.sections))

    def section_lines(self, east_m: ArrayLike, north_m: ArrayLike,
                      heading_deg: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Each section's left end, centre and right end on the ground, for antenna poses.

        Returns arrays of shape ``(k, s, 2)`` (k poses, s sections, east/north m).
        """
        e = np.atleast_1d(np.asarray(east_m, dtype=float))[:, None]
        n = np.atleast_1d(np.asarray(north_m, dtype=float))[:, None]
        h = np.radians(np.atleast_1d(np.asarray(heading_deg, dtype=float)))[:, None]
        fwd = np.stack([np.sin(h), np.cos(h)], axis=-1)       # (k, 1, 2)
        right = np.stack([np.cos(h), -np.sin(h)], axis=-1)
        x = np.array([s.fore_aft_m for s in self.sections])[None, :, None]
        y = np.array([s.lateral_m for s in self.sections])[None, :, None]
        half = np.array([s.width_m / 2.0 for s in self.sections])[None, :, None]
        centre = np.stack([e, n], axis=-1) + x * fwd + y * right
        return centre - half * right, centre, centre + half * right
