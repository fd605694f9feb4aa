"""agrihil's own socketcand client: the same frames as python-can's, less work per frame.

It also offers write-behind: one socket write per lockstep step instead of one per frame.

python-can's ``socketcand`` interface stays the default for ``socketcand:`` specs; this client
is chosen with a spec option (``socketcand:HOST:PORT/CH,client=agrihil`` or ``,batch=true``).
Why it replaces the library's client where it is chosen (measured in the fertilizer field run,
firmware over the embedded software bus, 5,740 rig frames and 630 SYNC round trips):

- python-can's ``send`` formats with a generator and a ``setsockopt(TCP_QUICKACK)`` after every
  write, and its ``recv`` formats a debug f-string and concatenates strings per read;
- every ``send`` is one ``sendall``: in a process that embeds the software bus as a thread,
  each write hands the GIL to the bus thread and waits to get it back (~25 µs per frame).

With ``batch=true`` frames are kept until the next :meth:`recv` (or :meth:`flush`, or
``max_batch`` frames) and go out in one write, in order. That is only right where the sender
waits for the bus after sending, as the lockstep loop does (SYNC, then wait for the DUT): in a
real-time loop frames would leave up to one tick late. ``busy_poll_us`` spins on the socket
for that long in :meth:`recv` before blocking (costs CPU while waiting; 0 = off).

The messages it produces are those python-can's client produces: the same ids, flags, data
(``bytearray``), timestamps, ``is_rx``, ``channel``; error frames as python-can reads them
(``is_error_frame``, extended, one zero data byte).
"""

from __future__ import annotations

import binascii
import select
import socket
import time
from collections import deque
from typing import Any

import can

#: "< send " + id text, per identifier, built on first use (a rig uses a few dozen ids)
_SEND_HEAD_STD = [f"< send {i:03X} ".encode("ascii") for i in range(0x800)]
#: " XX" per byte value, the spelling python-can's client uses is "%x"; ours is "%02X": the
#: server accepts either (hil.softbus.protocol.parse_send)
_BYTE_TEXT = [f" {b:02X}".encode("ascii") for b in range(256)]
_LEN_TEXT = [f"{n:X}".encode("ascii") for n in range(16)]
#: bytes of a partial message this client keeps before it declares the stream garbage
_MAX_PARTIAL = 4096


class SocketcandError(can.CanError):
    """The socketcand server refused the handshake or the connection failed."""


def format_send(msg: can.Message) -> bytes:
    r"""``< send ID LEN B0 … >`` for a message, as the socketcand protocol wants it.

    >>> format_send(can.Message(arbitration_id=0x181, data=b"\x01\xab", is_extended_id=False))
    b'< send 181 2 01 AB >'
    """
    can_id = msg.arbitration_id
    data = msg.data
    n = msg.dlc
    if msg.is_extended_id:
        head = f"< send {can_id & 0x1FFFFFFF:08X} ".encode("ascii")
    else:
        head = _SEND_HEAD_STD[can_id & 0x7FF]
    byte_text = _BYTE_TEXT
    return b"".join([head, _LEN_TEXT[n] if n < 16 else b"%X" % n,
                     *[byte_text[b] for b in data[:n]], b" >"])


def _receive_failed(exc: OSError) -> can.CanOperationError:
    """The error for a failed read.

    A server that closes while bytes of ours are still unread in its socket (it stopped before
    reading our last message) resets the connection instead of ending it: that is still the
    server closing it, and is said so.
    """
    if isinstance(exc, ConnectionResetError):
        return can.CanOperationError(f"socketcand: the server closed the connection ({exc})")
    return can.CanOperationError(f"socketcand: receive failed: {exc}")


