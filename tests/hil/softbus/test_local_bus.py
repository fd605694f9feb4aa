"""A client in the bus's own process (``SoftwareBus.local_bus``): the same frames, order, stamps,
faults and counters as a socket client, written behind until its next ``recv``, and the bus
thread serving the other clients whenever the local client is not running the loop."""

from __future__ import annotations

import itertools
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from hil.bus import open_bus
from hil.softbus import FaultKind, FaultRule, SoftwareBus
from hil.softbus.server import LocalBus, SoftwareBusError

from .frames import drain as _drain
from .frames import fields as _fields
from .frames import msg as _msg

ECHO = Path(__file__).resolve().parents[2] / "helpers" / "softbus_echo.py"


@pytest.fixture
def bus() -> Iterator[SoftwareBus]:
    with SoftwareBus(port=0, takeover_s=0.02) as softbus:
        yield softbus


def test_frames_reach_a_local_client_as_python_can_reads_them(bus: SoftwareBus) -> None:
    local = bus.local_bus()
    sender, listener = open_bus(bus.spec()), open_bus(bus.spec())
    try:
        time.sleep(0.1)  # python-can clients: their rawmode hold passes
        sender.send(_msg(0x181, b"\x10\x20"))
        sender.send(_msg(0x18FEF100, bytes(8), extended=True))
        sender.send(_msg(0x7FF, b""))
        got = _drain(local, 3)
        bus.inject_error_frames(1)
        got += _drain(local, 1)
        want = _drain(listener, 4)
        assert [_fields(m) for m in got] == [_fields(m) for m in want]
        assert got[3].is_error_frame and got[3].is_extended_id and bytes(got[3].data) == b"\0"
    finally:
        for b in (local, sender, listener):
            b.shutdown()


def test_sends_are_written_behind_until_recv_in_order_with_stamps() -> None:
    bus = SoftwareBus(port=0, takeover_s=5.0).start()  # the bus thread stays out of it
    local = bus.local_bus()
    peer = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        for i in range(20):
            local.send(_msg(0x100 + i, bytes([i])))
        assert peer.recv(0.1) is None          # nothing left the bus yet: written behind
        assert local.recv(0.0) is None          # its recv writes the step out ...
        got = _drain(peer, 20)
        assert [m.arbitration_id for m in got] == [0x100 + i for i in range(20)]
        stamps = [m.timestamp for m in got]
        assert stamps == sorted(stamps) and abs(stamps[0] - time.time()) < 5.0
        local.send(_msg(0x200))
        local.flush()                           # ... and so does flush()
        assert _drain(peer, 1)[0].arbitration_id == 0x200
        stats = bus.stats()
        assert stats["clients"]["local"]["received"] == 21
        assert stats["frames_in"] == 21 and stats["frames_delivered"] == 21
    finally:
        local.shutdown()
        peer.shutdown()
        bus.stop()


