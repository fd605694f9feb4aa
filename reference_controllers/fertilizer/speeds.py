"""Which ground speed a field rate is computed from.

The terminal names one source in its set-point (FertSetpoint.SpeedSource: the implement's Hall
ground wheel, the tractor's wheel-based speed PGN 65096, or its ground-based speed PGN 65097).
The two wheels read the ground through slip and skid: a wheel that skids 1 % less than on the
drive its calibration was made on reads 1 % fast, and a per-area rate computed from it
over-applies by as much for the whole pass (issue #29's dispersed campaign: rows over-applied
by 2.2-2.7 % on a Hall wheel reading 1.6-2.5 % fast). A ground-based speed (a radar or GNSS
receiver on the tractor) has no slip, so the reference uses it *whenever it hears one*, as its
ISOBUS mode does, and the terminal's source only while none is heard: ``ground_speed_first_s``
(0.3 s, three missed 100 ms frames, the ISOBUS mode's timeout) is how old the last valid
ground-based speed may be; 0 obeys SpeedSource alone.

Time is counted in control steps, as the flow reports' staleness is (``rows.FlowRows``): a
frame that arrived before step ``k`` has the arrival step ``k``.
"""

from __future__ import annotations

from collections.abc import Mapping

#: a J1939 "not available" / error speed decodes above the signal's valid maximum
MAX_VALID_SPEED_MPS = 64.255
#: the sources FertSetpoint.SpeedSource names, by value
SPEED_SOURCES = ("hall", "wheel", "ground")


def valid_speed(value: float) -> bool:
    """Whether a decoded speed is a speed (not J1939 "not available", not negative)."""
    return 0.0 <= value <= MAX_VALID_SPEED_MPS


class GroundSpeedFirst:
    """When the last valid ground-based speed was heard, and whether it is still fresh."""

    def __init__(self, within_s: float, period_s: float) -> None:
        if not within_s >= 0.0:
            raise ValueError(f"ground_speed_first_s must be >= 0, got {within_s}")
        self.within_steps = within_s / period_s if within_s > 0.0 else None
        self.heard_step: int | None = None

    def heard(self, value: float, step: int) -> None:
        """A ground-based speed frame arrived before step ``step``."""
        self.heard_step = step if valid_speed(value) else None

    def fresh(self, step: int) -> bool:
        """A valid ground-based speed was heard recently enough to be used at ``step``."""
        return (self.within_steps is not None and self.heard_step is not None
                and step - self.heard_step <= self.within_steps + 1e-9)

    def field_speed(self, speeds: Mapping[str, float], selected: str | None, step: int) -> float:
        """The speed (m/s) for eq. 1: the ground-based one while fresh, else ``selected``'s
        (the terminal's choice; ``None``: no source, 0)."""
        if selected is None:
            return 0.0
        if self.fresh(step):
            return speeds["ground"]
        return speeds[selected]