class SocketcandBus(can.BusABC):
    """A python-can bus on a socketcand server (agrihil's software bus, or socketcand itself).

    Parameters
    ----------
    channel : str, optional
        The server's channel to open (``can0``).
    host : str, optional
        The server's address.
    port : int, optional
        The server's port.
    batch : bool, optional
        Keep sent frames until the next :meth:`recv` or :meth:`flush` (write-behind).
    max_batch : int, optional
        With ``batch``, write once this many frames are waiting.
    busy_poll_us : float, optional
        In :meth:`recv`, poll the socket without blocking for this long first (0: off).
    connect_timeout : float, optional
        Seconds for the connection and the handshake.
    can_filters : optional
        python-can's receive filters.
    **kwargs
        Passed to ``can.BusABC``.

    Raises
    ------
    SocketcandError
        The server refused the handshake or closed the connection during it.
    OSError
        The connection could not be made.
    """

    def __init__(self, channel: str = "can0", host: str = "127.0.0.1", port: int = 29536, *,
                 batch: bool = False, max_batch: int = 256, busy_poll_us: float = 0.0,
                 connect_timeout: float = 10.0, can_filters: Any = None,
                 **kwargs: Any) -> None:
        self.channel = channel
        self.channel_info = f"socketcand on {channel}@{host}:{port} (agrihil client)"
        self.batch = bool(batch)
        self.max_batch = max(1, int(max_batch))
        self.busy_poll_s = max(0.0, float(busy_poll_us)) / 1e6
        self._pending: list[bytes] = []
        self._rx: deque[can.Message] = deque()
        self._partial = b""
        self._sock = socket.create_connection((host, port), timeout=connect_timeout)
        try:
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._handshake(channel)
        except BaseException:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self._poller = select.poll()
        self._poller.register(self._sock.fileno(), select.POLLIN)
        super().__init__(channel=channel, can_filters=can_filters, **kwargs)

    # handshake ---------------------------------------------------------------------------
    def _expect(self, want: bytes, step: str) -> None:
        """Read messages until ``want``; frames that arrive before or after it are kept.

        Anything else fails the handshake.
        """
        chunk = b""
        while True:
            bodies = self._split(chunk)
            for i, body in enumerate(bodies):
                body = body.strip()
                if body == want:
                    for later in bodies[i + 1:]:
                        self._queue(later)
                    return
                if body.startswith(b"frame ") or body.startswith(b"error "):
                    self._queue(body)
                    continue
                raise SocketcandError(f"socketcand {step}: expected '< {want.decode()} >', "
                                      f"got '< {body.decode('ascii', 'replace')} >'")
            chunk = self._sock.recv(65536)
            if not chunk:
                raise SocketcandError(f"socketcand {step}: the server closed the connection")

    def _handshake(self, channel: str) -> None:
        self._expect(b"hi", "greeting")
        self._sock.sendall(f"< open {channel} >".encode("ascii"))
        self._expect(b"ok", f"open {channel}")
        self._sock.sendall(b"< rawmode >")
        self._expect(b"ok", "rawmode")
        # Any message after rawmode tells agrihil's software bus that '< ok >' has been read:
        # it then stops holding frames back for this client (it holds them 50 ms for clients
        # that read '< ok >' with one exact recv, as python-can's does). Its answer, and a
        # real socketcand's, is '< echo >', which _queue skips like any non-frame.
        self._sock.sendall(b"< echo >")

    # sending -----------------------------------------------------------------------------
    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send ``msg``, or keep it for the next write with ``batch`` (``timeout`` is unused).

        Raises
        ------
        can.CanOperationError
            The write failed (or found no room in 5 s).
        """
        line = format_send(msg)
        if self.batch:
            pending = self._pending
            pending.append(line)
            if len(pending) >= self.max_batch:
                self.flush()
            return
        self._write(line)

    def flush(self) -> None:
        """Write every frame kept by ``batch`` in one write."""
        if self._pending:
            data = b"".join(self._pending)
            self._pending.clear()
            self._write(data)

    def _write(self, data: bytes) -> None:
        sock = self._sock
        try:
            sent = sock.send(data)
            if sent == len(data):
                return
            # the kernel buffer is full (the server is not reading): wait for room
            view = memoryview(data)[sent:]
            sock.settimeout(5.0)
            try:
                sock.sendall(view)
            finally:
                sock.setblocking(False)
        except BlockingIOError:
            sock.settimeout(5.0)
            try:
                sock.sendall(data)
            except OSError as exc:
                raise can.CanOperationError(f"socketcand: send failed: {exc}") from exc
            finally:
                sock.setblocking(False)
        except OSError as exc:
            raise can.CanOperationError(f"socketcand: send failed: {exc}") from exc

    # receiving ---------------------------------------------------------------------------
    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self._pending:
            self.flush()
        rx = self._rx
        if rx:
            return rx.popleft(), False
        sock = self._sock
        try:
            chunk = sock.recv(65536)  # what is there already costs no wait
        except BlockingIOError:
            chunk = None
        except OSError as exc:
            raise _receive_failed(exc) from exc
        if chunk is None and timeout != 0.0:
            chunk = self._wait(timeout)
        if chunk is None:
            return None, False
        if not chunk:
            raise can.CanOperationError("socketcand: the server closed the connection")
        self._parse(chunk)
        if rx:
            return rx.popleft(), False
        return None, False

    def _wait(self, timeout: float | None) -> bytes | None:
        sock = self._sock
        if self.busy_poll_s > 0.0:
            clock = time.perf_counter
            end = clock() + min(self.busy_poll_s, timeout if timeout is not None else 1e9)
            while clock() < end:
                try:
                    return sock.recv(65536)
                except BlockingIOError:
                    continue
                except OSError as exc:
                    raise _receive_failed(exc) from exc
        ms = -1 if timeout is None else max(0, int(timeout * 1000 + 0.999))
        if not self._poller.poll(ms):
            return None
        try:
            return sock.recv(65536)
        except BlockingIOError:
            return None
        except OSError as exc:
            raise _receive_failed(exc) from exc

    def _split(self, chunk: bytes) -> list[bytes]:
        """The bodies of the complete ``< ... >`` messages in what was kept plus ``chunk``.

        The partial rest is kept for the next read.
        """
        buf = self._partial + chunk if self._partial else chunk
        parts = buf.split(b">")
        tail = parts.pop()
        if len(tail) > _MAX_PARTIAL:
            tail = b""  # no '>' in sight: not socketcand, drop it (python-can drops too)
        self._partial = tail
        return [part[start + 1:] for part in parts if (start := part.find(b"<")) >= 0]

    def _parse(self, chunk: bytes) -> None:
        queue = self._queue
        for body in self._split(chunk):
            queue(body)

    def _queue(self, body: bytes) -> None:
        fields = body.split()
        if len(fields) < 3:
            return
        kind = fields[0]
        try:
            if kind == b"frame":
                id_text = fields[1]
                data = bytearray(binascii.unhexlify(b"".join(fields[3:])))
                self._rx.append(can.Message(
                    timestamp=float(fields[2]), arbitration_id=int(id_text, 16), data=data,
                    dlc=len(data), is_extended_id=len(id_text) != 3, is_rx=True,
                    channel=self.channel))
            elif kind == b"error":
                self._rx.append(can.Message(
                    timestamp=float(fields[2]), arbitration_id=int(fields[1], 16) & 0x1FFFFFFF,
                    is_error_frame=True, data=bytearray(1), dlc=1, is_extended_id=True,
                    is_rx=True, channel=self.channel))
        except (ValueError, binascii.Error):
            return  # a malformed line is skipped, as python-can's client skips it

    def fileno(self) -> int:
        """The socket's file descriptor (for ``select``, as python-can's notifier uses it)."""
        return self._sock.fileno()

    def shutdown(self) -> None:
        """Write the frames still kept, then close the connection."""
        try:
            self.flush()
        except can.CanError:
            pass
        finally:
            super().shutdown()
            self._sock.close()
