"""CANopen SYNC as the lockstep barrier, and the DUT's optional step-end frame.

Every ``period_ticks`` ticks the barrier sends SYNC (COB-ID 0x080 by default). In lockstep it
then waits until the DUT's step is complete, handing every frame it receives meanwhile to
``dispatch``. When the DUT's step is complete is for the DUT to say, in one of two ways:

* **by its command frame** (the default): the step ends when every frame id in ``await_ids``
  has arrived. The command frame(s) must then be the DUT's last frame of the step: a frame
  the rig receives after them (right after the step, before the next SYNC) is an error
  naming the frame, the cause and the fix (:class:`StepOrderError`).
* **by the step-end frame** (:data:`STEP_END_ID`, extended id 0x1FFFFFF0, no data): a DUT
  that sends it once after its boot-up, before answering the first SYNC, has announced that
  it marks its steps; from then on each step ends at that frame, so the DUT may send its
  frames in any order, the command first or last. It is the lockstep counterpart of a
  co-simulation participant reporting its step done (an FMU's ``doStep`` returning, an HLA
  federate's time-advance request): bench control, not machine traffic, so it is neither
  handed to ``dispatch`` nor written to the bus log, only counted (:attr:`step_ends`).

Either way, every frame of a step is read within that step, in the order the DUT sent it, so
the bus log is the same bytes run after run. Whether the DUT marks its steps is settled when
its first command frame arrives (the announcement is before it on the same connection, so
the answer does not depend on timing); a step-end frame that comes only later is an error
that says so. A restarted DUT announces again.

The wait has a wall-clock timeout (a watchdog, not simulated time): a DUT that does not
answer fails the step clearly, naming the missing frames and the simulated time. In real
time the barrier only sends SYNC, and step-end frames are counted and otherwise ignored.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection

import can

from hil.errors import BusError, HilError, StepTimeoutError

SYNC_ID = 0x080
#: the DUT's step-end frame: extended (29-bit) id, no data. An extended id so that it meets no
#: CANopen COB-ID; in J1939 terms its data page bits are both set, the page J1939 leaves to
#: ISO 15765-3, so no J1939 parameter group has it either
STEP_END_ID = 0x1FFFFFF0
#: where a DUT author reads the rule (named in the errors)
STEP_RULE_DOC = "docs/guide/clocks.md, 'Where a step ends'"
#: while a lockstep step waits, how often it asks whether the DUT is still alive (s)
ALIVE_POLL_S = 0.05


class StepOrderError(HilError, RuntimeError):
    """A DUT's frames of one lockstep step straddle two steps (the run would depend on timing)."""


def is_step_end(msg: can.Message) -> bool:
    """Whether ``msg`` is a DUT's step-end frame (:data:`STEP_END_ID`, extended)."""
    return msg.arbitration_id == STEP_END_ID and msg.is_extended_id and not msg.is_error_frame


