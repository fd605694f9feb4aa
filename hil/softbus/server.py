"""The software bus server: socketcand protocol on loopback, optional bit-rate pacing and faults.

Every frame a client sends goes to every *other* client that opened the same channel, in one
global order (the server's loop is the single point of serialization), stamped with the
server's clock. With a bit rate the frames are paced by :class:`~hil.softbus.arbiter.Arbiter`:
each holds the wire for its real bit time and contending frames go out lowest id first.

A client that cannot keep up never stalls the others: its socket's outgoing buffer is bounded,
frames beyond it are dropped *for that client only*, counted, and logged.

A frame that arrives alone is written to each receiver at once; frames that arrive together
(a burst the server fell behind on) go to each receiver in one write, in the same order.

Run it embedded (:class:`SoftwareBus`, a thread of its own), as a child process
(:class:`SoftwareBusProcess`) or standalone (``hil bus serve``). A process that embeds the bus
can join it without a socket: :meth:`SoftwareBus.local_bus` is a python-can bus whose
``recv`` runs the server's loop in the caller's thread (lockstep rigs: the rig waits for the
DUT, and while it waits it *is* the bus; no thread hand-off, no GIL contention).
"""

from __future__ import annotations

import contextlib
import errno
import ipaddress
import json
import logging
import os
import re
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import can

from hil.errors import BusError, HilError
from hil.softbus.arbiter import Arbiter
from hil.softbus.faults import FaultError, FaultRule, FaultTable
from hil.softbus.loop import READ, WRITE, EventLoop, Timer, sched_yield
from hil.softbus.protocol import Frame, MessageSplitter, ProtocolError, format_frame, parse_send
from hil.softbus.timing import ERROR_FRAME_BITS

log = logging.getLogger(__name__)

DEFAULT_PORT = 29536
DEFAULT_CHANNEL = "can0"
#: After ``< rawmode >`` the reply ``< ok >`` must reach the client alone (python-can reads it
#: with one exact ``recv``), so frames for a new client are held back this long, then flushed,
#: or until the client sends its next message (it has read ``< ok >`` by then; agrihil's own
#: clients send ``< echo >`` right after ``< rawmode >`` and so are never held).
RAWMODE_HOLD_S = 0.05
#: A client whose unsent bytes exceed this is too slow: frames for it are dropped and counted.
MAX_CLIENT_BUFFER = 4 * 1024 * 1024
#: Kernel send buffer per client socket: without a bound, loopback autotuning lets a client
#: that never reads hoard megabytes before the user-space bound above ever applies.
CLIENT_SNDBUF = 256 * 1024
_ERROR_CLASS_CONTROLLER = 0x004  # CAN_ERR_CRTL, what SocketCAN reports for bus errors


class SoftwareBusError(HilError, OSError):
    """The software bus could not start or stopped abnormally."""


def check_loopback(host: str, allow_remote: bool) -> None:
    """Refuse to bind anything but loopback unless explicitly asked."""
    if allow_remote:
        return
    if host == "localhost":
        return
    try:
        if ipaddress.ip_address(host).is_loopback:
            return
    except ValueError:
        pass
    raise SoftwareBusError(
        f"refusing to bind the software bus to {host!r}: it is not a loopback address "
        "(pass allow_remote / --allow-remote to expose the bus on a network)")


@dataclass
class ClientStats:
    received: int = 0
    sent: int = 0
    dropped_slow: int = 0
    protocol_errors: int = 0


@dataclass
class BusStats:
    frames_in: int = 0
    frames_delivered: int = 0
    error_frames: int = 0
    dropped_slow: int = 0
    tx_overflow: int = 0
    protocol_errors: int = 0
    clients_seen: int = 0
    busy_s: float = 0.0


#: Busy polling of a bus process (``hil bus serve``, :class:`SoftwareBusProcess`) after traffic,
#: upper bound of the adaptive window in µs (see :class:`hil.softbus.loop.BusyPoll`); the
#: environment variable overrides it, 0 turns it off. An embedded bus (:class:`SoftwareBus` in
#: a thread) does not busy poll unless asked: a spinning thread holds its process's GIL.
DEFAULT_BUSY_POLL_US = 200.0
BUSY_POLL_ENV = "AGRIHIL_SOFTBUS_BUSY_POLL_US"
#: A local driver (:meth:`SoftwareBus.local_bus`) that has not run the loop for this long hands
#: it back to the bus thread (so that other clients are served while the rig does something
#: else, e.g. restarts its DUT).
TAKEOVER_S = 0.02


