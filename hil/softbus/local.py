"""A client of an embedded software bus in the same process, without a socket (lockstep rigs).

:class:`LocalBus` is a python-can bus whose ``recv`` runs the bus's event loop in the
caller's thread; :class:`LocalEndpoint` is its session on the bus core (frames in and out as
objects, never as text).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol

import can

from hil.softbus.loop import EventLoop, sched_yield
from hil.softbus.protocol import Frame, ProtocolError
from hil.softbus.session import ClientSession
from hil.softbus.settings import DEFAULT_CHANNEL

if TYPE_CHECKING:
    from hil.softbus.core import BusCore


class LoopOwner(Protocol):
    """What a local client uses of the bus whose loop it runs while it waits: a
    :class:`~hil.softbus.server.SoftwareBus` (its loop, its core, the lock that says which
    thread runs the loop, and its list of local drivers). Named here as a role so that this
    module does not import the server, which imports it."""

    host: str
    port: int
    _state: BusCore
    _loop: EventLoop | None
    _stopping: bool
    _waiting: int
    _lock: threading.Lock
    _unpark: threading.Event
    _drivers: list[LocalBus]
    _locals: int

    def _acquire(self) -> BusCore: ...
    def _hand_over(self) -> None: ...
    def _owning(self) -> AbstractContextManager[BusCore]: ...

class LocalEndpoint(ClientSession):
    """A client in the server's own process (:class:`LocalBus`): frames go in and out as
    objects, never as text on a socket. Its receive queue is bounded like a socket's buffer:
    beyond ``max_queue`` frames, frames for it are dropped and counted."""

    local = True

    def __init__(self, server: BusCore, channel: str, max_queue: int) -> None:
        super().__init__(server)
        self.channel = channel
        self.raw = True
        self.name = "local"
        self.max_queue = max_queue
        self.rx: deque[can.Message] = deque()

    def deliver_frame(self, frame: Frame, stamp: float) -> None:
        """Queue a frame as python-can's socketcand client would read it from the wire."""
        if len(self.rx) >= self.max_queue:
            self._count_slow()
            return
        stamp = round(stamp, 6)  # the wire carries microseconds
        if frame.error:
            msg = can.Message(timestamp=stamp, arbitration_id=frame.can_id & 0x1FFFFFFF,
                              is_error_frame=True, data=bytearray(1), dlc=1,
                              is_extended_id=True, is_rx=True, channel=self.channel)
        else:
            data = bytearray(frame.data)
            msg = can.Message(timestamp=stamp, arbitration_id=frame.can_id, data=data,
                              dlc=len(data), is_extended_id=frame.extended, is_rx=True,
                              channel=self.channel)
        self.rx.append(msg)
        self.stats.sent += 1

    def deliver(self, line: bytes) -> None:  # pragma: no cover - _broadcast sends frames
        raise AssertionError("a local endpoint takes frames, not lines")

    deliver_many = deliver  # type: ignore[assignment]


