"""The socket transport: one client's TCP connection on the software bus's event loop.

Non-blocking reads hand the bytes to the client's session; writes go to the kernel at once and
what it does not take waits in a user-space buffer, written out when the socket is writable.
"""

from __future__ import annotations

import contextlib
import socket
from collections import deque
from typing import Protocol

from hil.softbus.loop import READ, WRITE, EventLoop

#: Linux's TCP_QUICKACK (12): a one-shot "acknowledge now". Where the system has none the
#: option fails and is skipped (a Nagle client is then as slow as its peer's delayed ACK)
_TCP_QUICKACK = getattr(socket, "TCP_QUICKACK", 12)

class Transport(Protocol):
    """What a client's connection offers the server (the socket transport, or a test's fake)."""

    def write(self, data: bytes) -> None: ...
    def is_closing(self) -> bool: ...
    def get_write_buffer_size(self) -> int: ...


class Connections(Protocol):
    """Where the open connections are listed (the bus core), so that stopping closes them."""

    connections: set[SocketTransport]


class Receiver(Protocol):
    """What a socket transport hands its bytes to: the client's session
    (:class:`hil.softbus.session.ClientSession`), named by its role so that the session may
    know the transport without the transport knowing it."""

    @property
    def server(self) -> Connections: ...
    def data_received(self, data: bytes) -> None: ...
    def connection_lost(self, exc: Exception | None) -> None: ...


class SocketTransport:
    """A client's socket on the server's loop: non-blocking writes with a user-space buffer
    for what the kernel does not take at once (written out when the socket is writable)."""

    __slots__ = ("_buffer", "_buffered", "_closing", "client", "fd", "loop", "sock")

    def __init__(self, sock: socket.socket, loop: EventLoop, client: Receiver) -> None:
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
            # acknowledge at once: a client that keeps Nagle on holds its next small write
            # until this ACK, which Linux would otherwise delay by up to 40 ms (issue 31)
            with contextlib.suppress(OSError):
                self.sock.setsockopt(socket.IPPROTO_TCP, _TCP_QUICKACK, 1)
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

