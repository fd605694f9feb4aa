"""Hostile and careless clients (issue #22.2, #22.3): none may freeze the bus, stay in its
client table after leaving, hoard memory, or flood the log.

Loopback only, ephemeral ports; every wait is bounded by a socket timeout.
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Iterator

import pytest

from hil.errors import BusError
from hil.softbus import SoftwareBus
from hil.softbus.commands import ERROR_SLICE, MAX_ERROR_FRAMES, run
from hil.softbus.control import control, token_path
from hil.softbus.core import BusCore
from hil.softbus.loop import EventLoop
from hil.softbus.ratelog import AddressWarnings

TIMEOUT = 5.0


def _connect(bus: SoftwareBus) -> socket.socket:
    sock = socket.create_connection((bus.host, bus.port), timeout=TIMEOUT)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    assert _read(sock, 1) == [b"< hi >"]
    return sock


def _read(sock: socket.socket, n: int) -> list[bytes]:
    """``n`` whole messages (the socket's timeout bounds each wait)."""
    buf = b""
    while buf.count(b">") < n:
        chunk = sock.recv(65536)
        if not chunk:
            break
        buf += chunk
    return [m.strip() + b" >" for m in buf.split(b">")[:n] if m.strip()]


def _raw(bus: SoftwareBus, channel: str = "can0") -> socket.socket:
    sock = _connect(bus)
    sock.sendall(f"< open {channel} >< rawmode >< echo >".encode())
    assert _read(sock, 3) == [b"< ok >", b"< ok >", b"< echo >"]
    return sock


def _control_client(bus: SoftwareBus) -> socket.socket:
    sock = _connect(bus)
    sock.sendall(f"< hil control {bus.control_token} >".encode())
    assert _read(sock, 1) == [b"< hil ok control >"]
    return sock


def _round_trips(a: socket.socket, b: socket.socket, n: int) -> int:
    """A sends, B answers with id+1, A reads the answer: how many completed (error frames
    on the way are skipped)."""
    done = 0
    for i in range(n):
        a.sendall(f"< send 100 2 {i >> 8:02X} {i & 0xFF:02X} >".encode())
        if not _next_frame(b, b"100"):
            break
        b.sendall(f"< send 101 2 {i >> 8:02X} {i & 0xFF:02X} >".encode())
        if not _next_frame(a, b"101"):
            break
        done += 1
    return done


_pending: dict[int, bytes] = {}


def _next_frame(sock: socket.socket, can_id: bytes) -> bool:
    """Read up to the next data frame with ``can_id`` (skipping error frames)."""
    buf = _pending.pop(sock.fileno(), b"")
    while True:
        while b">" not in buf:
            chunk = sock.recv(65536)
            if not chunk:
                return False
            buf += chunk
        message, _, buf = buf.partition(b">")
        words = message.split()
        if words[1:2] == [b"frame"] and words[2:3] == [can_id]:
            _pending[sock.fileno()] = buf
            return True


@pytest.fixture
def bus() -> Iterator[SoftwareBus]:
    with SoftwareBus(port=0, hold_s=0.0) as softbus:
        yield softbus


# -- #22.2: control commands ---------------------------------------------------------------
def test_a_frame_client_may_not_send_control_commands(bus: SoftwareBus) -> None:
    hostile = _raw(bus)
    try:
        hostile.sendall(b"< hil errors 30000000 >")
        [reply] = _read(hostile, 1)
        assert reply.startswith(b"< hil error control commands are for the control connection")
        hostile.sendall(b"< hil control not-the-token >< hil stats >")
        assert [r[:26] for r in _read(hostile, 2)] == [b"< hil error wrong control ",
                                                       b"< hil error control comman"]
        stats = bus.stats()
        assert stats["control_refused"] == 3 and stats["error_frames"] == 0
        assert stats["clients"][hostile.getsockname()[0] + ":"
                                + str(hostile.getsockname()[1])]["control_refused"] == 3
    finally:
        hostile.close()


def test_control_arguments_are_bounded(bus: SoftwareBus) -> None:
    ctl = _control_client(bus)
    try:
        ctl.sendall(b"< hil errors 30000000 >< hil errors -1 >< hil errors x >"
                    b"< hil fault add delay delay=1e9 >< hil fault add delay delay=nan >")
        replies = _read(ctl, 5)
        assert all(r.startswith(b"< hil error ") for r in replies), replies
        assert f"1..{MAX_ERROR_FRAMES}".encode() in replies[0]
        for _ in range(64):
            ctl.sendall(b"< hil fault add drop id=0x7ff >")
            assert _read(ctl, 1)[0].startswith(b"< hil ok ")
        ctl.sendall(b"< hil fault add drop id=0x7ff >")
        assert _read(ctl, 1)[0].startswith(b"< hil error at most 64 fault rules")
        assert bus.stats()["error_frames"] == 0
    finally:
        ctl.close()


def test_errors_run_in_slices_that_yield_to_the_loop() -> None:
    loop = EventLoop()
    try:
        core = BusCore(bitrate=None, log_path=None, seed=0, hold_s=0.0,
                       max_client_buffer=1 << 20, client_sndbuf=1 << 16, loop=loop)
        replies: list[str] = []
        run(core, ["errors", str(MAX_ERROR_FRAMES)], replies.append)
        assert core.stats.error_frames == ERROR_SLICE and replies == []  # the rest waits
        turns = 0
        while not replies and turns < 10 * MAX_ERROR_FRAMES // ERROR_SLICE:
            loop.run_once(0.0, spin=False)
            turns += 1
        assert replies == ["< hil ok >"] and core.stats.error_frames == MAX_ERROR_FRAMES
        assert turns >= MAX_ERROR_FRAMES // ERROR_SLICE - 1
    finally:
        loop.close()


def test_the_worst_command_does_not_freeze_the_bus(bus: SoftwareBus) -> None:
    listeners = [_raw(bus) for _ in range(3)]  # error frames go to them (they never read)
    a, b = _raw(bus), _raw(bus)
    hostile, ctl = _raw(bus, "can9"), _control_client(bus)
    try:
        assert _round_trips(a, b, 20) == 20
        hostile.sendall(b"< hil errors 30000000 >")  # refused: a frame client
        ctl.sendall(f"< hil errors {MAX_ERROR_FRAMES} >".encode())  # the worst allowed
        newcomer = socket.create_connection((bus.host, bus.port), timeout=TIMEOUT)
        try:
            assert _read(newcomer, 1) == [b"< hi >"]
        finally:
            newcomer.close()
        assert _round_trips(a, b, 200) == 200
        assert _read(ctl, 1) == [b"< hil ok >"]
        assert _read(hostile, 1)[0].startswith(b"< hil error control commands")
        stats = bus.stats()
        assert stats["error_frames"] == MAX_ERROR_FRAMES and stats["control_refused"] == 1
    finally:
        for sock in [*listeners, a, b, hostile, ctl]:
            sock.close()


def test_the_control_client_uses_the_token_file_and_refuses_a_wrong_token(
        bus: SoftwareBus) -> None:
    path = token_path(bus.port)
    assert bus.token_path == path and path.read_text().strip() == bus.control_token
    assert path.stat().st_mode & 0o077 == 0  # the user's alone
    assert control(bus.host, bus.port, ["fault", "list"]) == "< hil faults {} >"
    with pytest.raises(BusError, match="refused the control connection: wrong control token"):
        control(bus.host, bus.port, ["stats"], token="0" * 32)
    port = bus.port
    bus.stop()
    assert not token_path(port).exists()


# -- #22.3: clients that leave, endless messages, unread replies, warnings -----------------
def _clients_leave(bus: SoftwareBus, n: int, switch_channel: bool) -> None:
    for i in range(n):
        sock = _connect(bus)
        second = f"x{i}" if switch_channel else "can0"
        sock.sendall(f"< open can0 >< rawmode >< open {second} >< rawmode >< echo >".encode())
        assert _read(sock, 5)[-1] == b"< echo >"
        sock.close()


def _settle(bus: SoftwareBus, connected: int) -> dict[str, object]:
    deadline = time.monotonic() + TIMEOUT
    stats = bus.stats()
    while stats["clients_connected"] != connected and time.monotonic() < deadline:
        time.sleep(0.02)
        stats = bus.stats()
    return stats


@pytest.mark.parametrize("switch_channel", [False, True], ids=["same-channel", "new-channel"])
def test_clients_that_leave_are_forgotten(bus: SoftwareBus, switch_channel: bool) -> None:
    a, b = _raw(bus), _raw(bus)
    try:
        live = {f"{s.getsockname()[0]}:{s.getsockname()[1]}" for s in (a, b)}
        channels_before = set(bus.call(lambda s: list(s.channels)))
        _clients_leave(bus, 4000 if not switch_channel else 1000, switch_channel)
        stats = _settle(bus, 2)
        assert stats["clients_connected"] == 2
        assert set(stats["clients"]) == live  # `hil bus stats` lists the live clients only
        assert set(bus.call(lambda s: list(s.channels))) == channels_before
        assert bus.call(lambda s: sum(len(c) for c in s.channels.values())) == 2
        assert _round_trips(a, b, 50) == 50
    finally:
        a.close()
        b.close()


def test_an_endless_message_drops_its_client(bus: SoftwareBus) -> None:
    a, b = _raw(bus), _raw(bus)
    hostile = _raw(bus)
    try:
        chunk = b"x" * 65536
        hostile.sendall(b"< send 123 8 ")
        sent = 0
        with pytest.raises(OSError):  # the bus hangs up (reset or broken pipe) ...
            while sent < 64 * 1024 * 1024:
                hostile.sendall(chunk)
                sent += len(chunk)
            hostile.recv(1)  # ... or its end reads as closed
            raise ConnectionResetError("closed")
        stats = _settle(bus, 2)
        assert stats["dropped_clients"] == 1 and stats["protocol_errors"] >= 1
        assert _round_trips(a, b, 50) == 50
    finally:
        for sock in (a, b, hostile):
            sock.close()


def test_a_client_that_does_not_read_its_replies_is_dropped() -> None:
    with SoftwareBus(port=0, hold_s=0.0, max_client_buffer=64 * 1024,
                     client_sndbuf=16 * 1024) as bus:
        greedy = _connect(bus)
        greedy.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        chunk = b"< echo >" * 8192
        sent = 0
        try:
            with pytest.raises(OSError):
                while sent < 64 * 1024 * 1024:  # 64 MiB of replies it never reads
                    greedy.sendall(chunk)
                    sent += len(chunk)
            stats = _settle(bus, 0)
            assert stats["dropped_clients"] == 1 and stats["clients_connected"] == 0
        finally:
            greedy.close()


def test_warnings_are_logged_once_per_address_not_per_connection(
        bus: SoftwareBus, caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.WARNING, logger="hil.softbus")
    for _ in range(30):  # misbehave, reconnect, misbehave again
        sock = _connect(bus)
        sock.sendall(b"< bogus >" * 10 + b"< hil stats >< echo >")
        assert _read(sock, 2)[-1] == b"< echo >"
        sock.close()
    assert bus.stats()["protocol_errors"] == 300
    warned = [r for r in caplog.records if "127.0.0.1" in r.getMessage()]
    assert len(warned) == 1, [r.getMessage() for r in warned]


def test_address_warnings_are_rate_limited_and_bounded() -> None:
    now = [0.0]
    logged: list[str] = []

    class Sink(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            logged.append(record.getMessage())

    logger = logging.getLogger("test.ratelog")
    logger.addHandler(Sink())
    logger.propagate = False
    warnings = AddressWarnings(logger, interval_s=60.0, max_addresses=2, clock=lambda: now[0])
    assert warnings.warn("10.0.0.1", "bad %s", "a")
    assert not any(warnings.warn("10.0.0.1", "bad %s", "b") for _ in range(99))
    now[0] = 61.0
    assert warnings.warn("10.0.0.1", "bad %s", "c")
    assert logged == ["bad a", "bad c (99 similar warnings from 10.0.0.1 held back before this)"]
    for host in ("10.0.0.2", "10.0.0.3"):
        warnings.warn(host, "x")
    assert len(warnings._states) == 2 and "10.0.0.1" not in warnings._states