def busy_poll_from_env(default: float) -> float:
    """The busy-poll limit in µs: ``AGRIHIL_SOFTBUS_BUSY_POLL_US`` if set, else ``default``."""
    text = os.environ.get(BUSY_POLL_ENV, "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError as exc:
        raise SoftwareBusError(f"{BUSY_POLL_ENV}={text!r} is not a number of µs") from exc
    return max(0.0, value)


class Transport(Protocol):
    """What a client's connection offers the server (the socket transport, or a test's fake)."""

    def write(self, data: bytes) -> None: ...
    def is_closing(self) -> bool: ...
    def get_write_buffer_size(self) -> int: ...


class _SocketTransport:
    """A client's socket on the server's loop: non-blocking writes with a user-space buffer
    for what the kernel does not take at once (written out when the socket is writable)."""

    __slots__ = ("_buffer", "_buffered", "_closing", "client", "fd", "loop", "sock")

    def __init__(self, sock: socket.socket, loop: EventLoop, client: _Client) -> None:
        self.sock = sock
        self.fd = sock.fileno()
        self.loop = loop
        self.client = client
        self._buffer: deque[bytes] = deque()
        self._buffered = 0
        self._closing = False
        client.server.connections.add(self)
        loop.add(self.fd, READ, self._on_event)

    def is_closing(self) -> bool:
        return self._closing

    def get_write_buffer_size(self) -> int:
        return self._buffered

    def write(self, data: bytes) -> None:
        if self._closing:
            return
        if self._buffered:
            self._buffer.append(data)
            self._buffered += len(data)
            return
        try:
            sent = self.sock.send(data)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError as exc:
            # the server may be broadcasting over the channel's client list: detach later
            self._closing = True
            self.loop.call_later(0.0, self._close_now, exc)
            return
        if sent < len(data):
            rest = data[sent:]
            self._buffer.append(rest)
            self._buffered = len(rest)
            self.loop.set_events(self.fd, READ | WRITE)

    def _flush(self) -> None:
        buffer = self._buffer
        while buffer:
            data = buffer[0]
            try:
                sent = self.sock.send(data)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                self.close(exc)
                return
            self._buffered -= sent
            if sent < len(data):
                buffer[0] = data[sent:]
                return
            buffer.popleft()
        self.loop.set_events(self.fd, READ)

    def _on_event(self, events: int) -> None:
        if events & WRITE:
            self._flush()
        if events & READ and not self._closing:
            try:
                data = self.sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                self.close(exc)
                return
            if not data:
                self.close(None)
                return
            self.client.data_received(data)

    def close(self, exc: Exception | None = None) -> None:
        self._close_now(exc)

    def _close_now(self, exc: Exception | None) -> None:
        if self.fd < 0:  # closed already
            return
        self._closing = True
        self.client.server.connections.discard(self)
        self.loop.remove(self.fd)
        self.fd = -1
        with contextlib.suppress(OSError):
            self.sock.close()
        self._buffer.clear()
        self._buffered = 0
        self.client.connection_lost(exc)


class _Client:
    """One connection: the socketcand session state and its counters."""

    #: agrihil's local endpoint (:class:`_LocalEndpoint`) says True: it takes frames, not lines
    local = False

    def __init__(self, server: _Server) -> None:
        self.server = server
        self.transport: Transport | None = None
        self.splitter = MessageSplitter()
        self.channel: str | None = None
        self.raw = False
        self.held: list[bytes] | None = None  # frames waiting out the rawmode hold
        self.stats = ClientStats()
        self.name = "?"
        self._warned_slow = False

    # connection hooks ---------------------------------------------------------------------
    # Latency choices, measured on the project's 2-vCPU VMs with python-can clients (see
    # benchmarks/bench_softbus.py for the round trip figures):
    # - a plain poller loop instead of asyncio (see hil.softbus.loop); ``write`` calls
    #   ``send()`` at once when nothing is queued.
    # - TCP_NODELAY on every client socket (without it Nagle holds back-to-back frames for up
    #   to 40 ms). No TCP_QUICKACK: the ACK for a frame rides on the next frame back; forcing
    #   it costs a setsockopt per read and a bare ACK, +2-6 µs server CPU per round trip.
    # - Busy polling (bounded, adaptive, see hil.softbus.loop.BusyPoll) in a bus process.
    def connection_made(self, transport: Transport, sock: socket.socket | None = None) -> None:
        self.transport = transport
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.server.client_sndbuf)
            with contextlib.suppress(OSError):
                peer = sock.getpeername()
                self.name = f"{peer[0]}:{peer[1]}"
        self.server.stats.clients_seen += 1
        transport.write(b"< hi >")

    def data_received(self, data: bytes) -> None:
        try:
            messages = self.splitter.feed(data)
        except ProtocolError as exc:
            self._protocol_error(str(exc))
            return
        if len(messages) == 1:  # the latency case: one frame per read goes straight out
            self._handle(messages[0])  # (batching it would add 0.75 µs of bookkeeping)
            return
        # A burst: everything this read carried goes to each receiver in one write (one
        # syscall and one wake-up per receiver instead of one per frame). The order is the
        # same: nothing else runs on the loop in between. Measured: see _Server.begin_batch.
        server = self.server
        outer = server.begin_batch()
        try:
            for body in messages:
                self._handle(body)
        finally:
            if outer:
                server.end_batch()

    def connection_lost(self, exc: Exception | None) -> None:
        self.server.detach(self)

    # protocol ---------------------------------------------------------------------------
    def _handle(self, body: str) -> None:
        if self.raw:
            if self.held is not None:  # it has read '< ok >': nothing to wait for any more
                self._release()
            if body.startswith("send "):  # nearly every message: checked first
                self._send(body[5:])
                return
        word, _, rest = body.partition(" ")
        if self.raw and word == "send":
            self._send(rest)
        elif word == "open":
            channel = rest.strip()
            if not channel or not re.fullmatch(r"[A-Za-z0-9_.-]+", channel):
                self._reply(b"< error bad channel name >")
                return
            self.channel = channel
            self._reply(b"< ok >")
        elif word == "rawmode":
            if self.channel is None:
                self._reply(b"< error open a channel first >")
                return
            self.raw = True
            self.held = []
            self.server.attach(self)
            self._reply(b"< ok >")
            self.server.call_later(self.server.hold_s, self._release)
        elif word == "echo":
            self._reply(b"< echo >")
        elif word == "hil":
            self._reply(self.server.command(rest.split()).encode("ascii"))
        else:
            self._protocol_error(f"unsupported command {body!r}")

    def _send(self, args: str) -> None:
        try:
            frame = parse_send(args)
        except ProtocolError as exc:
            self._protocol_error(str(exc))
            return
        self.stats.received += 1
        self.server.submit(self, frame)

    def _release(self) -> None:
        held, self.held = self.held, None
        if held and self.transport is not None:
            self.transport.write(b"".join(held))

    def _reply(self, text: bytes) -> None:
        if self.transport is not None:
            self.server.flush_batch()  # frames already due to this client go out first
            self.transport.write(text)

    def _protocol_error(self, message: str) -> None:
        self.stats.protocol_errors += 1
        self.server.stats.protocol_errors += 1
        if self.stats.protocol_errors <= 5:
            log.warning("software bus: client %s: %s", self.name, message)

    def deliver(self, line: bytes) -> None:
        """Send one frame's line (or count it dropped if this client is not reading)."""
        if self.held is not None:
            self._hold([line])
            return
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        if transport.get_write_buffer_size() > self.server.max_client_buffer:
            self._count_slow()
            return
        transport.write(line)
        self.stats.sent += 1

    def deliver_many(self, lines: list[bytes]) -> None:
        """Send several frames' lines in one write; the buffer bound applies per write."""
        if self.held is not None:
            self._hold(lines)
            return
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        if transport.get_write_buffer_size() > self.server.max_client_buffer:
            self._count_slow(len(lines))
            return
        transport.write(b"".join(lines))
        self.stats.sent += len(lines)

    def _hold(self, lines: list[bytes]) -> None:
        assert self.held is not None
        room = max(0, 100_000 - len(self.held))
        self.held.extend(lines[:room])
        if len(lines) > room:
            self._count_slow(len(lines) - room)

    def _count_slow(self, n: int = 1) -> None:
        self.stats.dropped_slow += n
        self.server.stats.dropped_slow += n
        if not self._warned_slow:
            self._warned_slow = True
            log.warning("software bus: client %s is not reading; dropping its frames "
                        "(counted in stats) so the other clients are not stalled", self.name)


