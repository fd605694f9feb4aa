"""The software bus with python-can's own socketcand client."""

from __future__ import annotations

import json
import socket
import time
from collections.abc import Iterator

import can
import pytest

from hil.bus import open_bus
from hil.cli.bus import control
from hil.errors import BusError
from hil.softbus import FaultKind, FaultRule, SoftwareBus, SoftwareBusProcess
from hil.softbus.server import SoftwareBusError

from .frames import drain
from .frames import msg as _msg


def _drain(bus: can.BusABC, n: int, timeout: float = 5.0) -> list[can.Message]:
    return drain(bus, n, timeout, poll_s=0.2)


@pytest.fixture
def pair(softbus: SoftwareBus) -> Iterator[tuple[can.BusABC, can.BusABC]]:
    a, b = open_bus(softbus.spec()), open_bus(softbus.spec())
    yield a, b
    a.shutdown()
    b.shutdown()


def test_frames_reach_every_other_client_not_the_sender(softbus: SoftwareBus) -> None:
    a, b, c = (open_bus(softbus.spec()) for _ in range(3))
    try:
        a.send(_msg(0x181, b"\x10\x20"))
        a.send(_msg(0x18FEF100, bytes(8), extended=True))
        for other in (b, c):
            got = _drain(other, 2)
            assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in got] == [
                (0x181, False, b"\x10\x20"), (0x18FEF100, True, bytes(8))]
        assert a.recv(0.2) is None
    finally:
        for bus in (a, b, c):
            bus.shutdown()


def test_one_global_order_for_all_receivers(softbus: SoftwareBus) -> None:
    senders = [open_bus(softbus.spec()) for _ in range(2)]
    listeners = [open_bus(softbus.spec()) for _ in range(2)]
    try:
        for i in range(200):
            senders[i % 2].send(_msg(0x100 + (i % 2), i.to_bytes(2, "little")))
        seen = [[(m.arbitration_id, bytes(m.data)) for m in _drain(lst, 200)]
                for lst in listeners]
        assert len(seen[0]) == 200 and seen[0] == seen[1]
        stamps = [m.timestamp for m in _drain(senders[0], 100)]
        assert stamps == sorted(stamps)
    finally:
        for bus in senders + listeners:
            bus.shutdown()


def test_channels_are_separate(softbus: SoftwareBus) -> None:
    a, b = open_bus(softbus.spec("can0")), open_bus(softbus.spec("can1"))
    try:
        a.send(_msg(0x123))
        assert b.recv(0.3) is None
    finally:
        a.shutdown()
        b.shutdown()


def test_faults_drop_delay_corrupt_error(softbus: SoftwareBus,
                                         pair: tuple[can.BusABC, can.BusABC]) -> None:
    a, b = pair
    rule = softbus.add_fault(FaultRule(FaultKind.DROP, can_id=0x181, mask=0x7FF))
    a.send(_msg(0x181))
    a.send(_msg(0x182))
    assert [m.arbitration_id for m in _drain(b, 2, 1.0)] == [0x182]
    softbus.clear_faults(rule)

    softbus.add_fault(FaultRule(FaultKind.CORRUPT, can_id=0x183, mask=0x7FF))
    a.send(_msg(0x183, bytes(8)))
    corrupted = _drain(b, 1)[0]
    assert corrupted.arbitration_id == 0x183 and bytes(corrupted.data) != bytes(8)
    softbus.clear_faults()

    softbus.add_fault(FaultRule(FaultKind.DELAY, can_id=0x184, mask=0x7FF, delay_s=0.3))
    a.send(_msg(0x184))
    a.send(_msg(0x185))
    got = _drain(b, 2)
    assert [m.arbitration_id for m in got] == [0x185, 0x184]
    assert got[1].timestamp - got[0].timestamp == pytest.approx(0.3, abs=0.05)
    softbus.clear_faults()

    softbus.add_fault(FaultRule(FaultKind.ERROR, can_id=0x186, mask=0x7FF, count=1))
    a.send(_msg(0x186))
    a.send(_msg(0x186))
    got = _drain(b, 2)
    assert got[0].is_error_frame and not got[1].is_error_frame
    softbus.inject_error_frames(3)
    assert all(m.is_error_frame for m in _drain(b, 3))
    assert softbus.stats()["error_frames"] == 4