def test_lockstep_round_trips_with_a_process_on_the_bus(bus: SoftwareBus) -> None:
    local = bus.local_bus(busy_poll_us=200.0)
    echo = subprocess.Popen([sys.executable, str(ECHO), bus.spec()], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert echo.stdout is not None and echo.stdout.readline().strip() == "ready"
        time.sleep(0.1)
        for step in range(200):
            local.send(_msg(0x300, step.to_bytes(2, "little")))
            reply = local.recv(5.0)
            assert reply is not None and reply.arbitration_id == 0x301
            assert int.from_bytes(reply.data, "little") == step
    finally:
        assert echo.stdin is not None
        echo.stdin.close()
        echo.wait(10)
        local.shutdown()


def test_the_bus_thread_serves_the_others_while_the_local_client_is_quiet(
        bus: SoftwareBus) -> None:
    local = bus.local_bus()
    a, b = open_bus(bus.spec()), open_bus(bus.spec())
    try:
        time.sleep(0.1)
        local.send(_msg(0x123))                # a step left unsent (no recv) ...
        a.send(_msg(0x124))
        # ... the bus thread takes the loop back after takeover_s: both reach b, in order
        got = _drain(b, 2)
        assert [m.arbitration_id for m in got] == [0x123, 0x124]
        assert [m.arbitration_id for m in _drain(local, 1)] == [0x124]
        # a control call reaches the loop whoever has it
        assert bus.stats()["frames_in"] == 2
    finally:
        for x in (local, a, b):
            x.shutdown()


def test_faults_apply_to_a_local_client_both_ways(bus: SoftwareBus) -> None:
    local = bus.local_bus()
    peer = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        bus.add_fault(FaultRule(FaultKind.DROP, can_id=0x181, mask=0x7FF))
        local.send(_msg(0x181))
        local.send(_msg(0x182))
        local.flush()
        assert [m.arbitration_id for m in _drain(peer, 1)] == [0x182]
        peer.send(_msg(0x181))
        peer.send(_msg(0x183))
        assert [m.arbitration_id for m in _drain(local, 1)] == [0x183]
        assert peer.recv(0.1) is None and local.recv(0.1) is None
        assert bus.stats()["faults"]["drop"] == 2
    finally:
        local.shutdown()
        peer.shutdown()


def test_a_local_client_that_does_not_read_has_its_frames_dropped_and_counted(
        bus: SoftwareBus) -> None:
    slow = bus.local_bus(max_queue=10)
    peer = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        for i in range(25):
            peer.send(_msg(0x400, bytes([i])))
        time.sleep(0.3)
        got = _drain(slow, 10)
        assert [m.data[0] for m in got] == list(range(10)) and slow.recv(0.1) is None
        assert bus.stats()["clients"]["local"]["dropped_slow"] == 15
    finally:
        slow.shutdown()
        peer.shutdown()


def test_pacing_applies_to_a_local_client() -> None:
    with SoftwareBus(port=0, bitrate=250_000) as bus:
        local = bus.local_bus()
        peer = open_bus(bus.spec())
        try:
            time.sleep(0.1)
            for _ in range(20):
                local.send(_msg(0x500, bytes(8)))
            local.flush()
            got = _drain(peer, 20)
            gaps = [b.timestamp - a.timestamp for a, b in itertools.pairwise(got)]
            assert len(got) == 20 and min(gaps) >= 100 / 250_000
        finally:
            local.shutdown()
            peer.shutdown()


def test_log_holds_local_frames(tmp_path: Path) -> None:
    log_path = tmp_path / "bus.log"
    with SoftwareBus(port=0, log_path=log_path) as bus:
        local = bus.local_bus()
        local.send(_msg(0x321, b"\xAB"))
        local.flush()
        local.shutdown()
    assert [(m.arbitration_id, bytes(m.data)) for m in can.LogReader(log_path)] == [
        (0x321, b"\xAB")]


def test_lifecycle_errors_are_clear(bus: SoftwareBus) -> None:
    with pytest.raises(SoftwareBusError, match="not running"):
        SoftwareBus(port=0).local_bus()
    local = bus.local_bus()
    with pytest.raises(can.CanOperationError, match="identifier"):
        local.send(_msg(0x800))                # not an 11-bit id
    local.shutdown()
    with pytest.raises(can.CanOperationError, match="shut down"):
        local.send(_msg(0x100))
    other = bus.local_bus()
    assert isinstance(other, LocalBus)
    bus.stop()                                 # stopping the bus shuts its local clients
    assert other.recv(0.0) is None


def test_a_control_call_gets_the_loop_while_the_local_client_waits(bus: SoftwareBus) -> None:
    local = bus.local_bus()
    took: list[float] = []

    def control() -> None:
        time.sleep(0.1)
        start = time.monotonic()
        bus.add_fault(FaultRule(FaultKind.DROP, can_id=0x1))
        took.append(time.monotonic() - start)

    caller = threading.Thread(target=control)
    caller.start()
    try:
        assert local.recv(1.0) is None       # blocks in the loop for the whole second
        caller.join(5.0)
        assert took and took[0] < 0.5        # ... but the call did not wait for it
    finally:
        local.shutdown()


def test_a_client_that_vanishes_mid_broadcast_does_not_cost_the_others(
        bus: SoftwareBus) -> None:
    local = bus.local_bus()
    first = open_bus(bus.spec())
    dead = socket.create_connection((bus.host, bus.port))
    dead.recv(16)
    dead.sendall(b"< open can0 >")
    dead.recv(16)
    dead.sendall(b"< rawmode >< echo >")
    last = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        dead.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        dead.close()                          # a reset: writes to it fail
        for i in range(50):
            local.send(_msg(0x600, bytes([i])))
            local.flush()
        for receiver in (first, last):
            assert [m.data[0] for m in _drain(receiver, 50)] == list(range(50))
    finally:
        for b in (local, first, last):
            b.shutdown()
