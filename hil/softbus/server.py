"""The software bus server: socketcand protocol on loopback, optional bit-rate pacing and faults.

Every frame a client sends goes to every *other* client that opened the same channel, in one
global order (the server's event loop is the single point of serialization), stamped with the
server's clock. With a bit rate the frames are paced by :class:`~hil.softbus.arbiter.Arbiter`:
each holds the wire for its real bit time and contending frames go out lowest id first.

A client that cannot keep up never stalls the others: its socket's outgoing buffer is bounded,
frames beyond it are dropped *for that client only*, counted, and logged.

A frame that arrives alone is written to each receiver at once; frames that arrive together
(a burst the server fell behind on) go to each receiver in one write, in the same order.

Run it embedded (:class:`SoftwareBus`, a thread of its own), as a child process
(:class:`SoftwareBusProcess`) or standalone (``hil bus serve``).
"""

from __future__ import annotations

import asyncio
import contextlib
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
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import can

from hil.errors import BusError, HilError
from hil.softbus.arbiter import Arbiter
from hil.softbus.faults import FaultError, FaultRule, FaultTable
from hil.softbus.protocol import Frame, MessageSplitter, ProtocolError, format_frame, parse_send
from hil.softbus.timing import ERROR_FRAME_BITS

log = logging.getLogger(__name__)

DEFAULT_PORT = 29536
DEFAULT_CHANNEL = "can0"
#: After ``< rawmode >`` the reply ``< ok >`` must reach the client alone (python-can reads it
#: with one exact ``recv``), so frames for a new client are held back this long, then flushed.
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


class _Client(asyncio.Protocol):
    def __init__(self, server: _Server) -> None:
        self.server = server
        self.transport: asyncio.Transport | None = None
        self.splitter = MessageSplitter()
        self.channel: str | None = None
        self.raw = False
        self.held: list[bytes] | None = None  # frames waiting out the rawmode hold
        self.stats = ClientStats()
        self.name = "?"
        self._warned_slow = False

    # asyncio.Protocol hooks -------------------------------------------------------------
    # Latency choices, measured on the project's 2-vCPU VMs with python-can clients (see
    # benchmarks/bench_softbus.py for the round trip figures):
    # - asyncio transports: ``write`` calls ``send()`` at once when nothing is queued, 0.2 µs
    #   over a bare ``socket.send``; ``loop.sock_sendall``/``sock_recv`` would add a task step
    #   per frame per client.
    # - TCP_NODELAY on every client socket (without it Nagle holds back-to-back frames for up
    #   to 40 ms). No TCP_QUICKACK: the ACK for a frame rides on the next frame back; forcing
    #   it costs a setsockopt per read and a bare ACK, +2-6 µs server CPU per round trip.
    # - No busy polling: spinning 300 µs before blocking cut p50 only when client and server
    #   sat on different vCPUs, left p99 as it was, and burned a vCPU (p99 310-340 ->
    #   740-860 µs when all three shared one vCPU).
    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        assert isinstance(transport, asyncio.Transport)
        self.transport = transport
        sock = transport.get_extra_info("socket")
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, self.server.client_sndbuf)
        peer = transport.get_extra_info("peername")
        self.name = f"{peer[0]}:{peer[1]}" if peer else "client"
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
        if self.raw and body.startswith("send "):  # nearly every message: checked first
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
            asyncio.get_running_loop().call_later(self.server.hold_s, self._release)
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


