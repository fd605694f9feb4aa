"""CANopen SYNC as the lockstep barrier.

Every ``period_ticks`` ticks the barrier sends SYNC (COB-ID 0x080 by default). In lockstep it
then waits until every frame id in ``await_ids`` has arrived (the DUT's command frames), handing
every frame it receives meanwhile to ``dispatch``. The wait has a wall-clock timeout (a
watchdog, not simulated time): a DUT that does not answer fails the step clearly, naming the
missing frames and the simulated time. In real time the barrier only sends SYNC.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection

import can

from hil.errors import BusError, StepTimeoutError

SYNC_ID = 0x080
#: while a lockstep step waits, how often it asks whether the DUT is still alive (s)
ALIVE_POLL_S = 0.05


class SyncBarrier:
    def __init__(self, bus: can.BusABC, *, period_ticks: int, await_ids: Collection[int],
                 dispatch: Callable[[can.Message], None], timeout_s: float = 2.0,
                 sync_id: int = SYNC_ID, on_send: Callable[[can.Message], None] | None = None,
                 with_counter: bool = False, await_any: bool = False) -> None:
        if period_ticks < 1:
            raise ValueError(f"SYNC period must be >= 1 tick, got {period_ticks}")
        self.bus = bus
        self.period_ticks = period_ticks
        self.await_ids = frozenset(await_ids)
        self.dispatch = dispatch
        self.timeout_s = timeout_s
        self.sync_id = sync_id
        self.on_send = on_send
        self.with_counter = with_counter
        #: True: one of ``await_ids`` completes the step (alternative command frames)
        self.await_any = await_any
        self.counter = 0
        self.syncs_sent = 0
        #: called while the step waits for the DUT and nothing arrives (every
        #: ``ALIVE_POLL_S``): raises when the DUT is gone, so a crash ends the step at once
        #: instead of after the timeout
        self.alive: Callable[[], None] | None = None

    def due(self, tick: int) -> bool:
        return tick % self.period_ticks == 0

    def next_due(self, tick: int) -> int:
        """The first tick after ``tick`` at which SYNC is due."""
        return (tick // self.period_ticks + 1) * self.period_ticks

    def complete(self, tick: int, time_s: float, *, wait: bool) -> None:
        if not self.due(tick):
            return
        self.counter = self.counter % 240 + 1
        data = bytes([self.counter]) if self.with_counter else b""
        sync = can.Message(arbitration_id=self.sync_id, data=data, is_extended_id=False,
                           timestamp=time_s)
        try:
            self.bus.send(sync)
        except can.CanError as exc:
            raise BusError(f"cannot send SYNC at t={time_s:.3f} s: {exc}") from exc
        self.syncs_sent += 1
        if self.on_send is not None:
            self.on_send(sync)
        if wait and self.await_ids:
            self._await(time_s)

    def _await(self, time_s: float) -> None:
        pending = set(self.await_ids)
        start = time.monotonic()
        deadline = start + self.timeout_s
        alive = self.alive
        while pending:
            remaining = deadline - time.monotonic()
            if alive is not None and remaining > 0:
                msg = self.bus.recv(min(remaining, ALIVE_POLL_S))
                if msg is None:
                    alive()
                    continue
            else:
                msg = self.bus.recv(max(0.0, remaining)) if remaining > 0 else None
            if msg is None:
                missing = (" or " if self.await_any else ", ").join(
                    f"0x{i:X}" for i in sorted(pending))
                raise StepTimeoutError(
                    f"lockstep step at t={time_s:.3f} s: the DUT did not answer SYNC within "
                    f"{self.timeout_s} s (missing frames {missing})")
            self.dispatch(msg)
            if not msg.is_error_frame and msg.arbitration_id in pending:
                if self.await_any:
                    break
                pending.discard(msg.arbitration_id)
