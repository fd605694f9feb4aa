"""Virtual time that advances only when the step's participants are done."""

from __future__ import annotations

from hil.clock.base import Clock, TimingHealth


class LockstepClock(Clock):
    """Virtual time. No wall-clock waits; each step ends when its participants are done
    (the DUT has answered SYNC with its command frames, see :class:`~hil.clock.SyncBarrier`).
    Two runs with the same seed and the same DUT produce identical traces."""

    mode = "lockstep"
    waits_for_participants = True
    batches = True

    def _wait_for(self, tick: int) -> None:
        return None

    def health(self) -> TimingHealth:
        return TimingHealth(mode=self.mode, period_s=self.period_s, ticks=self.tick_index,
                            scheduler="virtual time (lockstep)")
