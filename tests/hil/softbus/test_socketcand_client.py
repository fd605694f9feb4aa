"""agrihil's socketcand client (``socketcand:…,client=agrihil`` or ``,batch=true``): the messages
python-can's client produces, write-behind, busy polling, spec options; and the server's
rawmode hold, which a client ends by sending its next message."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import can
import pytest

from hil.bus import open_bus
from hil.bus.socketcand import SocketcandBus, format_send
from hil.errors import BusSpecError
from hil.softbus import SoftwareBus

from .frames import drain as _drain
from .frames import fields as _fields
from .frames import msg as _msg


@pytest.fixture
def bus() -> Iterator[SoftwareBus]:
    with SoftwareBus(port=0) as softbus:
        yield softbus


def test_spec_options_choose_the_client(bus: SoftwareBus) -> None:
    for options, cls in ((",client=agrihil", SocketcandBus), (",batch=true", SocketcandBus),
                         (",busy_poll_us=50", SocketcandBus), ("", can.BusABC)):
        client = open_bus(bus.spec() + options)
        try:
            assert isinstance(client, cls)
            assert (type(client) is SocketcandBus) == bool(options)
        finally:
            client.shutdown()
    with pytest.raises(BusSpecError, match="client='carrier'"):
        open_bus(bus.spec() + ",client=carrier")
    with pytest.raises(BusSpecError, match="need client=agrihil"):
        open_bus(bus.spec() + ",client=python-can,batch=true")


def test_messages_are_those_python_can_reads(bus: SoftwareBus) -> None:
    ours, theirs, sender = (open_bus(bus.spec() + ",client=agrihil"), open_bus(bus.spec()),
                            open_bus(bus.spec()))
    try:
        time.sleep(0.1)
        frames = [_msg(0x181, b"\x10\x20"), _msg(0x18FEF100, bytes(range(8)), extended=True),
                  _msg(0x0, b""), _msg(0x7FF, b"\xff" * 8)]
        for frame in frames:
            sender.send(frame)
        got, want = _drain(ours, 4), _drain(theirs, 4)
        bus.inject_error_frames(1)
        got += _drain(ours, 1)
        want += _drain(theirs, 1)
        assert len(got) == 5 and [_fields(m) for m in got] == [_fields(m) for m in want]
        for frame in frames:       # and what it sends arrives as python-can's would
            ours.send(frame)
        echoed = _drain(theirs, 4)
        assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in echoed] == [
            (f.arbitration_id, f.is_extended_id, bytes(f.data)) for f in frames]
    finally:
        for b in (ours, theirs, sender):
            b.shutdown()


def test_format_send_matches_what_the_server_parses() -> None:
    from hil.softbus.protocol import parse_send
    for msg in (_msg(0x1, b""), _msg(0x7FF, bytes(range(8))),
                _msg(0x1FFFFFFF, b"\xab", extended=True)):
        line = format_send(msg).decode()
        frame = parse_send(line[len("< send "):-2])
        assert (frame.can_id, frame.extended, frame.data) == (
            msg.arbitration_id, msg.is_extended_id, bytes(msg.data))


def test_batch_writes_once_at_recv_in_order(bus: SoftwareBus) -> None:
    batcher = open_bus(bus.spec() + ",batch=true")
    peer = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        for i in range(30):
            batcher.send(_msg(0x200 + i))
        assert peer.recv(0.2) is None            # kept until the batcher's recv
        assert batcher.recv(0.0) is None
        assert [m.arbitration_id for m in _drain(peer, 30)] == [0x200 + i for i in range(30)]
        batcher.send(_msg(0x300))
        batcher.shutdown()                       # shutdown writes what is kept
        assert _drain(peer, 1)[0].arbitration_id == 0x300
    finally:
        peer.shutdown()


def test_busy_poll_and_timeouts(bus: SoftwareBus) -> None:
    spinner = open_bus(bus.spec() + ",busy_poll_us=2000")
    peer = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        start = time.monotonic()
        assert spinner.recv(0.05) is None
        assert 0.04 <= time.monotonic() - start < 1.0
        peer.send(_msg(0x42))
        got = spinner.recv(2.0)
        assert got is not None and got.arbitration_id == 0x42
    finally:
        spinner.shutdown()
        peer.shutdown()


def test_filters_apply(bus: SoftwareBus) -> None:
    client = SocketcandBus("can0", bus.host, bus.port,
                           can_filters=[{"can_id": 0x100, "can_mask": 0x7FF}])
    peer = open_bus(bus.spec())
    try:
        time.sleep(0.1)
        peer.send(_msg(0x101))
        peer.send(_msg(0x100))
        got = _drain(client, 1)
        assert [m.arbitration_id for m in got] == [0x100]
    finally:
        client.shutdown()
        peer.shutdown()


def test_a_closed_server_is_an_error(bus: SoftwareBus) -> None:
    client = open_bus(bus.spec() + ",client=agrihil")
    bus.stop()
    with pytest.raises(can.CanOperationError, match="closed"):
        client.recv(2.0)
    client.shutdown()


def _stop_without_reading(listener: socket.socket) -> None:
    """A socketcand server that answers the handshake, then stops while the client's last
    message ('< echo >') is still unread in its socket: the kernel resets the connection."""
    while True:                        # open_bus probes the greeting with a connection first
        conn, _ = listener.accept()
        with conn:
            conn.sendall(b"< hi >")
            answered = 0
            while answered < 2:        # '< open can0 >', '< rawmode >'
                data = conn.recv(1)
                if not data:
                    break
                if data == b">":
                    conn.sendall(b"< ok >")
                    answered += 1
            if answered == 2:
                time.sleep(0.2)        # '< echo >' arrives and stays unread
                return


def test_a_server_that_stops_with_our_message_unread_has_closed_the_connection() -> None:
    """The race behind a flaky test_a_closed_server_is_an_error: a bus stopped before it read
    the client's '< echo >' resets the connection; that too is "the server closed" it."""
    with socket.create_server(("127.0.0.1", 0)) as listener:
        server = threading.Thread(target=_stop_without_reading, args=(listener,), daemon=True)
        server.start()
        client = open_bus(f"socketcand:127.0.0.1:{listener.getsockname()[1]}/can0,"
                          "client=agrihil")
        try:
            server.join(5.0)
            with pytest.raises(can.CanOperationError,
                               match=r"server closed the connection \(.*reset"):
                client.recv(2.0)
        finally:
            client.shutdown()


