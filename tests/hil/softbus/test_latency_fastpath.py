"""The software bus's low-latency paths keep its behaviour: the table-driven ``send`` parser,
the direct single-frame path, and bursts written to each receiver in one write.

Only behaviour is checked here (order, completeness, counting); the speed of these paths is
measured by ``benchmarks/bench_softbus.py``, never asserted (machines are noisy)."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from hil.softbus import FaultKind, FaultRule, SoftwareBus
from hil.softbus.protocol import Frame, ProtocolError, format_send, parse_send
from hil.softbus.server import _Client, _Server


# -- the parser ------------------------------------------------------------------------------
@pytest.mark.parametrize("spelling", ["{:x}", "{:X}", "{:02x}", "{:02X}"])
def test_every_byte_spelling_parses_to_its_value(spelling: str) -> None:
    for value in range(256):
        text = spelling.format(value)
        assert parse_send(f"123 1 {text}").data == bytes([value])


def test_unusual_spellings_parse_as_before_and_bad_bytes_are_refused() -> None:
    # what int(text, 16) accepts still parses (the table is only a fast path) ...
    assert parse_send("123 3 001 0x2 +3").data == b"\x01\x02\x03"
    assert parse_send("18FEF100 8 de AD 0 ff 7 70 Fa 1").data == bytes.fromhex("deAD00ff0770Fa01")
    # ... and what it refuses, or what does not fit a byte, is still an error
    for body in ("123 1 100", "123 1 -1", "123 1 zz", "123 2 1", "123 1 1 2"):
        with pytest.raises(ProtocolError):
            parse_send(body)


def test_python_can_spelling_round_trips() -> None:
    from can.interfaces.socketcand.socketcand import convert_can_message_to_ascii_message
    for can_id, ext, data in ((0x7FF, False, bytes(range(8))), (0x18FEF100, True, b"\x00\xff"),
                              (0x0, False, b"")):
        line = convert_can_message_to_ascii_message(
            can.Message(arbitration_id=can_id, is_extended_id=ext, data=data))
        assert parse_send(line[len("< send "):-2]) == Frame(can_id, data, ext)
    frame = Frame(0x123, b"\x0a\xb0", False)
    assert parse_send(format_send(frame).decode()[7:-2]) == frame


# -- bursts: one write per receiver, same order ------------------------------------------
class _FakeTransport:
    def __init__(self, buffered: int = 0) -> None:
        self.writes: list[bytes] = []
        self.buffered = buffered

    def write(self, data: bytes) -> None:
        self.writes.append(data)

    def is_closing(self) -> bool:
        return False

    def get_write_buffer_size(self) -> int:
        return self.buffered


def _server_with(n_clients: int, *, buffered: int = 0) -> tuple[_Server, list[_Client]]:
    server = _Server(bitrate=None, log_path=None, seed=0, hold_s=0.0,
                     max_client_buffer=1024, client_sndbuf=4096)
    clients = []
    for _ in range(n_clients):
        client = _Client(server)
        client.transport = _FakeTransport(buffered)  # type: ignore[assignment]
        client.channel, client.raw = "can0", True
        server.attach(client)
        clients.append(client)
    return server, clients


def _sends(ids: range) -> bytes:
    return b"".join(format_send(Frame(i, i.to_bytes(2, "big"), False)) for i in ids)


def test_a_burst_in_one_read_is_one_write_per_receiver_in_order() -> None:
    server, (sender, b, c) = _server_with(3)
    sender.data_received(_sends(range(0x100, 0x140)))
    for receiver in (b, c):
        writes = receiver.transport.writes  # type: ignore[union-attr]
        assert len(writes) == 1
        ids = [int(m.split()[2], 16) for m in writes[0].split(b">")[:-1]]
        assert ids == list(range(0x100, 0x140))
        assert receiver.stats.sent == 0x40
    assert sender.transport.writes == []  # type: ignore[union-attr]
    assert server.stats.frames_delivered == 0x40 and server._batch is None


def test_a_single_frame_goes_straight_out() -> None:
    _, (sender, b) = _server_with(2)
    sender.data_received(_sends(range(0x10, 0x11)))
    sender.data_received(b"< send 11 1 ")  # a partial message: nothing yet ...
    assert len(b.transport.writes) == 1  # type: ignore[union-attr]
    sender.data_received(b"7 >")  # ... until its end arrives
    assert [w.split()[2] for w in b.transport.writes] == [b"010", b"011"]  # type: ignore[union-attr]


def test_a_slow_receiver_drops_a_whole_burst_and_counts_every_frame() -> None:
    server, (sender, slow) = _server_with(2, buffered=10_000)  # over max_client_buffer
    sender.data_received(_sends(range(0x200, 0x20A)))
    assert slow.transport.writes == []  # type: ignore[union-attr]
    assert slow.stats.dropped_slow == 10 and server.stats.dropped_slow == 10


def test_frames_held_after_rawmode_keep_their_order_and_cap() -> None:
    _, (sender, fresh) = _server_with(2)
    fresh.held = []
    sender.data_received(_sends(range(0x300, 0x305)))
    sender.data_received(_sends(range(0x305, 0x306)))
    assert [int(m.split()[2], 16) for m in fresh.held] == list(range(0x300, 0x306))
    fresh.held = [b""] * 99_998
    sender.data_received(_sends(range(0x400, 0x405)))
    assert len(fresh.held) == 100_000 and fresh.stats.dropped_slow == 3


# -- end to end through real sockets -----------------------------------------------------
def _raw_client(bus: SoftwareBus) -> socket.socket:
    sock = socket.create_connection((bus.host, bus.port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.settimeout(5.0)
    assert sock.recv(16) == b"< hi >"
    sock.sendall(b"< open can0 >")
    assert sock.recv(16) == b"< ok >"
    sock.sendall(b"< rawmode >")
    assert sock.recv(16) == b"< ok >"
    return sock


def _read_messages(sock: socket.socket, n: int, timeout: float = 5.0) -> list[bytes]:
    buf = b""
    deadline = time.monotonic() + timeout
    while buf.count(b">") < n and time.monotonic() < deadline:
        chunk = sock.recv(65536)
        if not chunk:
            break
        buf += chunk
    return [m.strip() + b" >" for m in buf.split(b">")[:n]]


@pytest.fixture
def quick_bus() -> Iterator[SoftwareBus]:
    with SoftwareBus(port=0, hold_s=0.0) as bus:
        yield bus


def test_burst_end_to_end_order_stamps_and_counts(quick_bus: SoftwareBus) -> None:
    a, b, c = (_raw_client(quick_bus) for _ in range(3))
    try:
        time.sleep(0.05)
        n = 500
        a.sendall(_sends(range(n)))  # one sendall: the server reads it in few reads
        for receiver in (b, c):
            got = _read_messages(receiver, n)
            assert [int(m.split()[2], 16) for m in got] == list(range(n))
            stamps = [float(m.split()[3]) for m in got]
            assert stamps == sorted(stamps)
        a.settimeout(0.2)
        with pytest.raises(TimeoutError):
            a.recv(16)  # nothing comes back to the sender
        stats = quick_bus.stats()
        assert stats["frames_in"] == n and stats["frames_delivered"] == n
    finally:
        for sock in (a, b, c):
            sock.close()


def test_a_reply_comes_after_the_frames_of_the_same_read(quick_bus: SoftwareBus) -> None:
    a, b = _raw_client(quick_bus), _raw_client(quick_bus)
    try:
        a.sendall(f"< hil control {quick_bus.control_token} >".encode())  # a control client
        assert a.recv(32) == b"< hil ok control >"
        time.sleep(0.05)
        a.sendall(b"< send 100 1 1 >< hil errors 1 >< send 101 1 2 >")
        assert [m.split()[1] for m in _read_messages(a, 2)] == [b"error", b"hil"]
        assert [m.split()[1:3] for m in _read_messages(b, 3)] == [
            [b"frame", b"100"], [b"error", b"00000004"], [b"frame", b"101"]]
    finally:
        a.close()
        b.close()


def test_bursts_with_faults_and_log(tmp_path: Path) -> None:
    log_path = tmp_path / "bus.log"
    with SoftwareBus(port=0, hold_s=0.0, log_path=log_path) as bus:
        bus.add_fault(FaultRule(FaultKind.DROP, can_id=0x105, mask=0x7FF))
        a, b = _raw_client(bus), _raw_client(bus)
        try:
            time.sleep(0.05)
            a.sendall(_sends(range(0x100, 0x10A)))
            got = [int(m.split()[2], 16) for m in _read_messages(b, 9)]
            assert got == [i for i in range(0x100, 0x10A) if i != 0x105]
        finally:
            a.close()
            b.close()
    logged = [m.arbitration_id for m in can.LogReader(log_path)]
    assert logged == [i for i in range(0x100, 0x10A) if i != 0x105]
