"""The rig's ISOBUS network: internal control functions on one CAN bus, as one rig device.

:class:`IsobusNetwork` hosts the rig's control functions (tractor ECU, Task Controller, ...),
gives each an :class:`~hil.isobus.port.IsobusPort`, claims their addresses (ISO 11783-5,
:mod:`hil.isobus.address_claim`), keeps the table of the external control functions it hears,
and carries their parameter groups in single frames, TP or ETP (ISO 11783-3,
:mod:`hil.isobus.transport`). It is a :class:`hil.rig.device.Device`: it never reads a clock
and has no thread; the runner (or :func:`hil.isobus.wire.drive`) tells it the run time through
:meth:`~IsobusNetwork.next_due`, :meth:`~IsobusNetwork.emit` and
:meth:`~IsobusNetwork.on_frame`, so it runs unchanged under the lockstep and the real-time
clock.

Frames one internal function sends to another go round inside the network (a CAN controller
does not hear its own frames); every frame it sends also goes on the bus.

Why not can-j1939 (PyPI ``can-j1939`` 2.0.12, ``import j1939``), which does address claim and TP:
its :class:`j1939.ElectronicControlUnit` starts a job thread in its constructor and every
timer of its transport (``j1939/j1939_21.py``: T1-T4, the BAM interval) and of its address
claim is a deadline computed from ``time.time()`` and waited for with a sleeping thread. There
is no way to hand it the run time, so it cannot run in lockstep (where a 60 s run takes a
fraction of a second) without patching the module's clock; it also has no ETP. This layer is
therefore our own, checked against can-j1939 on a python-can ``virtual`` bus in real time by
``tests/hil/isobus/test_j1939_probe.py`` (address claim both ways with contention, BAM and
RTS/CTS transfers both ways, byte-identical payloads).
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict, deque
from collections.abc import Iterable
from dataclasses import dataclass

import can

from hil.errors import FrameError
from hil.isobus.address_claim import AddressClaimer, AddressTable
from hil.isobus.can_id import decode_id, encode_id
from hil.isobus.faults import IsobusFaults
from hil.isobus.name import IsobusName
from hil.isobus.port import GLOBAL_ADDRESS, NULL_ADDRESS, Application, Handler, Received
from hil.isobus.tp_messages import PGN_ADDRESS_CLAIMED, PGN_REQUEST, TRANSPORT_PGNS
from hil.isobus.transport import TransportLayer, TransportTiming
from hil.rig.device import Device

#: how often applications without a ``next_due`` of their own are ticked
APP_TICK_S = 0.01
#: an application due within this of the run time is ticked now: a runner's tick grid
#: (k * dt) and an application's schedule (first + k * period) differ by float rounding
TIME_TOLERANCE_S = 1e-9
#: the longest next_due an idle network gives
IDLE_RECHECK_S = 60.0


@dataclass(frozen=True)
class _Outgoing:
    pgn: int
    data: bytes
    destination: int
    priority: int


class InternalControlFunction:
    """One control function the rig plays; its :class:`~hil.isobus.port.IsobusPort`.

    Made by :meth:`IsobusNetwork.add`, not directly.
    """

    def __init__(self, network: IsobusNetwork, name: IsobusName, preferred_address: int,
                 label: str) -> None:
        self.network = network
        self.name = name
        self.label = label
        self.claimer = AddressClaimer(name, preferred_address, network._send_from_claim,
                                      lambda a: network._address_free(a, self))
        self._handlers: dict[int, list[Handler]] = defaultdict(list)
        self._queue: list[_Outgoing] = []
        self.applications: list[Application] = []

    # -- IsobusPort --------------------------------------------------------------------------

    @property
    def address(self) -> int | None:
        """The claimed address, ``None`` until the claim has settled (or after cannot-claim)."""
        return self.claimer.address

    def send(self, pgn: int, data: bytes, destination: int = GLOBAL_ADDRESS,
             priority: int = 6) -> None:
        """Queue a parameter group: a single frame up to 8 bytes, else TP (BAM when to
        everyone) or, beyond 1,785 bytes, ETP. Held until the address claim has settled.

        Raises
        ------
        FrameError
            A PDU2 group to one address, a broadcast that needs ETP, a bad priority.
        """
        encode_id(priority, pgn, 0, destination)   # checks PDU1/PDU2, ranges
        if destination == GLOBAL_ADDRESS and len(data) > 1785:
            raise FrameError(f"{self.label}: PGN 0x{pgn:05X} of {len(data)} bytes to everyone: "
                             f"a broadcast carries at most 1785 bytes (ETP has no broadcast)")
        self._queue.append(_Outgoing(pgn, bytes(data), destination, priority))
        if self.network._inside:
            self.network._flush(self)    # sent from a handler or a tick: goes out now

    def subscribe(self, pgn: int, handler: Handler) -> None:
        """Call ``handler`` with every whole ``pgn`` to this function's address or to all."""
        self._handlers[pgn].append(handler)

    def name_of(self, address: int) -> int | None:
        """The NAME that holds ``address`` on the bus (internal functions included)."""
        return self.network.table.name_of(address)

    # -- network side --------------------------------------------------------------------------

    def run(self, application: Application) -> None:
        """Tick ``application`` with the run time from now on."""
        self.applications.append(application)

    def _dispatch(self, received: Received) -> None:
        for handler in list(self._handlers.get(received.pgn, ())):
            handler(received)


