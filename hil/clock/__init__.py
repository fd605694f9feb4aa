"""Clocks: one interface, two implementations.

:class:`RealtimeClock` steps against absolute wall-clock deadlines and records its own timing
health; :class:`LockstepClock` advances virtual time only when the step's participants (the
DUT answering SYNC, up to its command frame or its step-end frame) are done. Plants, metrics
and suites never read the wall clock: they ask the clock.
"""

from hil.clock.base import Clock, TimingHealth, TimingLimits
from hil.clock.lockstep import LockstepClock
from hil.clock.realtime import RealtimeClock
from hil.clock.sync import STEP_END_ID, StepOrderError, SyncBarrier, is_step_end

__all__ = ["STEP_END_ID", "Clock", "LockstepClock", "RealtimeClock", "StepOrderError",
           "SyncBarrier", "TimingHealth", "TimingLimits", "is_step_end", "make_clock"]


def make_clock(mode: str, period_s: float = 0.001) -> Clock:
    """``"realtime"`` or ``"lockstep"`` → a clock of that kind."""
    from hil.errors import ConfigError

    if mode == "realtime":
        return RealtimeClock(period_s)
    if mode == "lockstep":
        return LockstepClock(period_s)
    raise ConfigError(f"unknown clock {mode!r}; expected 'realtime' or 'lockstep'", key="clock")