class SyncBarrier:
    """SYNC every ``period_ticks`` ticks; in lockstep, wait for the DUT's step to end.

    Parameters
    ----------
    bus : can.BusABC
        The rig's bus.
    period_ticks : int
        Ticks between SYNCs (the control period over the physics period).
    await_ids : collection of int
        The DUT's command frames.
    dispatch : callable
        Called with every frame received while a step waits (but step-end frames).
    timeout_s : float
        Wall-clock watchdog of one step's wait.
    sync_id : int
        The SYNC's COB-ID.
    on_send : callable, optional
        Called with each SYNC sent (the rig's own nodes hear it).
    with_counter : bool
        SYNC carries CANopen's counter byte.
    await_any : bool
        One of ``await_ids`` is the step's command (alternative command frames).
    """

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
        #: True once the DUT announced that it marks its steps (step-end frame before its
        #: first command frame); settled (``_settled``) when that command frame arrives
        self.marks_steps = False
        self._settled = False
        #: step-end frames received
        self.step_ends = 0
        #: the bus hands the DUT's answers over within ``send`` (:class:`hil.bus.InlineBus`):
        #: nothing can arrive late, so frames after the command are in order by construction
        self.synchronous = bool(getattr(bus, "answers_synchronously", False))
        #: judge frames after a step's end (:meth:`late_frame_error`); off for a DUT whose
        #: harness cannot mark its steps yet (the rig's in-process controllers on a threaded
        #: bus), whose late frames are read as before
        self.check_order = True

    def dut_restarted(self) -> None:
        """A new DUT (power cycle): it announces afresh whether it marks its steps."""
        self.marks_steps = False
        self._settled = False

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
        while True:
            remaining = deadline - time.monotonic()
            if alive is not None and remaining > 0:
                msg = self.bus.recv(min(remaining, ALIVE_POLL_S))
                if msg is None:
                    alive()
                    continue
            else:
                msg = self.bus.recv(max(0.0, remaining)) if remaining > 0 else None
            if msg is None:
                raise StepTimeoutError(self._timeout_message(time_s, pending))
            if is_step_end(msg):
                self.step_ends += 1
                if not self._settled:       # the announcement (after boot-up)
                    self.marks_steps = True
                    continue
                if not self.marks_steps:
                    raise StepOrderError(self._late_announcement(time_s))
                if pending:
                    raise StepOrderError(
                        f"lockstep step at t={time_s:.3f} s: the DUT ended its step (step-end "
                        f"frame 0x{STEP_END_ID:X}) before its command frame "
                        f"{self._ids(pending)}: each step's frames, the command among them, "
                        f"go before the step-end frame ({STEP_RULE_DOC})")
                return
            self.dispatch(msg)
            if not msg.is_error_frame and msg.arbitration_id in pending:
                if self.await_any:
                    pending.clear()
                else:
                    pending.discard(msg.arbitration_id)
                if not pending:
                    self._settled = True
                    if not self.marks_steps:
                        return

    def late_frame_error(self, msg: can.Message, time_s: float) -> StepOrderError | None:
        """Judge a frame received after the step at ``time_s`` ended, before the next SYNC.

        In lockstep the DUT acts only on what the rig sends, so nothing of its own may arrive
        between a step's end and the next SYNC: such a frame belongs to the step just ended
        but came after the frame that ended it, and where it lands would depend on timing.

        Returns
        -------
        StepOrderError or None
            For a data frame or a step-end frame, the error naming the frame, the cause and
            the fix; None for an error frame (the bus makes those), on a bus that answers
            synchronously, or with :attr:`check_order` off.
        """
        if is_step_end(msg):
            self.step_ends += 1
        if self.synchronous or not self.check_order or msg.is_error_frame:
            return None
        frame = f"0x{msg.arbitration_id:X}"
        if is_step_end(msg):
            if self.marks_steps:
                return StepOrderError(
                    f"lockstep step at t={time_s:.3f} s: the DUT sent a second step-end frame "
                    f"0x{STEP_END_ID:X} in one step: send it once per SYNC, after the step's "
                    f"last frame ({STEP_RULE_DOC})")
            return StepOrderError(self._late_announcement(time_s))
        if self.marks_steps:
            return StepOrderError(
                f"lockstep step at t={time_s:.3f} s: the DUT sent frame {frame} after its "
                f"step-end frame 0x{STEP_END_ID:X}: the step-end frame goes after the step's "
                f"last frame ({STEP_RULE_DOC})")
        return StepOrderError(
            f"lockstep step at t={time_s:.3f} s: the DUT sent frame {frame} after its command "
            f"frame {self._ids(self.await_ids)}, which ends the step in lockstep, so that "
            f"frame would land in the next step or this one depending on timing. Either send "
            f"the command frame last in each step, or end each step with the step-end frame "
            f"(extended id 0x{STEP_END_ID:X}, no data) and send one after boot-up "
            f"({STEP_RULE_DOC})")

    def _ids(self, ids: Collection[int]) -> str:
        return (" or " if self.await_any else ", ").join(f"0x{i:X}" for i in sorted(ids))

    def _timeout_message(self, time_s: float, pending: set[int]) -> str:
        what = (f"missing frames {self._ids(pending)}" if pending else
                f"its commands arrived, its step-end frame 0x{STEP_END_ID:X} did not")
        return (f"lockstep step at t={time_s:.3f} s: the DUT did not answer SYNC within "
                f"{self.timeout_s} s ({what})")

    def _late_announcement(self, time_s: float) -> str:
        return (f"lockstep step at t={time_s:.3f} s: the DUT's first step-end frame "
                f"0x{STEP_END_ID:X} came after its first command frame, so the rig had "
                f"already taken the command frame as the end of each step: a DUT that marks "
                f"its steps sends one step-end frame after boot-up, before answering the first "
                f"SYNC ({STEP_RULE_DOC})")