class IsobusNetwork(Device):
    """The rig's ISOBUS control functions on one bus, as a rig device.

    Parameters
    ----------
    timing : TransportTiming, optional
        TP/ETP timeouts and windows.
    faults : IsobusFaults, optional
        Faults to inject into the DUT's stack (:mod:`hil.isobus.faults`).
    start_s : float
        Run time at which the functions claim their addresses.
    name : str
        The device's name in logs.
    log_frames : int
        How many of the last frames :attr:`log` keeps.

    What a peer cannot do to it: frames from the global address 0xFF (no control function
    sends from it) and, but for the address claim and the request for it, from the null
    address 0xFE are dropped and counted in :attr:`dropped`; transfers from addresses that never
    claimed are not answered (:mod:`hil.isobus.transport`). Address claims reach applications
    that subscribe to PGN 0xEE00 (after the network's table has taken them), so a Task
    Controller sees an address change hands.
    """

    def __init__(self, timing: TransportTiming | None = None,
                 faults: IsobusFaults | None = None, start_s: float = 0.0,
                 name: str = "isobus", log_frames: int = 10_000) -> None:
        self.name = name
        self.faults = faults or IsobusFaults()
        self.table = AddressTable()
        self.functions: list[InternalControlFunction] = []
        self.transport = TransportLayer(self._send_from_transport, self._deliver, timing,
                                        self.faults, claimed=self._claimed)
        #: frames dropped on arrival, by reason (``source 0xFF``, ``source 0xFE``)
        self.dropped: Counter[str] = Counter()
        self.start_s = start_s
        self._started = False
        self._now = 0.0
        self._outbox: list[can.Message] = []
        self._loopback: deque[can.Message] = deque()
        self._contenders = sorted(self.faults.contend, key=lambda c: c.at_s)
        self._app_due: dict[int, float] = {}
        #: True while the network runs (emit, on_frame): a send then goes out at once; from
        #: outside it waits for the next emit, which :meth:`next_due` makes immediate
        self._inside = False
        #: the last ``log_frames`` frames seen or sent: (time, "rx" or "tx", frame)
        self.log: deque[tuple[float, str, can.Message]] = deque(maxlen=log_frames)

    # -- building ------------------------------------------------------------------------------

    def add(self, name: IsobusName, preferred_address: int,
            label: str = "") -> InternalControlFunction:
        """Host a control function; it claims ``preferred_address`` at ``start_s``."""
        if any(f.name.value == name.value for f in self.functions):
            raise FrameError(f"two internal control functions with {name.describe()}")
        cf = InternalControlFunction(self, name, preferred_address,
                                     label or f"CF 0x{preferred_address:02X}")
        self.functions.append(cf)
        if self._started:
            cf.claimer.start(self._now)
            self._drain()
        return cf

    # -- Device --------------------------------------------------------------------------------

    def next_due(self, time_s: float) -> float:
        """The earliest time after ``time_s`` when the network has something to do."""
        if self._outbox or self._loopback or any(
                f._queue and f.address is not None for f in self.functions):
            return math.nextafter(time_s, math.inf)
        if not self._started:
            return max(self.start_s, math.nextafter(time_s, math.inf))
        due = self.transport.next_due()
        for cf in self.functions:
            due = min(due, cf.claimer.next_due())
            for i, app in enumerate(cf.applications):
                due = min(due, self._app_next_due(cf, i, app))
        if self._contenders:
            due = min(due, self._contenders[0].at_s)
        # finite even when idle: hil.rig.runner asks a device's next_due only after its emit,
        # not after on_frame, so timers a received frame starts (TP/ETP sessions) would wait
        # for the due time given before it; an idle network is polled once a minute
        due = min(due, time_s + IDLE_RECHECK_S)
        return max(due, math.nextafter(time_s, math.inf))

    def emit(self, time_s: float) -> list[can.Message]:
        """Run everything due by ``time_s`` and return the frames to put on the bus."""
        self._inside = True
        try:
            self._advance(time_s)
        finally:
            self._inside = False
        return self._take_outbox()

    def accepts(self, msg: can.Message) -> bool:
        """Every extended (29-bit) data frame: they are all ISOBUS traffic."""
        return bool(msg.is_extended_id) and not msg.is_error_frame and not msg.is_remote_frame

    def on_frame(self, msg: can.Message, time_s: float) -> list[can.Message]:
        """Take a frame from the bus; return what the network sends in reply at once."""
        self._now = max(self._now, time_s)
        self.log.append((time_s, "rx", msg))
        self._inside = True
        try:
            self._intake(msg)
            self._drain()
        finally:
            self._inside = False
        return self._take_outbox()

    # -- what the network knows -----------------------------------------------------------------

    def external(self) -> dict[int, int]:
        """Address -> NAME of the control functions on the bus that are not the rig's own."""
        ours = {f.name.value for f in self.functions}
        return {a: n for a, n in self.table.snapshot().items() if n not in ours}

    # -- internals -----------------------------------------------------------------------------

    def _app_next_due(self, cf: InternalControlFunction, i: int, app: Application) -> float:
        own = getattr(app, "next_due", None)
        if callable(own):
            return float(own(self._now))
        return self._app_due.get(id(app), self._now)

    def _advance(self, now: float) -> None:
        now = self._now = max(self._now, now)      # run time never goes back
        if not self._started and now >= self.start_s:
            self._started = True
            for cf in self.functions:
                cf.claimer.start(now)
            self._drain()
        if not self._started:
            return
        while self._contenders and self._contenders[0].at_s <= now:
            c = self._contenders.pop(0)
            frame = can.Message(arbitration_id=encode_id(6, PGN_ADDRESS_CLAIMED, c.address),
                                data=c.name.to_bytes(8, "little"), is_extended_id=True)
            self._emit_frame(frame)
            self.faults.fired.append((c, f"claim of 0x{c.address:02X} at {now:g} s"))
            self._drain()
        for cf in self.functions:
            cf.claimer.poll(now)
            self._flush(cf)
        self.transport.poll(now)
        self._drain()
        for cf in self.functions:
            for i, app in enumerate(cf.applications):
                if self._app_next_due(cf, i, app) <= now + TIME_TOLERANCE_S:
                    app.tick(now)
                    if not callable(getattr(app, "next_due", None)):
                        self._app_due[id(app)] = now + APP_TICK_S
                    self._drain()

    def _take_outbox(self) -> list[can.Message]:
        out, self._outbox = self._outbox, []
        return out

    def _address_free(self, address: int, asking: InternalControlFunction) -> bool:
        if self.table.name_of(address) not in (None, asking.name.value):
            return False
        return all(f is asking or f.claimer.current != address for f in self.functions)

    def _flush(self, cf: InternalControlFunction) -> None:
        """Send what ``cf`` queued, once its address has settled."""
        source = cf.address
        if source is None or not self._started:
            return
        queue, cf._queue = cf._queue, []
        for out in queue:
            if len(out.data) <= 8:
                frame = can.Message(arbitration_id=encode_id(out.priority, out.pgn, source,
                                                             out.destination),
                                    data=out.data, is_extended_id=True)
                self._emit_frame(frame)
            else:
                self.transport.send(out.pgn, out.data, source, out.destination, out.priority,
                                    self._now)
        self._drain()

    def _send_from_claim(self, priority: int, pgn: int, source: int, destination: int,
                         data: bytes) -> None:
        self._emit_frame(can.Message(arbitration_id=encode_id(priority, pgn, source,
                                                              destination),
                                     data=data, is_extended_id=True))

    def _send_from_transport(self, priority: int, pgn: int, source: int, destination: int,
                             data: bytes) -> None:
        self._emit_frame(can.Message(arbitration_id=encode_id(priority, pgn, source,
                                                              destination),
                                     data=data, is_extended_id=True))

    def _emit_frame(self, frame: can.Message) -> None:
        frame.timestamp = self._now
        self._outbox.append(frame)
        self.log.append((self._now, "tx", frame))
        self._loopback.append(frame)

    def _drain(self) -> None:
        """Let the internal functions hear what the others sent."""
        while self._loopback:
            self._intake(self._loopback.popleft())

    def _claimed(self, address: int) -> bool:
        return self.table.name_of(address) is not None

    def _local(self, address: int) -> list[InternalControlFunction]:
        return [f for f in self.functions if f.claimer.current == address
                and address != NULL_ADDRESS]

    def _intake(self, msg: can.Message) -> None:
        fid = decode_id(msg.arbitration_id)
        data = bytes(msg.data)
        now = self._now
        if fid.source == GLOBAL_ADDRESS or (fid.source == NULL_ADDRESS and fid.pgn not in (
                PGN_ADDRESS_CLAIMED, PGN_REQUEST)):
            # ISO 11783-5: 0xFF is no one's source; from 0xFE only cannot-claim and requests
            self.dropped[f"source 0x{fid.source:02X}"] += 1
            return
        if fid.pgn == PGN_ADDRESS_CLAIMED:
            if len(data) != 8:
                return
            value = int.from_bytes(data, "little")
            self.table.on_claim(fid.source, value)
            for cf in self.functions:
                if cf.name.value != value:
                    cf.claimer.on_claim(fid.source, value, now)
            self._deliver(Received(fid.pgn, data, fid.source, GLOBAL_ADDRESS, now,
                                   fid.priority))
            return
        if fid.pgn == PGN_REQUEST and len(data) >= 3 and \
                int.from_bytes(data[:3], "little") == PGN_ADDRESS_CLAIMED:
            # J1939-81 and ISO 11783-5: the requester answers its own global request too
            for cf in self.functions:
                cf.claimer.on_request(fid.destination, now)
        if fid.pgn in TRANSPORT_PGNS:
            if fid.destination == GLOBAL_ADDRESS or self._local(fid.destination):
                self.transport.on_frame(fid.pgn, fid.source, fid.destination, data,
                                        fid.priority, now)
            return
        self._deliver(Received(fid.pgn, data, fid.source, fid.destination, now, fid.priority))

    def _deliver(self, received: Received) -> None:
        if received.destination == GLOBAL_ADDRESS:
            targets: Iterable[InternalControlFunction] = self.functions
        else:
            targets = self._local(received.destination)
        for cf in targets:
            if cf.claimer.current == received.source:
                continue    # its own message, looped back
            cf._dispatch(received)
