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

This module is the public facade. The pieces live in modules of their own:
:mod:`hil.softbus.transport` (the socket transport), :mod:`hil.softbus.session` (the
per-client protocol session), :mod:`hil.softbus.core` (the bus core: delivery, batching,
pacing, faults), :mod:`hil.softbus.local` (the in-process client), :mod:`hil.softbus.process`
(the bus as a child process) and :mod:`hil.softbus.settings` (ports and limits).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from hil.errors import BusError
from hil.softbus.commands import parse_errors
from hil.softbus.control import CONTROL_TOKEN_ENV, new_token, remove_token, write_token
from hil.softbus.core import BusCore, BusStats
from hil.softbus.faults import FaultRule
from hil.softbus.local import LocalBus, LocalEndpoint
from hil.softbus.loop import READ, EventLoop
from hil.softbus.process import SoftwareBusProcess
from hil.softbus.session import ClientSession, ClientStats
from hil.softbus.settings import (
    BUSY_POLL_ENV,
    CLIENT_SNDBUF,
    DEFAULT_BUSY_POLL_US,
    DEFAULT_CHANNEL,
    DEFAULT_PORT,
    MAX_CLIENT_BUFFER,
    RAWMODE_HOLD_S,
    TAKEOVER_S,
    SoftwareBusError,
    busy_poll_from_env,
    check_loopback,
)
from hil.softbus.transport import SocketTransport, Transport

log = logging.getLogger(__name__)

CONTROL_TOKEN = re.compile(r"[A-Za-z0-9_-]{16,128}")

#: the names these classes had when they lived here (tests build a core and sessions directly)
_Server = BusCore
_Client = ClientSession
_SocketTransport = SocketTransport
_LocalEndpoint = LocalEndpoint

__all__ = [
    "BUSY_POLL_ENV", "CLIENT_SNDBUF", "DEFAULT_BUSY_POLL_US", "DEFAULT_CHANNEL", "DEFAULT_PORT",
    "MAX_CLIENT_BUFFER", "RAWMODE_HOLD_S", "TAKEOVER_S", "BusCore", "BusStats", "ClientSession",
    "ClientStats", "LocalBus", "LocalEndpoint", "SocketTransport", "SoftwareBus",
    "SoftwareBusError", "SoftwareBusProcess", "Transport", "busy_poll_from_env",
    "check_loopback", "raise_if_unreachable",
]


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

    ``control_token``: what a connection must send (``< hil control TOKEN >``) before it may
    send control commands (default: a fresh random one, :attr:`control_token`); with
    ``token_file`` (default) the bus writes it to :func:`hil.softbus.control.token_path` of its
    port while it listens, for ``hil bus fault``/``stats``. This process's own calls
    (:meth:`add_fault`, :meth:`stats` …) need no token.

    >>> with SoftwareBus(port=0) as bus:          # doctest: +SKIP
    ...     spec = bus.spec()                      # 'socketcand:127.0.0.1:41234/can0'
    """

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *,
                 bitrate: int | None = None, log_path: str | Path | None = None,
                 seed: int = 0, allow_remote: bool = False, hold_s: float = RAWMODE_HOLD_S,
                 max_client_buffer: int = MAX_CLIENT_BUFFER,
                 client_sndbuf: int = CLIENT_SNDBUF, busy_poll_us: float | None = None,
                 takeover_s: float = TAKEOVER_S, control_token: str | None = None,
                 token_file: bool = True) -> None:
        check_loopback(host, allow_remote)
        if control_token is not None and not CONTROL_TOKEN.fullmatch(control_token):
            raise SoftwareBusError("a control token is 16 to 128 letters, digits, '_' or '-'")
        if bitrate is not None and bitrate <= 0:
            raise SoftwareBusError(f"bitrate must be positive, got {bitrate}")
        self.host = host
        self.port = port
        self._busy_poll_arg = busy_poll_us
        self.busy_poll_us = 0.0  # resolved when it starts: see _open
        self.takeover_s = takeover_s
        self._state = BusCore(bitrate=bitrate, log_path=Path(log_path) if log_path else None,
                              seed=seed, hold_s=hold_s, max_client_buffer=max_client_buffer,
                              client_sndbuf=client_sndbuf,
                              control_token=control_token or new_token())
        self._token_file = token_file
        #: where the control token was written while the bus listens (None: nowhere)
        self.token_path: Path | None = None
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
        if self._token_file:
            try:
                self.token_path = write_token(self.port, self.control_token)
            except OSError as exc:
                log.warning("software bus: cannot write its control token (%s); hil bus "
                            "fault/stats need --token or $%s", exc, CONTROL_TOKEN_ENV)

    @property
    def control_token(self) -> str:
        """What a control connection sends first: ``< hil control TOKEN >``."""
        return self._state.control_token

    def _close(self) -> None:
        loop, self._loop = self._loop, None
        if self.token_path is not None:
            remove_token(self.port, self.control_token)
            self.token_path = None
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
            client = ClientSession(self._state)
            transport = SocketTransport(sock, self._loop, client)
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

    def _acquire(self) -> BusCore:
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
    def _owning(self) -> Iterator[BusCore]:
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
        """Put ``count`` error frames (at most :data:`~hil.softbus.commands.MAX_ERROR_FRAMES`)
        on ``channel``."""
        try:
            count, channel = parse_errors(["errors", str(count), channel])
        except ValueError as exc:
            raise SoftwareBusError(str(exc)) from exc
        self.call(lambda s: s.inject_errors(count, channel))

    def stats(self) -> dict[str, Any]:
        return dict(self.call(lambda s: s.stats_dict()))

    def local_bus(self, channel: str = DEFAULT_CHANNEL, *, busy_poll_us: float = 0.0,
                  max_queue: int = 100_000) -> LocalBus:
        """A python-can bus on this software bus without a socket, for a lockstep loop in
        this process. See :class:`LocalBus`."""
        if self._loop is None:
            raise SoftwareBusError("software bus is not running: start() it first")
        return LocalBus(self, channel, busy_poll_us=busy_poll_us, max_queue=max_queue)


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
