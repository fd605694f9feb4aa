"""The paced bus at 250 kbit/s (ISOBUS): no more frames than the bit rate allows, and
contended frames go out by identifier. Checked on the server's own delivery stamps, which are
the simulated wire times, not on wall-clock speed."""

from __future__ import annotations

import itertools
import socket
import time
from types import SimpleNamespace

import can
import pytest

import hil.softbus.core as core_module
from hil.bus import open_bus
from hil.softbus import SoftwareBus
from hil.softbus.core import BusCore
from hil.softbus.protocol import Frame, format_send
from hil.softbus.timing import frame_bits, worst_case_frame_bits

BITRATE = 250_000


def _drain(bus: can.BusABC, n: int, timeout: float) -> list[can.Message]:
    out: list[can.Message] = []
    deadline = time.monotonic() + timeout
    while len(out) < n and time.monotonic() < deadline:
        msg = bus.recv(0.2)
        if msg is not None:
            out.append(msg)
    return out


def test_paced_bus_carries_no_more_than_the_bit_rate() -> None:
    n = 1500
    with SoftwareBus(port=0, bitrate=BITRATE) as softbus:
        a, b = open_bus(softbus.spec()), open_bus(softbus.spec())
        try:
            start = time.monotonic()
            for i in range(n):
                a.send(can.Message(arbitration_id=0x18FEF100 | (i & 0xFF), is_extended_id=True,
                                   data=i.to_bytes(2, "little") + bytes(6)))
            got = _drain(b, n, timeout=20)
            wall = time.monotonic() - start
        finally:
            a.shutdown()
            b.shutdown()
    assert len(got) == n
    for prev, cur in itertools.pairwise(got):
        bits = frame_bits(cur.arbitration_id, True, bytes(cur.data))
        assert cur.timestamp - prev.timestamp >= bits / BITRATE - 2e-6
    span = got[-1].timestamp - got[0].timestamp
    assert (n - 1) / span <= BITRATE / min(frame_bits(m.arbitration_id, True, bytes(m.data))
                                           for m in got) + 1e-6
    # the frames really took wire time: 1,500 frames of ~130-160 bits at 250 kbit/s ≈ 0.8-1 s
    assert span >= (n - 1) * 120 / BITRATE
    assert (n - 1) / span > 0.5 * BITRATE / worst_case_frame_bits(True, 8)  # it keeps up
    print(f"\npaced 250 kbit/s: {(n - 1) / span:,.0f} frames/s on the wire stamps, "
          f"wall {wall:.2f} s")


def _raw_client(softbus: SoftwareBus) -> socket.socket:
    """A socketcand client in raw mode on ``softbus``, as a plain socket: it can put several
    frames in one write, which the bus reads at one moment (python-can's client writes each
    frame apart, and on a loaded host the writes can be a frame time apart)."""
    sock = socket.create_connection((softbus.host, softbus.port), timeout=5)
    for expect, command in ((b"< hi >", b"< open can0 >"), (b"< ok >", b"< rawmode >")):
        assert sock.recv(64).startswith(expect)
        sock.sendall(command)
    assert sock.recv(64).startswith(b"< ok >")
    return sock


def _sends(*can_ids: int) -> bytes:
    return b"".join(format_send(Frame(can_id, bytes(8), False)) for can_id in can_ids)


def test_contended_frames_are_ordered_by_identifier() -> None:
    with SoftwareBus(port=0, bitrate=BITRATE) as softbus:
        b = open_bus(softbus.spec())
        a = _raw_client(softbus)
        try:
            time.sleep(0.1)
            # a frame on the wire, a backlog behind it, then three contenders in one write:
            # they are ready together whatever the host's scheduling
            a.sendall(_sends(0x300, *[0x7F0] * 60))
            a.sendall(_sends(0x250, 0x100, 0x200))
            got = [m.arbitration_id for m in _drain(b, 64, timeout=10)]
        finally:
            a.close()
            b.shutdown()
    assert len(got) == 64 and got[0] == 0x300
    i = got.index(0x100)
    # the three low ids overtake the queued 0x7F0 backlog, lowest first
    assert got[i:i + 3] == [0x100, 0x200, 0x250]
    assert i < 30, f"low ids waited behind {i - 1} backlog frames"


def _core_on_a_clock(monkeypatch, clock: list[float]) -> tuple[BusCore, list[int]]:
    """A paced bus core without a loop on a clock the test moves, recording the wire order."""
    monkeypatch.setattr(core_module, "time", SimpleNamespace(monotonic=lambda: clock[0],
                                                          time=lambda: 1.7e9 + clock[0]))
    core = BusCore(bitrate=BITRATE, log_path=None, seed=0, hold_s=0.0,
                   max_client_buffer=1 << 20, client_sndbuf=1 << 16)
    wire: list[int] = []
    monkeypatch.setattr(core, "_transmit", lambda sender, frame, channel, mono:
                        wire.append(frame.can_id))
    return core, wire


@pytest.mark.parametrize("one_read", [True, False])
def test_frames_of_one_read_contend_together(monkeypatch, one_read: bool) -> None:
    """Three frames read at once, the server pre-empted ten frame times between handling
    them: they still contend as one (lowest id first), since the wire is pumped only once
    the whole read is offered. Handled as three reads they are three arrivals."""
    clock = [100.0]
    core, wire = _core_on_a_clock(monkeypatch, clock)
    core.submit(None, Frame(0x300, bytes(8), False))     # holds the wire from t = 100 s
    if one_read:
        assert core.begin_arrival()
    for can_id in (0x250, 0x100, 0x200):
        core.submit(None, Frame(can_id, bytes(8), False))
        clock[0] += 0.005
    if one_read:
        core.end_arrival()
    clock[0] += 1.0
    core._pump()
    assert wire == ([0x300, 0x100, 0x200, 0x250] if one_read else [0x300, 0x250, 0x100, 0x200])
