"""The bus core: the state the event loop owns, and how a frame crosses the bus.

Every frame goes to every *other* client on its channel, in one global order, stamped with
the server's clock; with a bit rate it is paced and arbitrated (:mod:`hil.softbus.arbiter`),
and the fault table (:mod:`hil.softbus.faults`) may drop, corrupt, delay it or raise an error
frame. Frames that arrive together are written to each receiver in one write (batching).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import can

from hil.softbus.arbiter import Arbiter
from hil.softbus.control import tokens_equal
from hil.softbus.faults import FaultTable
from hil.softbus.loop import EventLoop, Timer
from hil.softbus.protocol import Frame, format_frame
from hil.softbus.ratelog import AddressWarnings
from hil.softbus.settings import DEFAULT_CHANNEL
from hil.softbus.timing import ERROR_FRAME_BITS

if TYPE_CHECKING:
    from hil.softbus.transport import SocketTransport

log = logging.getLogger(__name__)

_ERROR_CLASS_CONTROLLER = 0x004  # CAN_ERR_CRTL, what SocketCAN reports for bus errors
_ERROR_CLASS_BUSOFF = 0x040  # CAN_ERR_BUSOFF: the busoff rule's error frame says so
#: The most frames a delay fault holds back at once; beyond, frames it would delay are dropped
#: and counted (``delayed_dropped``).
MAX_DELAYED = 100_000


@dataclass
class BusStats:
    """The bus's counters, as ``hil bus stats`` prints them."""

    frames_in: int = 0
    frames_delivered: int = 0
    error_frames: int = 0
    dropped_slow: int = 0
    tx_overflow: int = 0
    protocol_errors: int = 0
    #: clients disconnected for an error they cannot recover from (an endless message, not
    #: reading their replies)
    dropped_clients: int = 0
    #: control commands refused because they came from a frame client (or a bad token)
    control_refused: int = 0
    #: delayed frames dropped because too many were waiting (:data:`MAX_DELAYED`)
    delayed_dropped: int = 0
    clients_seen: int = 0
    busy_s: float = 0.0


class Client(Protocol):
    """What the core asks of a client it serves: a socket's session
    (:class:`hil.softbus.session.Client`) or a local endpoint
    (:class:`hil.softbus.local.LocalEndpoint`, ``local`` True, which also has
    ``deliver_frame``). The core names this role, not the classes that play it, so that the
    sessions may know the core without the core knowing them."""

    #: for counters and warnings
    name: str
    #: the channel it asked for, and the one the core lists it on (None: none)
    channel: str | None
    attached: str | None
    #: its connection; the core sets it to None when it forgets the client
    transport: Any
    #: True: takes frames as objects (``deliver_frame``), not lines
    local: bool
    #: its counters (a dataclass: :class:`hil.softbus.session.ClientStats`)
    stats: Any

    def deliver(self, line: bytes) -> None: ...
    def deliver_many(self, lines: list[bytes]) -> None: ...