def test_control_protocol_and_cli_errors(softbus: SoftwareBus,
                                         pair: tuple[can.BusABC, can.BusABC]) -> None:
    a, b = pair
    reply = control(softbus.host, softbus.port, ["fault", "add", "drop", "id=0x200"])
    assert reply.startswith("< hil ok ")
    a.send(_msg(0x200))
    a.send(_msg(0x201))
    assert [m.arbitration_id for m in _drain(b, 2, 1.0)] == [0x201]
    listing = json.loads(control(softbus.host, softbus.port, ["fault", "list"])[12:-2])
    assert next(iter(listing.values())).startswith("drop id=0x200")
    with pytest.raises(BusError, match="unknown fault kind"):
        control(softbus.host, softbus.port, ["fault", "add", "melt"])
    stats = json.loads(control(softbus.host, softbus.port, ["stats"])[12:-2])
    assert stats["faults"]["drop"] == 1


def test_a_client_that_never_reads_does_not_stall_the_others() -> None:
    with SoftwareBus(port=0, max_client_buffer=64 * 1024, client_sndbuf=16 * 1024) as softbus:
        # a raw client that handshakes and then never reads
        dead = socket.create_connection((softbus.host, softbus.port))
        dead.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        dead.recv(16)
        dead.sendall(b"< open can0 >")
        dead.recv(16)
        dead.sendall(b"< rawmode >")
        dead.recv(16)
        a, b = open_bus(softbus.spec()), open_bus(softbus.spec())
        try:
            time.sleep(0.1)
            n, chunk = 20_000, 500
            got: list[can.Message] = []
            for start in range(0, n, chunk):  # a live reader keeps up with each chunk
                for i in range(start, start + chunk):
                    a.send(_msg(0x300, i.to_bytes(4, "little")))
                got += _drain(b, chunk, timeout=10)
            assert len(got) == n
            assert [int.from_bytes(m.data, "little") for m in got] == list(range(n))
            assert softbus.stats()["dropped_slow"] > 0
        finally:
            a.shutdown()
            b.shutdown()
            dead.close()


def test_protocol_errors_are_counted_not_fatal(softbus: SoftwareBus) -> None:
    raw = socket.create_connection((softbus.host, softbus.port))
    try:
        raw.recv(16)
        raw.sendall(b"< open can0 >")
        raw.recv(16)
        raw.sendall(b"< rawmode >")
        raw.recv(16)
        raw.sendall(b"< send 123 4 1 2 >< bogus >")
        time.sleep(0.1)
        assert softbus.stats()["protocol_errors"] == 2
    finally:
        raw.close()


def test_refuses_non_loopback_unless_asked() -> None:
    with pytest.raises(SoftwareBusError, match="not a loopback"):
        SoftwareBus("0.0.0.0", 0)
    SoftwareBus("0.0.0.0", 0, allow_remote=True)  # constructing is allowed when asked


def test_port_in_use_is_a_clear_error(softbus: SoftwareBus) -> None:
    with pytest.raises(SoftwareBusError, match="failed to start"):
        SoftwareBus(port=softbus.port).start()


def test_server_log_is_a_readable_candump(tmp_path) -> None:
    log_path = tmp_path / "server.log"
    with SoftwareBus(port=0, log_path=log_path) as softbus:
        a, b = open_bus(softbus.spec()), open_bus(softbus.spec())
        a.send(_msg(0x123, b"\xAB"))
        _drain(b, 1)
        a.shutdown()
        b.shutdown()
    frames = list(can.LogReader(log_path))
    assert [(m.arbitration_id, bytes(m.data)) for m in frames] == [(0x123, b"\xAB")]


def test_child_process_bus() -> None:
    with SoftwareBusProcess(port=0) as proc:
        a, b = open_bus(proc.spec()), open_bus(proc.spec())
        try:
            a.send(_msg(0x42))
            assert _drain(b, 1)[0].arbitration_id == 0x42
        finally:
            a.shutdown()
            b.shutdown()
    assert proc.proc is not None and proc.proc.poll() is not None
