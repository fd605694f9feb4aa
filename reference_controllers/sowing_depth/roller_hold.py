"""Where the depth controller holds the roller while its depth sensor is dead.

Section 2, "CAN adapter", of ``docs/models/reference-controllers.md``. While the depth loop
regulates, the roller's rod never rests: it runs excursions of ~1-2 mm with a period of 1-2 s
around the position that gives the target depth. When the inclinometer dies that instantaneous
position is wherever the last excursion left it, up to ~2 mm off (issue #16). The best estimate
of the right position is the rod's *mean* over the last seconds of valid control, so the
adapter tracks that mean (a first-order low-pass of the drive's Position actual value 0x6064,
TPDO1) and, when the depth turns invalid on a running machine, drives the rod back to it with
a bounded proportional position loop in the drive's profile-velocity mode::

    tracking (depth valid, control enabled):  m += min(1, T/tau) * (p - m)   (first: m = p)
    each new X voltage (a sign of life):      h  = m
    holding  (depth invalid, enabled):        v  = clamp(k * (h - p), -v_hold, v_hold)

The hold target ``h`` is the mean as it was at the inclinometer's last sign of life, not at
the moment it was declared dead: a frozen output is recognised only ``frozen_after_s`` (0.2 s)
after its last change, and the positions the loop reached meanwhile, steering on a dead
reading, say nothing about the right one.

Constants (the defaults of :class:`RollerHoldParams`, which the adapter's ``hold_*``
parameters override; chosen from the rig's physics, not from seeds):

* ``tau`` = 2 s: the regulating excursions (1-2 s period, 0.5-1 Hz) come through a first-order
  low-pass attenuated by 1/sqrt(1 + (2 pi f tau)^2) = 0.08-0.16, so a 2 mm excursion moves the
  mean by <= 0.3 mm; the soil processes that really move the right position (stubble 5 m,
  compaction 8 m, moisture 20 m correlation lengths: >= 4.5 s at 4 km/h) it follows with 2 s
  of lag. The short terrain band (1 m) is what the excursions chase: after the fault nobody can.
* ``k`` = 5 /s: the hold loop's time constant 1/k = 0.2 s returns a 2 mm offset in ~0.6 s.
  The loop sees the position one SYNC late (TPDO1 of the previous step): its discrete poles
  ``z^2 - z + kT = 0`` stay real (no overshoot) for kT <= 0.25, here kT = 0.05.
* ``v_hold`` = 10 mm/s: a 2 mm offset asks for exactly this, so the bound only acts on a mean
  further away (a fault early in a transient); it keeps the commanded deceleration k * v_hold
  = 50 mm/s^2 far below the drive's profile deceleration (250 mm/s^2, 0x6084), so the drive's
  ramp never lags the loop into an overshoot.

The C build (``firmware/core/roller_hold.c``) computes the same in the same order.

>>> hold = RollerHold(RollerHoldParams())
>>> hold.track(40.0, 0.01); hold.track(42.0, 0.01); round(hold.mean_mm, 12)
40.01
>>> hold.speed(39.0)                       # no sign of life seen with a mean: no target
0.0
>>> hold.mark(); hold.track(44.0, 0.01)    # the target stays the mean at the mark
>>> round(hold.speed(39.0), 12)            # 5 /s * 1.01 mm
5.05
>>> hold.speed(20.0)                       # bounded
10.0
"""

from __future__ import annotations

from dataclasses import dataclass


def _clamp(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


@dataclass(frozen=True)
class RollerHoldParams:
    """The hold's constants (see the module docstring for why these values).

    Parameters
    ----------
    time_constant_s : float
        ``tau``, the low-pass time constant of the tracked mean rod position (s, > 0).
    gain_per_s : float
        ``k``, the position loop's gain (mm/s per mm; 0 holds the rod where it is).
    speed_mm_s : float
        ``v_hold``, the bound of the hold loop's speed command (mm/s, >= 0).
    """

    time_constant_s: float = 2.0
    gain_per_s: float = 5.0
    speed_mm_s: float = 10.0

    def __post_init__(self) -> None:
        if not self.time_constant_s > 0.0:
            raise ValueError(f"hold_time_constant_s must be > 0, got {self.time_constant_s}")
        if not self.gain_per_s >= 0.0:
            raise ValueError(f"hold_gain_per_s must be >= 0, got {self.gain_per_s}")
        if not self.speed_mm_s >= 0.0:
            raise ValueError(f"hold_speed_mm_s must be >= 0, got {self.speed_mm_s}")


class RollerHold:
    """The mean rod position of valid control, and the loop that holds the rod at the mean
    of the depth sensor's last sign of life.

    Parameters
    ----------
    params : RollerHoldParams
        The hold's constants.
    """

    def __init__(self, params: RollerHoldParams) -> None:
        self.params = params
        self.mean_mm: float | None = None
        #: the hold target: the mean at the depth sensor's last sign of life
        self.target_mm: float | None = None

    def reset(self) -> None:
        """Forget the mean and the target (control was switched off: they no longer say
        where to hold)."""
        self.mean_mm = None
        self.target_mm = None

    def mark(self) -> None:
        """The depth sensor showed a sign of life (a new reading): the mean so far becomes
        the hold target."""
        self.target_mm = self.mean_mm

    def track(self, position_mm: float, period_s: float) -> None:
        """One step of valid control at rod position ``position_mm``: update the mean."""
        if self.mean_mm is None:
            self.mean_mm = position_mm
        else:
            alpha = min(1.0, period_s / self.params.time_constant_s)
            self.mean_mm = self.mean_mm + alpha * (position_mm - self.mean_mm)

    def speed(self, position_mm: float) -> float:
        """The rod speed (mm/s, positive extends) that drives the rod to the hold target; 0
        without a target."""
        if self.target_mm is None:
            return 0.0
        p = self.params
        return _clamp(p.gain_per_s * (self.target_mm - position_mm), -p.speed_mm_s,
                      p.speed_mm_s)
