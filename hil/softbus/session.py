"""The per-client protocol session: the socketcand state machine of one connection.

A session greets its client, follows ``open`` and ``rawmode``, parses ``send`` into frames for
the bus core, and writes the frames the core delivers to it (bounded: a client that does not
read loses its own frames, counted, and never stalls the others).
"""

from __future__ import annotations

import contextlib
import logging
import re
import socket
from dataclasses import dataclass
from typing import TYPE_CHECKING

from hil.softbus import commands
from hil.softbus.protocol import MessageSplitter, ProtocolError, parse_send
from hil.softbus.transport import Transport

if TYPE_CHECKING:
    from hil.softbus.core import BusCore

log = logging.getLogger(__name__)


@dataclass
class ClientStats:
    """One client's counters (frames it sent to the bus, frames written to it, drops)."""

    received: int = 0
    sent: int = 0
    dropped_slow: int = 0
    protocol_errors: int = 0
    control_refused: int = 0


class ClientSession:
    """One connection: the socketcand session state and its counters."""

    #: agrihil's local endpoint (:class:`LocalEndpoint`) says True: it takes frames, not lines
    local = False

    def __init__(self, server: BusCore) -> None:
        self.server = server
        self.transport: Transport | None = None
        self.splitter = MessageSplitter()
        self.channel: str | None = None
        self.raw = False
        self.held: list[bytes] | None = None  # frames waiting out the rawmode hold
        self.stats = ClientStats()
        self.name = "?"
        #: the peer's host, what warnings are keyed by (a reconnect keeps it)
        self.address = "?"
        #: the channel the core lists this client on (None: on none)
        self.attached: str | None = None
        #: a control connection (sent the bus's token): may send ``< hil … >`` commands
        self.control = False
        self._command_running = False
        self._warned_slow = False

    # connection hooks ---------------------------------------------------------------------
    # Latency choices, measured on the project's 2-vCPU VMs with python-can clients (see
    # benchmarks/bench_softbus.py for the round trip figures):
    # - a plain poller loop instead of asyncio (see hil.softbus.loop); ``write`` calls
    #   ``send()`` at once when nothing is queued.
    # - TCP_NODELAY on every client socket (without it Nagle holds back-to-back frames for up
    #   to 40 ms). TCP_QUICKACK after every read (hil.softbus.transport): the client's side
    #   of Nagle is the client's, and a DUT that keeps it on and answers SYNC with several
    #   small writes waited for a delayed ACK (~40 ms) before each write after the first,
    #   25x slower in lockstep (issue 31). It costs a setsockopt per read and a bare ACK
    #   (+2-6 µs server CPU per round trip); benchmarks/bench_nagle.py measures both clients.
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
                self.address = str(peer[0])
        self.server.stats.clients_seen += 1
        transport.write(b"< hi >")

    def data_received(self, data: bytes) -> None:
        try:
            messages = self.splitter.feed(data)
        except ProtocolError as exc:  # no end in sight: the stream cannot be resynchronised
            self._protocol_error(str(exc))
            self.drop(f"dropped: {exc}")
            return
        if len(messages) == 1:  # the latency case: one frame per read goes straight out
            self._handle(messages[0])  # (batching it would add 0.75 µs of bookkeeping)
            return
        # A burst: everything this read carried goes to each receiver in one write (one
        # syscall and one wake-up per receiver instead of one per frame). The order is the
        # same: nothing else runs on the loop in between. Measured: see BusCore.begin_batch.
        server = self.server
        outer = server.begin_batch()
        arrival = server.begin_arrival()   # on a paced bus: ready together, as read
        try:
            for body in messages:
                self._handle(body)
        finally:
            if arrival:
                server.end_arrival()
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
            self._control(rest.split())
        else:
            self._protocol_error(f"unsupported command {body!r}")

    def _control(self, words: list[str]) -> None:
        """A ``< hil … >`` command: a control connection's, or refused."""
        server = self.server
        if words[:1] == ["control"] and not self.control:
            if len(words) == 2 and server.authorize(words[1]):
                self.control = True
                self._reply(b"< hil ok control >")
            else:
                self._refuse("wrong control token")
            return
        if not self.control:
            self._refuse("control commands are for the control connection (hil bus fault, "
                         "hil bus stats), not for frame clients")
            return
        if self._command_running:
            self._reply(b"< hil error busy: the previous command is still running >")
            return
        self._command_running = True

        def reply(text: str) -> None:
            self._command_running = False
            self._reply(text.encode("ascii", "replace"))

        commands.run(server, words, reply, alive=lambda: self.transport is not None)

    def _refuse(self, why: str) -> None:
        self.stats.control_refused += 1
        self.server.stats.control_refused += 1
        self._warn("software bus: client %s sent a control command: refused (%s)",
                   self.name, why)
        self._reply(f"< hil error {why} >".encode("ascii"))

    def drop(self, why: str) -> None:
        """Disconnect this client for good (an error it cannot recover from), counted."""
        transport = self.transport
        if transport is None or transport.is_closing():
            return
        self.server.stats.dropped_clients += 1
        self._warn("software bus: client %s %s", self.name, why)
        close = getattr(transport, "close", None)
        if close is not None:
            close(None)

    def _warn(self, message: str, *args: object) -> None:
        self.server.warnings.warn(self.address, message, *args)

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
        transport = self.transport
        if transport is not None:
            self.server.flush_batch()  # frames already due to this client go out first
            if transport.get_write_buffer_size() > self.server.max_client_buffer:
                # it asks and asks but never reads the answers: nothing else bounds them
                self.drop("dropped: it does not read its replies")
                return
            transport.write(text)

    def _protocol_error(self, message: str) -> None:
        self.stats.protocol_errors += 1
        self.server.stats.protocol_errors += 1
        self._warn("software bus: client %s: %s", self.name, message[:200])

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
            self._warn("software bus: client %s is not reading; dropping its frames "
                       "(counted in stats) so the other clients are not stalled", self.name)