class _LocalEndpoint(_Client):
    """A client in the server's own process (:class:`LocalBus`): frames go in and out as
    objects, never as text on a socket. Its receive queue is bounded like a socket's buffer:
    beyond ``max_queue`` frames, frames for it are dropped and counted."""

    local = True

    def __init__(self, server: _Server, channel: str, max_queue: int) -> None:
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


class _Server:
    """The state the loop owns. Use :class:`SoftwareBus` or ``hil bus serve``."""

    def __init__(self, *, bitrate: int | None, log_path: Path | None, seed: int,
                 hold_s: float, max_client_buffer: int, client_sndbuf: int,
                 loop: EventLoop | None = None) -> None:
        self.bitrate = bitrate
        self.client_sndbuf = client_sndbuf
        self.hold_s = hold_s
        self.max_client_buffer = max_client_buffer
        self.channels: dict[str, list[_Client]] = {}
        #: every open socket connection (raw mode or not), closed when the bus stops
        self.connections: set[_SocketTransport] = set()
        self.stats = BusStats()
        self.faults = FaultTable(seed=seed)
        self.arbiter: Arbiter[tuple[_Client | None, Frame, str]] | None = (
            Arbiter(bitrate) if bitrate else None)
        self.loop = loop
        self._timer: Timer | None = None
        self._mono0 = time.monotonic()
        self._wall0 = time.time()
        self._log_path = log_path
        self._logger: can.Listener | None = None
        #: lines waiting for one write per client while a burst is processed (None: no burst)
        self._batch: dict[_Client, list[bytes]] | None = None

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

    def attach(self, client: _Client) -> None:
        assert client.channel is not None
        self.channels.setdefault(client.channel, []).append(client)

    def detach(self, client: _Client) -> None:
        if client.channel and client in self.channels.get(client.channel, []):
            self.channels[client.channel].remove(client)
        if self._batch:
            self._batch.pop(client, None)
        client.transport = None

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

    # frames -------------------------------------------------------------------------
    def submit(self, sender: _Client | None, frame: Frame, channel: str | None = None) -> None:
        self.stats.frames_in += 1
        channel = channel or (sender.channel if sender else DEFAULT_CHANNEL) or DEFAULT_CHANNEL
        now = time.monotonic()
        if self.arbiter is None:
            self._transmit(sender, frame, channel, now)
            return
        accepted = self.arbiter.offer((sender, frame, channel), can_id=frame.can_id,
                                      extended=frame.extended, data=frame.data, ready=now,
                                      bits=ERROR_FRAME_BITS if frame.error else None)
        if not accepted:
            self.stats.tx_overflow += 1
            if self.stats.tx_overflow == 1:
                log.warning("software bus: transmit queue full at %d bit/s: frames are offered "
                            "faster than the wire carries them; dropping", self.bitrate)
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

    def _transmit(self, sender: _Client | None, frame: Frame, channel: str, mono: float) -> None:
        if self.faults:
            verdict = self.faults.apply(frame.can_id, frame.data)
            if verdict.error_frame:
                self._broadcast(None, Frame(_ERROR_CLASS_CONTROLLER, b"", True, error=True),
                                channel, mono)
            if verdict.drop:
                return
            if verdict.data is not None:
                frame = Frame(frame.can_id, verdict.data, frame.extended)
            if verdict.delay_s > 0:
                self.call_later(verdict.delay_s, self._delayed, sender, frame, channel,
                                mono + verdict.delay_s)
                return
        self._broadcast(sender, frame, channel, mono)

    def _delayed(self, sender: _Client | None, frame: Frame, channel: str, mono: float) -> None:
        outer = self.begin_batch()  # a local driver's open batch keeps the order
        try:
            self._broadcast(sender, frame, channel, mono)
        finally:
            if outer:
                self.end_batch()

    def _broadcast(self, sender: _Client | None, frame: Frame, channel: str,
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
               "bitrate": self.bitrate}
        if self.loop is not None and self.loop.busy_poll:
            out["busy_poll"] = self.loop.busy_poll.stats()
        return out

    # control commands ----------------------------------------------------------------
    def command(self, words: list[str]) -> str:
        try:
            return self._command(words)
        except (FaultError, ValueError, IndexError) as exc:
            return f"< hil error {str(exc).replace('<', '(').replace('>', ')')} >"

    def _command(self, words: list[str]) -> str:
        if words[:2] == ["fault", "add"]:
            rule_id = self.faults.add(FaultRule.parse(words[2:]))
            return f"< hil ok {rule_id} >"
        if words[:2] == ["fault", "clear"]:
            self.faults.clear(int(words[2]) if len(words) > 2 else None)
            return "< hil ok >"
        if words[:2] == ["fault", "list"]:
            rules = {rid: " ".join(r.to_words()) for rid, r in self.faults.rules().items()}
            return f"< hil faults {json.dumps(rules)} >"
        if words[:1] == ["errors"]:
            count = int(words[1]) if len(words) > 1 else 1
            channel = words[2] if len(words) > 2 else DEFAULT_CHANNEL
            for _ in range(count):
                self.submit(None, Frame(_ERROR_CLASS_CONTROLLER, b"", True, error=True),
                            channel)
            return "< hil ok >"
        if words[:1] == ["stats"]:
            return f"< hil stats {json.dumps(self.stats_dict())} >"
        raise ValueError(f"unknown hil command {' '.join(words)!r}; known: fault add|clear|list, "
                         "errors N, stats")