def _raw_client(bus: SoftwareBus, after_rawmode: bytes = b"") -> socket.socket:
    sock = socket.create_connection((bus.host, bus.port))
    sock.settimeout(5.0)
    assert sock.recv(16) == b"< hi >"
    sock.sendall(b"< open can0 >")
    assert sock.recv(16) == b"< ok >"
    sock.sendall(b"< rawmode >" + after_rawmode)
    return sock


def test_the_rawmode_hold_ends_with_the_clients_next_message() -> None:
    with SoftwareBus(port=0, hold_s=5.0) as bus:   # a hold long enough to see
        held = _raw_client(bus)
        assert held.recv(16) == b"< ok >"
        eager = _raw_client(bus, b"< echo >")         # agrihil's clients (and the firmware)
        peer = open_bus(bus.spec() + ",client=agrihil")
        try:
            time.sleep(0.05)
            peer.send(_msg(0x123))
            data = b""
            while data.count(b">") < 3:
                data += eager.recv(256)
            assert data.startswith(b"< ok >< echo >< frame 123 ")
            held.settimeout(0.3)
            with pytest.raises(TimeoutError):           # python-can's kind: still held ...
                held.recv(256)
            held.sendall(b"< echo >")                   # ... until it says something
            assert held.recv(256).startswith(b"< frame 123 ")
        finally:
            held.close()
            eager.close()
            peer.shutdown()


def test_a_frame_in_the_same_read_as_the_handshake_reply_is_kept() -> None:
    """A real socketcand may send frames right behind '< ok >' in one segment: they are
    received, not dropped with the handshake."""
    import socket
    import threading

    listener = socket.create_server(("127.0.0.1", 0))
    port = listener.getsockname()[1]

    def serve() -> None:
        conn, _ = listener.accept()
        with conn:
            conn.sendall(b"< hi >")
            conn.recv(64)                                  # < open can0 >
            conn.sendall(b"< ok >")
            conn.recv(64)                                  # < rawmode >
            conn.sendall(b"< ok >< frame 123 1.500000 AB >")
            conn.recv(64)                                  # < echo >
            time.sleep(0.5)

    server = threading.Thread(target=serve, daemon=True)
    server.start()
    bus = SocketcandBus("can0", "127.0.0.1", port)
    try:
        msg = bus.recv(1.0)
        assert msg is not None and msg.arbitration_id == 0x123 and bytes(msg.data) == b"\xab"
        assert msg.timestamp == 1.5
    finally:
        bus.shutdown()
        listener.close()
        server.join(2.0)