class BusCore:
    """The state the loop owns. Use :class:`SoftwareBus` or ``hil bus serve``."""

    def __init__(self, *, bitrate: int | None, log_path: Path | None, seed: int,
                 hold_s: float, max_client_buffer: int, client_sndbuf: int,
                 loop: EventLoop | None = None, control_token: str = "") -> None:
        self.bitrate = bitrate
        #: what a connection must send (``< hil control TOKEN >``) to become a control
        #: connection; empty: no connection may (see :mod:`hil.softbus.control`)
        self.control_token = control_token
        #: client warnings, once per address and then rate-limited
        self.warnings = AddressWarnings(log)
        self._delayed_pending = 0
        self.client_sndbuf = client_sndbuf
        self.hold_s = hold_s
        self.max_client_buffer = max_client_buffer
        self.channels: dict[str, list[Client]] = {}
        #: every open socket connection (raw mode or not), closed when the bus stops
        self.connections: set[SocketTransport] = set()
        self.stats = BusStats()
        self.faults = FaultTable(seed=seed)
        self.arbiter: Arbiter[tuple[Client | None, Frame, str]] | None = (
            Arbiter(bitrate) if bitrate else None)
        self.loop = loop
        self._timer: Timer | None = None
        self._mono0 = time.monotonic()
        self._wall0 = time.time()
        self._log_path = log_path
        self._logger: can.Listener | None = None
        #: lines waiting for one write per client while a burst is processed (None: no burst)
        self._batch: dict[Client, list[bytes]] | None = None
        #: while one socket read's frames are offered: the moment the server read them (their
        #: common ready time on a paced bus), and whether the wire must be pumped after them
        self._arrival: float | None = None
        self._pump_after_arrival = False

    def call_later(self, delay: float, callback: Callable[..., Any], *args: Any) -> Timer | None:
        """Run ``callback`` on the loop after ``delay`` s (not at all without a loop: tests)."""
        if self.loop is None:
            return None
        return self.loop.call_later(delay, callback, *args)

    def open_log(self) -> None:
        if self._log_path is not None:
            self._logger = can.Logger(self._log_path)

    def close_log(self) -> None:
        if self._logger is not None:
            self._logger.stop()
            self._logger = None

    def stamp(self, mono: float) -> float:
        return self._wall0 + (mono - self._mono0)

    def attach(self, client: Client) -> None:
        """Put ``client`` on its channel (taking it off the one it was on, if any: a client
        is on one channel at most, however often it asks)."""
        assert client.channel is not None
        self._unlist(client)
        self.channels.setdefault(client.channel, []).append(client)
        client.attached = client.channel

    def detach(self, client: Client) -> None:
        """Forget ``client``: off its channel, out of the open batch, no transport."""
        self._unlist(client)
        if self._batch:
            self._batch.pop(client, None)
        client.transport = None

    def _unlist(self, client: Client) -> None:
        channel = client.attached
        if channel is None:
            return
        client.attached = None
        members = self.channels.get(channel)
        if members is not None:
            with contextlib.suppress(ValueError):
                members.remove(client)
            if not members:  # no empty lists left behind by channels nobody is on
                del self.channels[channel]

    # batching -----------------------------------------------------------------------
    def begin_batch(self) -> bool:
        """Collect deliveries until :meth:`end_batch`; False if a batch is already open.

        Batching only happens when one read carries several frames, i.e. when the server has
        fallen behind a burst, or while a local driver (:class:`LocalBus`) sends a lockstep
        step's frames; a lone frame from a socket is written at once. Measured (strace -c) on
        a 20,000-frame burst between two python-can clients in separate processes: the server
        read the burst in 6 reads, then made 20,000 ``sendto`` calls, one per frame, before
        batching; with batching it made 55 reads and 55 writes (~360 frames per write).
        """
        if self._batch is not None:
            return False
        self._batch = {}
        return True

    def end_batch(self) -> None:
        self.flush_batch()
        self._batch = None

    def flush_batch(self) -> None:
        """Write out what the open batch holds (before a reply that must come after it)."""
        batch = self._batch
        if not batch:
            return
        self._batch = {}
        for client, lines in batch.items():
            if len(lines) == 1:
                client.deliver(lines[0])
            else:
                client.deliver_many(lines)

    # arrivals -----------------------------------------------------------------------
    def begin_arrival(self) -> bool:
        """Frames submitted until :meth:`end_arrival` arrived together (one socket read).

        On a paced bus they are ready at the same moment, the one the server read them at,
        and contend for the wire together: none of them takes the wire before the others
        are offered, however long the server takes over the read (a loaded host may pre-empt
        it between two frames for longer than a frame's wire time). False if one is open.
        """
        if self._arrival is not None:
            return False
        self._arrival = time.monotonic()
        return True

    def end_arrival(self) -> None:
        self._arrival = None
        if self._pump_after_arrival:
            self._pump_after_arrival = False
            self._pump()

    # frames -------------------------------------------------------------------------
    def submit(self, sender: Client | None, frame: Frame,
               channel: str | None = None) -> None:
        self.stats.frames_in += 1
        channel = channel or (sender.channel if sender else DEFAULT_CHANNEL) or DEFAULT_CHANNEL
        if self.arbiter is None:
            self._transmit(sender, frame, channel, time.monotonic())
            return
        now = self._arrival if self._arrival is not None else time.monotonic()
        accepted = self.arbiter.offer((sender, frame, channel), can_id=frame.can_id,
                                      extended=frame.extended, data=frame.data, ready=now,
                                      bits=ERROR_FRAME_BITS if frame.error else None)
        if not accepted:
            self.stats.tx_overflow += 1
            if self.stats.tx_overflow == 1:
                log.warning("software bus: transmit queue full at %d bit/s: frames are offered "
                            "faster than the wire carries them; dropping", self.bitrate)
            return
        if self._arrival is not None:
            self._pump_after_arrival = True    # once the whole read is offered
            return
        self._pump()

    def _pump(self) -> None:
        assert self.arbiter is not None
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        outer = self.begin_batch()
        try:
            for tx in self.arbiter.due(time.monotonic()):
                sender, frame, channel = tx.payload
                self._transmit(sender, frame, channel, tx.end)
        finally:
            if outer:
                self.end_batch()
        self.stats.busy_s = self.arbiter.busy_s
        nxt = self.arbiter.next_event()
        if nxt is not None:
            self._timer = self.call_later(max(0.0, nxt - time.monotonic()), self._pump)

    def _transmit(self, sender: Client | None, frame: Frame, channel: str,
                  mono: float) -> None:
        if self.faults:
            verdict = self.faults.apply(frame.can_id, frame.data)
            if verdict.error_frame:
                error_class = _ERROR_CLASS_CONTROLLER | (
                    _ERROR_CLASS_BUSOFF if verdict.bus_off else 0)
                self._broadcast(None, Frame(error_class, b"", True, error=True), channel, mono)
            if verdict.drop:
                return
            if verdict.data is not None:
                frame = Frame(frame.can_id, verdict.data, frame.extended)
            if verdict.delay_s > 0:
                if self._delayed_pending >= MAX_DELAYED:
                    self.stats.delayed_dropped += 1
                    return
                if self.call_later(verdict.delay_s, self._delayed, sender, frame, channel,
                                   mono + verdict.delay_s) is not None:
                    self._delayed_pending += 1
                return
        self._broadcast(sender, frame, channel, mono)

    def _delayed(self, sender: Client | None, frame: Frame, channel: str,
                 mono: float) -> None:
        self._delayed_pending -= 1
        outer = self.begin_batch()  # a local driver's open batch keeps the order
        try:
            self._broadcast(sender, frame, channel, mono)
        finally:
            if outer:
                self.end_batch()

    def _broadcast(self, sender: Client | None, frame: Frame, channel: str,
                   mono: float) -> None:
        stamp = self.stamp(mono)
        line: bytes | None = None
        if frame.error:
            self.stats.error_frames += 1
        else:
            self.stats.frames_delivered += 1
        batch = self._batch
        for client in self.channels.get(channel, ()):
            if client is sender:
                continue
            if client.local:
                client.deliver_frame(frame, stamp)  # type: ignore[attr-defined]
                continue
            if line is None:
                line = format_frame(frame, stamp)
            if batch is None:
                client.deliver(line)
            else:
                pending = batch.get(client)
                if pending is None:
                    batch[client] = [line]
                else:
                    pending.append(line)
        if self._logger is not None:
            self._logger.on_message_received(can.Message(
                timestamp=stamp, arbitration_id=frame.can_id, data=frame.data,
                is_extended_id=frame.extended, is_error_frame=frame.error, channel=channel))

    def stats_dict(self) -> dict[str, Any]:
        """Counters of the bus, per client, and of injected faults."""
        out = {**asdict(self.stats), "faults": dict(self.faults.injected),
               "clients": {c.name: asdict(c.stats) for cs in self.channels.values()
                           for c in cs},
               "clients_connected": len(self.connections),
               "bitrate": self.bitrate}
        if self.loop is not None and self.loop.busy_poll:
            out["busy_poll"] = self.loop.busy_poll.stats()
        return out

    # control ----------------------------------------------------------------------------
    def authorize(self, token: str) -> bool:
        """Whether ``token`` is this bus's control token (constant-time comparison)."""
        return bool(self.control_token) and tokens_equal(token, self.control_token)

    def inject_errors(self, count: int, channel: str = DEFAULT_CHANNEL) -> None:
        """Put ``count`` error frames on ``channel`` now (callers bound ``count``)."""
        outer = self.begin_batch()
        try:
            for _ in range(count):
                self.submit(None, Frame(_ERROR_CLASS_CONTROLLER, b"", True, error=True),
                            channel)
        finally:
            if outer:
                self.end_batch()