class SoftwareBus:
    """A software bus server, embedded in a thread of its own (:meth:`start`) or run in the
    calling thread (:meth:`serve_forever`, what ``hil bus serve`` does).

    The thread shares the GIL with the process that embeds it: while another thread of that
    process computes, every frame waits for the GIL (switch interval 5 ms). Measured round
    trip between python-can clients with a busy Python thread in the embedding process: p50
    15.6 ms embedded against 10.6 ms with :class:`SoftwareBusProcess` (~0.2 ms for either when
    the process is idle). For latency, run the bus as a process; for a lockstep rig in the
    embedding process, join with :meth:`local_bus` (the rig's own thread then runs the bus
    while it waits).

    ``busy_poll_us``: upper bound of the adaptive busy-poll window after traffic (0: off; None:
    ``AGRIHIL_SOFTBUS_BUSY_POLL_US`` or 0, since a spinning thread would hold the embedding
    process's GIL; ``hil bus serve`` defaults to :data:`DEFAULT_BUSY_POLL_US`).

    >>> with SoftwareBus(port=0) as bus:          # doctest: +SKIP
    ...     spec = bus.spec()                      # 'socketcand:127.0.0.1:41234/can0'
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *,
                 bitrate: int | None = None, log_path: str | Path | None = None,
                 seed: int = 0, allow_remote: bool = False, hold_s: float = RAWMODE_HOLD_S,
                 max_client_buffer: int = MAX_CLIENT_BUFFER,
                 client_sndbuf: int = CLIENT_SNDBUF, busy_poll_us: float | None = None,
                 takeover_s: float = TAKEOVER_S) -> None:
        check_loopback(host, allow_remote)
        if bitrate is not None and bitrate <= 0:
            raise SoftwareBusError(f"bitrate must be positive, got {bitrate}")
        self.host = host
        self.port = port
        self._busy_poll_arg = busy_poll_us
        self.busy_poll_us = 0.0  # resolved when it starts: see _open
        self.takeover_s = takeover_s
        self._state = _Server(bitrate=bitrate, log_path=Path(log_path) if log_path else None,
                              seed=seed, hold_s=hold_s, max_client_buffer=max_client_buffer,
                              client_sndbuf=client_sndbuf)
        self._loop: EventLoop | None = None
        self._listener: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stopping = False
        self._failure: BaseException | None = None
        #: who runs the loop: the bus thread, or a local driver while it waits (see local_bus)
        self._lock = threading.Lock()
        self._waiting = 0  # threads waiting for the loop: the bus thread lets them have it
        self._waiting_lock = threading.Lock()
        self._drivers: list[LocalBus] = []
        self._locals = 0
        self._unpark = threading.Event()

    # lifecycle -------------------------------------------------------------------------
    def _open(self, *, own_thread: bool) -> None:
        """Bind and listen, open the log: after this, clients can connect."""
        if self._loop is not None:
            raise SoftwareBusError("software bus already started")
        arg = self._busy_poll_arg
        self.busy_poll_us = (max(0.0, arg) if arg is not None else
                             busy_poll_from_env(0.0 if own_thread else DEFAULT_BUSY_POLL_US))
        loop = EventLoop(busy_poll_us=self.busy_poll_us)
        try:
            family = socket.getaddrinfo(self.host, self.port, type=socket.SOCK_STREAM)[0][0]
            listener = socket.create_server((self.host, self.port), family=family, backlog=128)
        except OSError as exc:
            loop.close()
            raise SoftwareBusError(f"software bus failed to start on {self.host}:{self.port}: "
                                   f"{exc}") from exc
        listener.setblocking(False)
        self.port = listener.getsockname()[1]
        self._listener = listener
        self._loop = loop
        self._state.loop = loop
        loop.add(listener.fileno(), READ, self._accept)
        self._state.open_log()

    def _close(self) -> None:
        loop, self._loop = self._loop, None
        if self._listener is not None:
            if loop is not None:
                loop.remove(self._listener.fileno())
            self._listener.close()
            self._listener = None
        for transport in list(self._state.connections):
            transport.close()
        self._state.close_log()
        if loop is not None:
            loop.close()

    def _accept(self, _events: int) -> None:
        assert self._listener is not None and self._loop is not None
        for _ in range(64):
            try:
                sock, _addr = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno in (errno.EMFILE, errno.ENFILE):
                    log.warning("software bus: cannot accept a client: %s", exc)
                return
            sock.setblocking(False)
            client = _Client(self._state)
            transport = _SocketTransport(sock, self._loop, client)
            client.connection_made(transport, sock)

    def serve_forever(self, *, on_listening: Callable[[SoftwareBus], Any] | None = None) -> None:
        """Serve in the calling thread until :meth:`request_stop` (busy polling on by default:
        nothing else of this process competes with the loop)."""
        self._open(own_thread=False)
        try:
            self._ready.set()
            if on_listening is not None:
                on_listening(self)
            self._run()
        finally:
            with self._lock:
                self._close()

    async def serve(self, *, on_listening: Any = None) -> None:
        """Serve until :meth:`request_stop` (the coroutine ``hil bus serve`` runs): the loop
        runs in a thread of its own so that the caller's event loop stays responsive, and
        however this coroutine ends (stop, cancellation, Ctrl-C) the bus stops with it."""
        import asyncio

        aloop = asyncio.get_running_loop()
        done: asyncio.Future[None] = aloop.create_future()

        def settle(exc: BaseException | None) -> None:
            if not done.done():
                if exc is None:
                    done.set_result(None)
                else:
                    done.set_exception(exc)

        def run() -> None:
            failure: BaseException | None = None
            try:
                self.serve_forever(on_listening=on_listening)
            except BaseException as exc:  # handed to the awaiting coroutine
                failure = exc
            with contextlib.suppress(RuntimeError):  # the event loop is closed already
                aloop.call_soon_threadsafe(settle, failure)

        thread = threading.Thread(target=run, name="hil-softbus", daemon=True)
        thread.start()
        try:
            await done
        finally:
            self.request_stop()
            thread.join(5.0)

    def _run(self) -> None:
        """The bus thread's loop: serve, except while a local driver runs the loop itself."""
        loop = self._loop
        assert loop is not None
        lock = self._lock
        while not self._stopping:
            if self._waiting:  # another thread wants the loop: let it have it first
                self._unpark.wait(0.005)
                self._unpark.clear()
                continue
            if self._driver_active():
                # a local driver serves while it waits; stay out of its way, but answer
                # cross-thread calls (stats, faults) and take over when it goes quiet
                if loop.has_threadsafe_calls():
                    with lock:
                        loop.run_once(0.0, spin=False)
                    continue
                self._unpark.wait(self.takeover_s)
                self._unpark.clear()
                continue
            with lock:
                if self._driver_active() or self._waiting:
                    continue
                if self._state._batch is not None:  # a quiet driver's step: write it out
                    self._state.end_batch()
                timeout = self.takeover_s if self._drivers else None
                loop.run_once(timeout)

    def _driver_active(self) -> bool:
        if not self._drivers:
            return False
        now = time.monotonic()
        return any(d.driving or now - d.last_drive < self.takeover_s for d in self._drivers)

    def request_stop(self) -> None:
        self._stopping = True
        self._unpark.set()
        if self._loop is not None:
            self._loop.wake()

    def start(self, timeout: float = 5.0) -> SoftwareBus:
        """Start serving in a background thread; returns once the port is listening."""
        if self._thread is not None:
            raise SoftwareBusError("software bus already started")
        self._open(own_thread=True)

        def run() -> None:
            try:
                self._ready.set()
                self._run()
            except BaseException as exc:  # reported by stop(), never silent
                self._failure = exc
                log.error("software bus thread died: %r", exc)
            finally:
                with self._lock:
                    self._close()

        self._thread = threading.Thread(target=run, name="hil-softbus", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise SoftwareBusError(f"software bus did not start within {timeout} s")
        return self

    def stop(self, timeout: float = 5.0) -> None:
        for driver in list(self._drivers):
            driver.shutdown()
        if self._thread is None:
            if self._loop is not None and not self._stopping:  # opened, driven only
                with self._lock:
                    self._close()
            return
        self.request_stop()
        self._thread.join(timeout)
        alive = self._thread.is_alive()
        self._thread = None
        if alive:
            raise SoftwareBusError(f"software bus thread did not stop within {timeout} s")
        if self._failure is not None:
            raise SoftwareBusError(f"software bus thread died: {self._failure}") \
                from self._failure

    def __enter__(self) -> SoftwareBus:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # use --------------------------------------------------------------------------------
    def spec(self, channel: str = DEFAULT_CHANNEL) -> str:
        """The bus spec clients pass to :func:`hil.bus.open_bus`."""
        return f"socketcand:{self.host}:{self.port}/{channel}"

    def _acquire(self) -> _Server:
        """Take the loop (wake the bus thread out of its wait if it has it); release with
        ``self._lock.release()``. (Not a context manager: this is on every local send, and a
        generator-based one costs ~3 µs.)"""
        lock = self._lock
        if not lock.acquire(blocking=False):
            with self._waiting_lock:
                self._waiting += 1
            try:
                if self._loop is not None:
                    self._loop.wake()
                lock.acquire()
            finally:
                with self._waiting_lock:
                    self._waiting -= 1
                self._unpark.set()
        return self._state

    def _hand_over(self) -> None:
        """Let the threads waiting for the loop have it, then take it back (called by the
        thread that holds it)."""
        self._lock.release()
        deadline = time.monotonic() + 1.0
        while self._waiting and time.monotonic() < deadline:
            time.sleep(0.0002)
        self._acquire()

    @contextlib.contextmanager
    def _owning(self) -> Iterator[_Server]:
        """Hold the loop for a block."""
        state = self._acquire()
        try:
            yield state
        finally:
            self._lock.release()

    def call(self, func: Any, *args: Any, timeout: float = 5.0) -> Any:
        """Run ``func(state, *args)`` with the loop held and return its result."""
        if self._loop is None:
            raise SoftwareBusError("software bus is not running")
        with self._owning() as state:
            return func(state, *args)

    def add_fault(self, rule: FaultRule) -> int:
        return int(self.call(lambda s: s.faults.add(rule)))

    def clear_faults(self, rule_id: int | None = None) -> None:
        self.call(lambda s: s.faults.clear(rule_id))

    def inject_error_frames(self, count: int = 1, channel: str = DEFAULT_CHANNEL) -> None:
        self.call(lambda s: s.command(["errors", str(count), channel]))

    def stats(self) -> dict[str, Any]:
        return dict(self.call(lambda s: s.stats_dict()))

    def local_bus(self, channel: str = DEFAULT_CHANNEL, *, busy_poll_us: float = 0.0,
                  max_queue: int = 100_000) -> LocalBus:
        """A python-can bus on this software bus without a socket, for a lockstep loop in
        this process. See :class:`LocalBus`."""
        if self._loop is None:
            raise SoftwareBusError("software bus is not running: start() it first")
        return LocalBus(self, channel, busy_poll_us=busy_poll_us, max_queue=max_queue)


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

    def __init__(self, softbus: SoftwareBus, channel: str = DEFAULT_CHANNEL, *,
                 busy_poll_us: float = 0.0, max_queue: int = 100_000, **kwargs: Any) -> None:
        self._softbus = softbus
        self.channel_info = f"local client of the software bus on {softbus.host}:{softbus.port}"
        self.driving = False
        self.last_drive = float("-inf")  # the bus thread serves until this bus is used
        self.busy_poll_s = max(0.0, busy_poll_us) / 1e6
        self._channel = channel
        with softbus._owning() as state:
            self._endpoint = _LocalEndpoint(state, channel, max_queue)
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


class SoftwareBusProcess:
    """The software bus in a child process (``python -m hil bus serve``).

    ``busy_poll_us`` goes to the child as ``AGRIHIL_SOFTBUS_BUSY_POLL_US`` (None: the child's
    default, :data:`DEFAULT_BUSY_POLL_US`, unless the variable is set in this process).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, bitrate: int | None = None,
                 log_path: str | Path | None = None, seed: int = 0,
                 busy_poll_us: float | None = None) -> None:
        check_loopback(host, False)
        self.host = host
        self.port = port
        self._args = [sys.executable, "-m", "hil", "bus", "serve", "--host", host,
                      "--port", str(port), "--seed", str(seed)]
        if bitrate:
            self._args += ["--bitrate", str(bitrate)]
        if log_path:
            self._args += ["--log", str(log_path)]
        self._env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        if busy_poll_us is not None:
            self._env[BUSY_POLL_ENV] = str(max(0.0, busy_poll_us))
        self.proc: subprocess.Popen[str] | None = None

    def start(self, timeout: float = 10.0) -> SoftwareBusProcess:
        self.proc = subprocess.Popen(self._args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env=self._env)
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout
        import selectors
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        while time.monotonic() < deadline:
            if sel.select(timeout=max(0.0, deadline - time.monotonic())):
                line = self.proc.stdout.readline()
                if not line:
                    break
                match = re.search(r"listening on (\S+):(\d+)", line)
                if match:
                    self.port = int(match.group(2))
                    sel.close()
                    return self
        sel.close()
        self._end(timeout=5.0)
        detail = self._stderr()
        self.stop()
        raise SoftwareBusError(f"software bus process did not start: {detail}")

    def _stderr(self) -> str:
        if self.proc is None or self.proc.stderr is None:
            return ""
        with contextlib.suppress(Exception):
            return self.proc.stderr.read()[-2000:]
        return ""

    def spec(self, channel: str = DEFAULT_CHANNEL) -> str:
        return f"socketcand:{self.host}:{self.port}/{channel}"

    def stats(self) -> dict[str, Any]:
        """The bus's counters (``< hil stats >`` over the control protocol)."""
        from hil.cli.bus import control

        reply = control(self.host, self.port, ["stats"])
        return dict(json.loads(reply[len("< hil stats "):-2]))

    def _end(self, timeout: float) -> None:
        """Terminate the child (kill it if it does not go), leaving its pipes readable."""
        if self.proc is None or self.proc.poll() is not None:
            return
        self.proc.terminate()
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout)

    def stop(self, timeout: float = 5.0) -> None:
        if self.proc is None:
            return
        try:
            self._end(timeout)
        finally:
            for pipe in (self.proc.stdout, self.proc.stderr):
                if pipe is not None and not pipe.closed:
                    pipe.close()

    def __enter__(self) -> SoftwareBusProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def raise_if_unreachable(host: str, port: int, timeout: float = 2.0) -> None:
    """Fail fast with a clear message when no software bus listens at host:port."""
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.settimeout(timeout)
            greeting = sock.recv(16)
    except OSError as exc:
        raise BusError(f"no software bus (socketcand server) at {host}:{port}: {exc}; start one "
                       f"with `hil bus serve --port {port}`") from exc
    if not greeting.startswith(b"< hi >"):
        raise BusError(f"{host}:{port} answered {greeting!r}, not a socketcand greeting")