class _Server:
    """The state the event loop owns. Use :class:`SoftwareBus` or ``hil bus serve``."""

    def __init__(self, *, bitrate: int | None, log_path: Path | None, seed: int,
                 hold_s: float, max_client_buffer: int, client_sndbuf: int) -> None:
        self.bitrate = bitrate
        self.client_sndbuf = client_sndbuf
        self.hold_s = hold_s
        self.max_client_buffer = max_client_buffer
        self.channels: dict[str, list[_Client]] = {}
        self.stats = BusStats()
        self.faults = FaultTable(seed=seed)
        self.arbiter: Arbiter[tuple[_Client | None, Frame, str]] | None = (
            Arbiter(bitrate) if bitrate else None)
        self._timer: asyncio.TimerHandle | None = None
        self._mono0 = time.monotonic()
        self._wall0 = time.time()
        self._log_path = log_path
        self._logger: can.Listener | None = None
        #: lines waiting for one write per client while a burst is processed (None: no burst)
        self._batch: dict[_Client, list[bytes]] | None = None

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
        client.transport = None

    # batching -----------------------------------------------------------------------
    def begin_batch(self) -> bool:
        """Collect deliveries until :meth:`end_batch`; False if a batch is already open.

        Batching only happens when one read carries several frames, i.e. when the server has
        fallen behind a burst; a lone frame is written at once. Measured (strace -c) on a
        20,000-frame burst between two python-can clients in separate processes: the server
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
            loop = asyncio.get_running_loop()
            self._timer = loop.call_later(max(0.0, nxt - time.monotonic()), self._pump)

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
                loop = asyncio.get_running_loop()
                loop.call_later(verdict.delay_s, self._broadcast, sender, frame, channel,
                                mono + verdict.delay_s)
                return
        self._broadcast(sender, frame, channel, mono)

    def _broadcast(self, sender: _Client | None, frame: Frame, channel: str,
                   mono: float) -> None:
        stamp = self.stamp(mono)
        line = format_frame(frame, stamp)
        if frame.error:
            self.stats.error_frames += 1
        else:
            self.stats.frames_delivered += 1
        batch = self._batch
        for client in self.channels.get(channel, ()):
            if client is not sender:
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
        return {**asdict(self.stats), "faults": dict(self.faults.injected),
                "clients": {c.name: asdict(c.stats) for cs in self.channels.values()
                            for c in cs},
                "bitrate": self.bitrate}

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
    """A software bus server in a thread of its own, for embedding in a rig or a test.

    The thread shares the GIL with the process that embeds it: while another thread of that
    process computes, every frame waits for the GIL (switch interval 5 ms). Measured round
    trip between python-can clients with a busy Python thread in the embedding process: p50
    15.6 ms embedded against 10.6 ms with :class:`SoftwareBusProcess` (~0.2 ms for either when
    the process is idle). For latency, run the bus as a process.

    >>> with SoftwareBus(port=0) as bus:          # doctest: +SKIP
    ...     spec = bus.spec()                      # 'socketcand:127.0.0.1:41234/can0'
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *,
                 bitrate: int | None = None, log_path: str | Path | None = None,
                 seed: int = 0, allow_remote: bool = False, hold_s: float = RAWMODE_HOLD_S,
                 max_client_buffer: int = MAX_CLIENT_BUFFER,
                 client_sndbuf: int = CLIENT_SNDBUF) -> None:
        check_loopback(host, allow_remote)
        if bitrate is not None and bitrate <= 0:
            raise SoftwareBusError(f"bitrate must be positive, got {bitrate}")
        self.host = host
        self.port = port
        self._state = _Server(bitrate=bitrate, log_path=Path(log_path) if log_path else None,
                              seed=seed, hold_s=hold_s, max_client_buffer=max_client_buffer,
                              client_sndbuf=client_sndbuf)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._failure: BaseException | None = None

    # lifecycle -------------------------------------------------------------------------
    async def serve(self, *, on_listening: Any = None) -> None:
        """Serve until :meth:`request_stop` (the coroutine ``hil bus serve`` runs)."""
        loop = asyncio.get_running_loop()
        self._loop = loop
        self._stop = asyncio.Event()
        server = await loop.create_server(lambda: _Client(self._state), self.host, self.port,
                                          reuse_address=True)
        self.port = server.sockets[0].getsockname()[1]
        self._state.open_log()
        try:
            self._ready.set()
            if on_listening is not None:
                on_listening(self)
            await self._stop.wait()
        finally:
            server.close()
            for clients in list(self._state.channels.values()):
                for client in list(clients):
                    if client.transport is not None:
                        client.transport.close()
            await server.wait_closed()
            self._state.close_log()

    def request_stop(self) -> None:
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)

    def start(self, timeout: float = 5.0) -> SoftwareBus:
        """Start serving in a background thread; returns once the port is listening."""
        if self._thread is not None:
            raise SoftwareBusError("software bus already started")

        def run() -> None:
            try:
                asyncio.run(self.serve())
            except BaseException as exc:  # reported by start()/stop(), never silent
                self._failure = exc
                log.error("software bus thread died: %r", exc)
            finally:
                self._ready.set()

        self._thread = threading.Thread(target=run, name="hil-softbus", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise SoftwareBusError(f"software bus did not start within {timeout} s")
        if self._failure is not None:
            raise SoftwareBusError(f"software bus failed to start on {self.host}:{self.port}: "
                                   f"{self._failure}") from self._failure
        return self

    def stop(self, timeout: float = 5.0) -> None:
        if self._thread is None:
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

    def call(self, func: Any, *args: Any, timeout: float = 5.0) -> Any:
        """Run ``func(state, *args)`` on the server's loop and return its result."""
        if self._loop is None:
            raise SoftwareBusError("software bus is not running")

        async def run() -> Any:
            return func(self._state, *args)

        return asyncio.run_coroutine_threadsafe(run(), self._loop).result(timeout)

    def add_fault(self, rule: FaultRule) -> int:
        return int(self.call(lambda s: s.faults.add(rule)))

    def clear_faults(self, rule_id: int | None = None) -> None:
        self.call(lambda s: s.faults.clear(rule_id))

    def inject_error_frames(self, count: int = 1, channel: str = DEFAULT_CHANNEL) -> None:
        self.call(lambda s: s.command(["errors", str(count), channel]))

    def stats(self) -> dict[str, Any]:
        return dict(self.call(lambda s: s.stats_dict()))


class SoftwareBusProcess:
    """The software bus in a child process (``python -m hil bus serve``)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, bitrate: int | None = None,
                 log_path: str | Path | None = None, seed: int = 0) -> None:
        check_loopback(host, False)
        self.host = host
        self.port = port
        self._args = [sys.executable, "-m", "hil", "bus", "serve", "--host", host,
                      "--port", str(port), "--seed", str(seed)]
        if bitrate:
            self._args += ["--bitrate", str(bitrate)]
        if log_path:
            self._args += ["--log", str(log_path)]
        self.proc: subprocess.Popen[str] | None = None

    def start(self, timeout: float = 10.0) -> SoftwareBusProcess:
        self.proc = subprocess.Popen(self._args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
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
        self.stop()
        raise SoftwareBusError(f"software bus process did not start: {self._stderr()}")

    def _stderr(self) -> str:
        if self.proc is None or self.proc.stderr is None:
            return ""
        with contextlib.suppress(Exception):
            return self.proc.stderr.read()[-2000:]
        return ""

    def spec(self, channel: str = DEFAULT_CHANNEL) -> str:
        return f"socketcand:{self.host}:{self.port}/{channel}"

    def stop(self, timeout: float = 5.0) -> None:
        if self.proc is None or self.proc.poll() is not None:
            return
        self.proc.terminate()
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout)

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
