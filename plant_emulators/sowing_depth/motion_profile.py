"""On-line motion profiles of a CiA 402 drive: trapezoidal moves and velocity ramps.

A :class:`MotionProfile` holds the drive's demand (position, velocity) and moves it one step at a
time, so a new target may arrive at any step (CiA 402's "change set immediately").

* :meth:`MotionProfile.move_step` (profile position mode): accelerate at ``accel`` up to
  ``v_max``, cruise, then follow the braking curve into the target, which yields a trapezoidal
  (or triangular) velocity profile. The braking curve is the discrete-time one,
  ``v = sqrt((d·dt/2)² + 2·d·s) - d·dt/2``, so that steps of ``dt`` decelerating at ``d`` end
  exactly on the target. A target that cannot be reached without exceeding ``decel`` is
  overshot and approached again.
* :meth:`MotionProfile.velocity_step` (profile velocity mode, halt, quick stop): ramp the
  velocity to a target with ``accel`` while its magnitude grows and ``decel`` while it shrinks.

Units are whatever the caller uses consistently (the drive uses mm, mm/s, mm/s², s).

Example
-------
>>> p = MotionProfile(0.0)
>>> steps = 0
>>> while not p.move_step(0.001, 10.0, 50.0, 250.0, 250.0):
...     steps += 1
>>> p.position, p.velocity
(10.0, 0.0)
>>> 0.39 < steps * 0.001 < 0.41   # triangular: 0.2 s up to 50 mm/s, 0.2 s down
True
"""

from __future__ import annotations

import math

__all__ = ["MotionProfile"]


class MotionProfile:
    """Demand position and velocity of a drive's trajectory generator.

    Parameters
    ----------
    position : float
        Initial demand position.
    velocity : float, default 0
        Initial demand velocity.
    """

    __slots__ = ("position", "velocity")

    def __init__(self, position: float, velocity: float = 0.0) -> None:
        self.position = position
        self.velocity = velocity

    def reset(self, position: float, velocity: float = 0.0) -> None:
        """Put the demand at ``position`` with ``velocity`` (e.g. on enable or mode change)."""
        self.position = position
        self.velocity = velocity

    def move_step(self, dt: float, target: float, v_max: float, accel: float,
                  decel: float) -> bool:
        """Advance one step toward ``target``; return True once the demand rests on it."""
        p = self.position
        v = self.velocity
        rem = target - p
        if rem == 0.0 and v == 0.0:
            return True
        direction = 1.0 if rem > 0.0 or (rem == 0.0 and v < 0.0) else -1.0
        dist = rem * direction
        vt = v * direction
        if vt < 0.0:
            vt_new = vt + decel * dt
            if vt_new > 0.0:
                vt_new = 0.0
        else:
            # Fastest speed from which steps of dt decelerating at decel stop on the target.
            half = 0.5 * decel * dt
            v_stop = math.sqrt(half * half + 2.0 * decel * dist) - half
            v_lim = v_max if v_max < v_stop else v_stop
            if vt > v_lim:
                vt_new = vt - decel * dt
                if vt_new < v_lim:
                    vt_new = v_lim
            else:
                vt_new = vt + accel * dt
                if vt_new > v_lim:
                    vt_new = v_lim
            if vt_new * dt >= dist and vt_new <= v_stop + decel * dt:
                self.position = target
                self.velocity = 0.0
                return True
        self.velocity = vt_new * direction
        self.position = p + self.velocity * dt
        return False

    def velocity_step(self, dt: float, v_target: float, accel: float, decel: float) -> None:
        """Ramp the demand velocity one step toward ``v_target`` and integrate the position."""
        v = self.velocity
        dv = v_target - v
        if dv != 0.0:
            rate = accel if v * dv >= 0.0 else decel
            step = rate * dt
            if dv > step:
                v += step
            elif dv < -step:
                v -= step
            else:
                v = v_target
            self.velocity = v
        self.position += v * dt