class LocalBus(can.BusABC):
    """A client of an embedded :class:`SoftwareBus` in the same process, for lockstep loops.

    Why (measured, fertilizer field run, firmware over the embedded bus, 630 SYNC round trips,
    ~9 rig frames per step): with python-can's socketcand client every rig frame is a socket
    write that wakes the bus thread and waits to get the GIL back (~25 µs per frame), and each
    SYNC round trip is four hand-offs between threads and processes (rig -> bus thread -> DUT
    -> bus thread -> rig, ~240 µs). A step (9 frames + SYNC -> the firmware's answer) took
    p50 ~420 µs that way, ~150 µs here (~100 µs with ``busy_poll_us=300``; see
    ``benchmarks/bench_softbus.py::test_lockstep_step``). Here:

    - ``send`` hands the frame to the server directly (stamped, fault-checked, paced, logged
      and ordered as any client's frame); lines for socket clients are written once per step:
      they wait in the server's batch until this bus's next ``recv`` (write-behind, the
      lockstep pattern: send a step's frames and SYNC, then wait for the DUT);
    - ``recv`` runs the server's loop in the caller's thread until a frame for this client
      arrives: the DUT's answer reaches the rig in two hand-offs (rig -> DUT -> rig), and the
      bus thread sleeps meanwhile (it takes the loop back when this bus has not run it for
      ``takeover_s``, so other clients are served while the rig does something else).

    Frames a socket client would read arrive here as python-can's socketcand client reads
    them (same fields, stamps of the server's clock). Frames are delayed until the next
    ``recv``/``flush``: use it where the caller waits for the bus after sending (lockstep),
    not in a real-time loop. ``busy_poll_us`` spins in ``recv`` for that long before blocking.
    """

    def __init__(self, softbus: LoopOwner, channel: str = DEFAULT_CHANNEL, *,
                 busy_poll_us: float = 0.0, max_queue: int = 100_000, **kwargs: Any) -> None:
        self._softbus = softbus
        self.channel_info = f"local client of the software bus on {softbus.host}:{softbus.port}"
        self.driving = False
        self.last_drive = float("-inf")  # the bus thread serves until this bus is used
        self.busy_poll_s = max(0.0, busy_poll_us) / 1e6
        self._channel = channel
        with softbus._owning() as state:
            self._endpoint = LocalEndpoint(state, channel, max_queue)
            state.stats.clients_seen += 1
            softbus._locals += 1
            if softbus._locals > 1:
                self._endpoint.name = f"local-{softbus._locals}"
            state.attach(self._endpoint)
        softbus._drivers.append(self)
        self._closed = False
        super().__init__(channel=channel, **kwargs)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self._closed:
            raise can.CanOperationError("the local software bus client is shut down")
        data = msg.data
        try:  # as a socketcand client sends it: id, extended flag, dlc bytes (no error flag)
            frame = Frame(msg.arbitration_id,
                          bytes(data) if len(data) == msg.dlc else bytes(data[:msg.dlc]),
                          msg.is_extended_id)
        except ProtocolError as exc:
            raise can.CanOperationError(f"software bus: cannot send: {exc}") from exc
        softbus = self._softbus
        state = softbus._acquire()
        try:
            if state._batch is None:
                state._batch = {}  # write-behind: flushed by recv()/flush() (or a takeover)
            endpoint = self._endpoint
            endpoint.stats.received += 1
            if state.arbiter is None and not state.faults:  # submit(), minus two calls
                state.stats.frames_in += 1
                state._broadcast(endpoint, frame, self._channel, time.monotonic())
            else:
                state.submit(endpoint, frame)
        finally:
            softbus._lock.release()
        self.last_drive = time.monotonic()

    def flush(self) -> None:
        """Write out the frames this bus sent since its last ``recv``."""
        with self._softbus._owning() as state:
            if state._batch is not None:
                state.end_batch()

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        rx = self._endpoint.rx
        if rx and self._softbus._state._batch is None:
            return rx.popleft(), False
        softbus = self._softbus
        if self._closed or softbus._loop is None:
            return (rx.popleft() if rx else None), False
        loop = softbus._loop
        self.driving = True
        state = softbus._acquire()
        try:
            if state._batch is not None:
                state.end_batch()
            if rx:
                return rx.popleft(), False
            loop.run_once(0.0, spin=False)
            if rx or timeout == 0.0:
                return (rx.popleft() if rx else None), False
            clock = time.perf_counter
            start = clock()
            deadline = None if timeout is None else start + timeout
            if self.busy_poll_s > 0.0:
                end = start + self.busy_poll_s
                if deadline is not None:
                    end = min(end, deadline)
                while not rx and clock() < end:
                    sched_yield()  # a DUT woken on this vCPU runs now, not after the spin
                    loop.run_once(0.0, spin=False)
            while not rx and not softbus._stopping:
                left = None if deadline is None else deadline - clock()
                if left is not None and left <= 0.0:
                    break
                loop.run_once(left, spin=False)
                if softbus._waiting:  # a control call woke the loop: let it in, then go on
                    softbus._hand_over()
            return (rx.popleft() if rx else None), False
        finally:
            softbus._lock.release()
            self.driving = False
            self.last_drive = time.monotonic()

    def shutdown(self) -> None:
        if self._closed:
            return
        self._closed = True
        softbus = self._softbus
        try:
            if softbus._loop is not None:
                with softbus._owning() as state:
                    if state._batch is not None:
                        state.end_batch()
                    state.detach(self._endpoint)
        finally:
            if self in softbus._drivers:
                softbus._drivers.remove(self)
            softbus._unpark.set()
            super().shutdown()

